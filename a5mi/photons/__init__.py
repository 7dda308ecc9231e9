"""Host-side photon mapping: progressive passes here or on Dask (:mod:`.passes`, docs/EXTENSIONS.md E.17) and the
photon-map picture and counts of ``a5mi photons`` (:mod:`.report`, E.16)."""

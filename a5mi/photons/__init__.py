"""Host-side photon mapping: progressive passes here or on Dask (:mod:`.passes`, docs/EXTENSIONS.md E.17), the
photon-map picture and counts of ``a5mi photons`` (:mod:`.report`, E.16), and a scene rendered by photon mapping
and by Mitsuba's ``ptracer`` on the same materials (:mod:`.versus`, E.16 "scene10's caustic against ptracer")."""

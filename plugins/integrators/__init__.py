"""Integrator plugins on one base (``base``): ``a5_whitted`` (SPEC B.3, in ``whitted/``), ``a5_path``
(EXTENSIONS E.13, E.14), ``a5_photon`` / ``a5_ppm`` (E.16, E.17, in ``photon/``) and ``a5_irradiancecache``
(E.23, in ``irradiance_cache/``).

May import: every other part of :mod:`a5mi.plugins`; only :mod:`a5mi.plugins` (registration) imports them.
"""

"""BSDF plugins and what shades a surface: ``a5_material`` (the assignment's Phong material, SPEC A.4,
B.3), ``a5_milled`` (Ward on a milling field, EXTENSIONS E.20), bump mapping (``bump``, E.7) and dispersion
(``spectral``, E.10).

May import: the :mod:`a5mi.plugins` leaves (``syntax``, ``params``, ``sampling``, ``optics``),
:mod:`a5mi.plugins.textures`, the a5mi leaves.
"""

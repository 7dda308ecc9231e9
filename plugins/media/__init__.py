"""Participating media and subsurface scattering (EXTENSIONS E.12, E.18, E.21): the medium's parameters
(``medium``), transmittance towards lights (``light``), the random walk (``walk``), subsurface walks
(``subsurface``) and the dipole profile (``dipole``).

May import: the :mod:`a5mi.plugins` leaves, :mod:`a5mi.plugins.kernel`, :mod:`a5mi.plugins.emulation`, the a5mi
leaves.
"""

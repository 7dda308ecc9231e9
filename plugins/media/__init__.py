"""What a participating medium is (docs/EXTENSIONS.md E.8, E.9, E.18): the medium's parameters (``medium``),
the transmittance towards a light (``light``) and the dipole profile of subsurface scattering (``dipole``).
How a ray walks through them is the integrator's (plugins/integrators/whitted/).

May import: the :mod:`a5mi.plugins` leaves and the a5mi leaves; never the kernel or an integrator (the kernel
imports this package).
"""

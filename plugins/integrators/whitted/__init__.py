"""``a5_whitted``: the assignment's Whitted ray tracer (SPEC B.3-B.4): the plugin (``integrator``),
its ray-tree kernel (``raytree``), and the kernel's walks through media (``medium_segment``, ``medium_walk``:
E.8, E.9) and under surfaces (``subsurface``: E.18).

May import: :mod:`a5mi.plugins.kernel`, :mod:`a5mi.plugins.media` and the lower plugin packages.
"""

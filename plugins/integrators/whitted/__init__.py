"""``a5_whitted``: the assignment's Whitted ray tracer (SPEC B.3-B.4): the plugin (``integrator``),
its ray-tree kernel (``raytree``) and the record mode behind ``a5mi trace`` (``record``).

May import: :mod:`a5mi.plugins.kernel`, :mod:`a5mi.plugins.media` and the lower plugin packages.
"""

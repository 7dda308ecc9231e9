"""Emitter plugins: ``a5_point`` for point and directional lights (SPEC A.2, B.3), ``a5_spot`` (EXTENSIONS
E.1), ``a5_area`` (E.2), ``a5_cubemap`` (the SPEC A.1 cube-map background).

May import: the :mod:`a5mi.plugins` leaves, :mod:`a5mi.plugins.textures`, the a5mi leaves.
"""

"""The render pipeline after the scene is described (SPEC B.1-B.5): the options object (``options``), the
scene build and warm sessions (``session``), the driver (``driver``), tiles and jitter (``tiles``,
``glibc_rand``), one pass over the tiles (``render_pass``), E.5 passes (``passes``), split renders (``bands``),
the blur and downsampling (``filters``), the work estimate made before a render starts (``estimate``), the
picture of the irradiance cache's records (``ic_records``).

May import: the leaves (:mod:`a5mi.platform`, :mod:`a5mi.spec`), :mod:`a5mi.converters`, :mod:`a5mi.plugins`,
:mod:`a5mi.runtime`; never the command layer.
"""

"""Texture plugins: ``a5_marble`` (SPEC A.4 Perlin marble; the noise in ``perlin``), ``a5_bitmap``, the
solid textures (``solids``, EXTENSIONS E.6), ``a5_btf`` (E.19), and the image atlas they share (``imagedata``).

May import: the :mod:`a5mi.plugins` leaves, the a5mi leaves.
"""

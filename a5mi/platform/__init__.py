"""Platform and I/O leaves: typed user errors (``errors``), the one image reader and atomic writer
(``imageio``), output targets checked before the work (``paths``, ``clobber``), signal handling (``interrupts``),
memory and thread budgets (``resources``), aligned arrays (``arrays``).

May import: the standard library, numpy, OpenImageIO, :mod:`a5mi` (version, data folder), :mod:`a5mi.spec` and
each other; nothing else of a5mi.
"""

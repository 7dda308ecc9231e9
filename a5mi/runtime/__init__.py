"""What the process runs on: the Dr.Jit/Mitsuba variant (``variant``), the libLLVM check (``llvm``),
optional extras by command (``extras``), the TLS Dask cluster (``cluster``).

May import: the leaves (:mod:`a5mi.platform`, :mod:`a5mi.spec`); never the command layer.
"""

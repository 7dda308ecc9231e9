"""``a5_photon`` and ``a5_ppm`` (EXTENSIONS E.16, E.17): emission (``emit``), tracing (``trace``,
``walk``), the maps' kd-trees (``maps``), the two integrators (``integrator``, ``ppm``).

May import: :mod:`a5mi.plugins.kernel`, :mod:`a5mi.plugins.emitters` and the lower plugin packages.
"""

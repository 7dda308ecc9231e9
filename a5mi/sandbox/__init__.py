"""Running untrusted programs (another a5 binary, a student's submission): the bubblewrap sandbox
(``bwrap``), what a run uses and how it is ended (``accounting``: its processes by uid, its cgroup's CPU time),
its size-limited folder (``folders``), its limits and result (``records``) and the checked reading of what it
wrote (``outputs``).

May import: the leaves (:mod:`a5mi.platform`, :mod:`a5mi.spec`); never the renderer or the command layer.
"""

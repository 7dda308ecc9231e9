"""Running untrusted programs (another a5 binary, a student's submission): the bubblewrap sandbox
(``bwrap``) and the checked reading of what such a program wrote (``outputs``).

May import: the leaves (:mod:`a5mi.platform`, :mod:`a5mi.spec`); never the renderer or the command layer.
"""

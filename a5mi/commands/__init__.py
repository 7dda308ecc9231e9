"""One module per ``a5mi`` sub-command (``render`` is also the ``a5`` command): each defines a
:class:`~a5mi.cli.app.Command` named after the module (``RENDER``, ``COMPARE``, ...) with its flags, its checks
and what it prints. The framework they share (flag table, dispatcher, console, progress) is :mod:`a5mi.cli`.

May import: everything in a5mi. Only the command layer (:mod:`a5mi.cli`, :mod:`a5mi.commands`) prints.
"""

"""``a5mi serve``: a warm a5mi process that renders the ``a5`` commands of the same user (docs/SERVE.md).

:mod:`.protocol` is the socket's place and its messages, :mod:`.client` what the ``a5`` console script runs
before anything else (standard library only: it never imports Mitsuba, Dr.Jit or the command layer), and
:mod:`.server` the listening loop that hands each accepted request to a callback, one render at a time, in
the server's own (main) thread. The callback, which runs the ``a5`` command itself, is the command layer's
(:mod:`a5mi.commands.serve`): this library never imports it.

May import: the ``a5mi`` leaves (:mod:`a5mi.platform.interrupts`) and each other.
"""

"""Errors a user can cause at the command-line level (bad flags, unwritable outputs), reported by the CLI.

Scene-file errors are :class:`a5mi.converters.errors.SceneError` (with a ``FILE:LINE:COL`` position);
these are the others. :mod:`a5mi.cli` prints any :class:`UserError` as one line ``a5: error: <msg>`` and
exits with status :attr:`ExitStatus.USAGE` (2).

:class:`ExitStatus` is the one exit-status policy of every command (``a5`` and each ``a5mi`` sub-command),
the ``cmp``/``diff`` convention plus ``sysexits``: 0 same / ok, 1 a "differ" or "fail" verdict, 2 a mistake
the user can fix, 70 an internal error (a bug: ``EX_SOFTWARE``), 128 + N a signal, 141 a closed output pipe.
"""

from __future__ import annotations

import enum


class ExitStatus(enum.IntEnum):
    """Exit status of every a5mi command (README "Exit status" table)."""

    OK = 0            #: success; for a comparison: the images match
    DIFFER = 1        #: a verdict: images differ, a submission fails, a check does not hold
    USAGE = 2         #: something the user can fix: flags, scene file, missing or unreadable input
    SOFTWARE = 70     #: internal error (sysexits EX_SOFTWARE): a bug; --debug shows the traceback
    INTERRUPTED = 130  #: SIGINT (128 + 2); SIGTERM gives 143, SIGHUP 129
    BROKEN_PIPE = 141  #: the reader of standard output went away (128 + SIGPIPE)

    @staticmethod
    def signal(signum: int) -> int:
        """The status of a command stopped by signal ``signum``: ``128 + signum``."""
        return 128 + int(signum)


class UserError(Exception):
    """Something the user can fix: the message is one line and says what was expected and what was found."""


class UsageError(UserError):
    """Command-line misuse: unknown flag, missing or malformed value, missing ``-input``/``-output``."""


class ImageWriteError(UserError):
    """An output image cannot be written: unknown extension, missing or read-only folder, failed write."""


class ImageReadError(UserError):
    """An input image is missing, unreadable or corrupt; ``reason`` is the cause without the path."""

    def __init__(self, msg: str, reason: str | None = None) -> None:
        super().__init__(msg)
        self.reason = reason if reason is not None else msg


class FileReadError(UserError):
    """An input file is not a readable regular file within its size limit; ``reason`` is the cause without
    the path (``not a regular file (FIFO)``, ``... bytes is more than the limit of ... bytes``)."""

    def __init__(self, msg: str, reason: str | None = None) -> None:
        super().__init__(msg)
        self.reason = reason if reason is not None else msg


class MissingExtraError(UserError):
    """A command needs a module of an optional dependency group that is not installed (:mod:`a5mi.runtime.extras`):
    ``needs the 'EXTRA' extra: pip install 'a5mi[EXTRA]' (missing module MODULE)``."""

    def __init__(self, module: str, extra: str) -> None:
        super().__init__(f"needs the '{extra}' extra: pip install 'a5mi[{extra}]' (missing module {module})")
        self.module, self.extra = module, extra

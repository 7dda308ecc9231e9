"""Errors a user can cause at the command-line level (bad flags, unwritable outputs), reported by the CLI.

Scene-file errors are :class:`a5mi.converters.errors.SceneError` (with a ``FILE:LINE:COL`` position);
these are the others. :mod:`a5mi.cli` prints any :class:`UserError` as one line ``a5: error: <msg>`` and
exits with status 2 (SPEC B.1 flags; issue 8's error rules).
"""

from __future__ import annotations


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

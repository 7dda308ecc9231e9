"""The command layer's stream helpers, below every other module of :mod:`a5mi.cli` (the console, the progress
bar): a diagnostic write that never fails the command."""

from __future__ import annotations

from typing import Any


def write_diagnostic(stream: Any, text: str) -> None:
    """Write ``text`` to a diagnostic stream; a stream that cannot take it (closed, full, hung up) drops it."""
    try:
        stream.write(text)
        stream.flush()
    except (OSError, ValueError, AttributeError):
        pass

"""``python3 -m a5mi.cli.setup llvm``: the set-up step ``make setup`` runs before the virtual environment exists
(standard library only): make sure Dr.Jit will find libLLVM >= 16, installing it as root on Debian/Ubuntu
(:func:`a5mi.runtime.llvm.ensure`). Prints ``a5mi: ...`` lines; exit status
(:class:`a5mi.platform.errors.ExitStatus`) 0 when
libLLVM is usable, 2 when it is not (the message says what to install) or the arguments are wrong."""

from __future__ import annotations

import sys
from collections.abc import Sequence


def main(argv: Sequence[str]) -> int:
    from a5mi.platform.errors import ExitStatus
    from a5mi.runtime import llvm

    if list(argv) != ["llvm"]:
        print("usage: python3 -m a5mi.cli.setup llvm", file=sys.stderr)
        return ExitStatus.USAGE
    try:
        llvm.ensure(lambda msg: print(f"a5mi: {msg}", flush=True))
    except llvm.LLVMError as exc:
        print(f"a5mi: error: {exc}", file=sys.stderr)
        return ExitStatus.USAGE
    return ExitStatus.OK


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

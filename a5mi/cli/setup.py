"""``python3 -m a5mi.cli.setup llvm``: the set-up step ``make setup`` runs before the virtual environment exists
(standard library only): make sure Dr.Jit will find libLLVM >= 16, installing it as root on Debian/Ubuntu
(:func:`a5mi.llvm.ensure`). Prints ``a5mi: ...`` lines; exit 0 when usable, 1 otherwise."""

from __future__ import annotations

import sys
from collections.abc import Sequence


def main(argv: Sequence[str]) -> int:
    from a5mi import llvm

    if list(argv) != ["llvm"]:
        print("usage: python3 -m a5mi.cli.setup llvm", file=sys.stderr)
        return 2
    try:
        llvm.ensure(lambda msg: print(f"a5mi: {msg}", flush=True))
    except llvm.LLVMError as exc:
        print(f"a5mi: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

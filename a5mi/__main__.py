"""``python -m a5mi ARGS``: the ``a5`` command (SPEC B.1); see :mod:`a5mi.cli`."""

import sys

from a5mi.cli import run

if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))

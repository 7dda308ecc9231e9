"""``python -m a5mi ARGS``: the ``a5`` command (SPEC B.1); see :mod:`a5mi.cli`."""

from a5mi.entry import a5

if __name__ == "__main__":
    a5()

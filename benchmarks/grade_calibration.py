"""Print the verdict calibration table of docs/GRADING.md (a5mi.grade.calibrate) at a given size.

    .venv/bin/python benchmarks/grade_calibration.py [SIZE]      (default 300: the handout's size)
"""

from __future__ import annotations

import sys
import tempfile

from a5mi import require_data_dir
from a5mi.grade.calibrate import calibrate, markdown


def main(argv: list[str]) -> int:
    size = int(argv[0]) if argv else 300
    with tempfile.TemporaryDirectory() as cache:
        rows = calibrate(require_data_dir() / "scenes", size, cache,
                         log=lambda m: print(m, file=sys.stderr, flush=True))
    print(markdown(rows, size))
    bad = [r for r in rows if not r.ok]
    print(f"\n{len(rows) - len(bad)} of {len(rows)} renders get the expected verdict", flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

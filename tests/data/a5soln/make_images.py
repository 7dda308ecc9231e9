"""Make the a5soln images of the project's own scenes that tests/fidelity/test_a5soln_own_scenes.py compares
a5mi with, and this folder's README (the command of each image).

    python tests/data/a5soln/make_images.py /path/to/a5soln

``a5soln`` is the course's sample solution (the 2012 Linux x86-64 build, public as ``five/a5soln`` in the
GitHub repository ``tuituji/6.837-MIT-CG``); it never goes into this repository. Each command runs in
``scenes/`` (the binary resolves mesh, texture and cube-map paths against its working directory, SPEC A.0) and
writes BMP (the 2012 binary writes BMP or TGA, SPEC B.1) into a temporary folder; each BMP is then stored here
as PNG, losslessly (the same 8-bit levels).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
sys.path.insert(0, str(ROOT / "tests" / "fidelity"))

from test_a5soln_own_scenes import CASES  # noqa: E402

from a5mi.platform.imageio import read_levels, write_image  # noqa: E402

HEAD = """# a5soln's images of the project's own scenes

Test data of `tests/fidelity/test_a5soln_own_scenes.py` (which renders each with `a5` and the same flags and
compares: PSNR >= 77 dB, fewer than 0.1% of pixels off by more than 2/255). Made by `make_images.py` (this
folder) with the course's sample solution `a5soln` (the 2012 Linux x86-64 build, `five/a5soln` of the GitHub
repository `tuituji/6.837-MIT-CG`; the binary itself is not kept anywhere in this project):

    python tests/data/a5soln/make_images.py /path/to/a5soln

Each command below ran in `scenes/` (relative mesh, texture and cube-map paths, SPEC A.0) with `OUT` a
temporary folder; every BMP it wrote is stored here as PNG, losslessly (`NAME.bmp` -> `NAME.png`, the same
8-bit levels). The scenes, meshes, textures and cube map are the project's own (`scenes/`,
`scenes/make_assets.py`); no course data is used.

| image(s) | command (in `scenes/`) | SPEC |
| --- | --- | --- |
"""


def main(binary: str) -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for case in CASES:
            argv = case.a5soln_argv(out)
            subprocess.run([binary, *argv], cwd=ROOT / "scenes", check=True, stdout=subprocess.DEVNULL)
            for image in case.images():
                levels = read_levels(out / image.replace(".png", ".bmp"))
                write_image(str(HERE / image), levels.astype("uint8"))
                assert (read_levels(HERE / image) == levels).all(), image
            cmd = " ".join(["a5soln", *case.a5soln_argv(Path("OUT"))])
            rows.append(f"| {', '.join(case.images())} | `{cmd}` | {case.spec} |")
    (HERE / "README.md").write_text(HEAD + "\n".join(rows) + "\n")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: make_images.py /path/to/a5soln")
    main(sys.argv[1])

"""Import rules of the converters (ARCHITECTURE.md): the description is made without Mitsuba, and converters
use only the leaf modules of ``a5mi`` (spec, options, imageio, errors)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

from a5mi import PROJECT_ROOT

LEAVES = {"a5mi.spec", "a5mi.options", "a5mi.imageio", "a5mi.errors"}


def test_describe_reads_every_file_without_importing_mitsuba(scenes_dir: Path) -> None:
    code = ("import sys\nfrom a5mi.converters.a5_parser import parse_file\n"
            "from a5mi.converters.describe import describe\n"
            "from a5mi.converters import materials, to_mitsuba, to_xml\n"
            f"d = describe(parse_file({str(scenes_dir / 'scene11_cube.txt')!r}), stock=True)\n"
            "assert d.background.faces and d.shapes, d\n"
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('mitsuba', 'drjit'))\n"
            "assert not bad, bad\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_converters_import_only_the_leaf_modules_of_a5mi() -> None:
    for path in sorted((PROJECT_ROOT / "converters").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] if node.module != "a5mi" else [f"a5mi.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                if name.split(".")[0] == "a5mi":
                    assert name in LEAVES, f"{path.name} imports {name}"

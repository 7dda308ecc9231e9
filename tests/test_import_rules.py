"""ARCHITECTURE.md import rules: plugins take SPEC constants from the leaf modules of ``a5mi`` and nothing else."""

from __future__ import annotations

import ast
from pathlib import Path

PLUGINS = Path(__file__).resolve().parent.parent / "plugins"
#: The only ``a5mi`` modules a plugin may import (leaf modules: standard library and a5mi.spec only).
LEAVES = {"a5mi.spec", "a5mi.options"}


def _a5mi_imports(path: Path) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        out |= {n for n in names if n == "a5mi" or n.startswith("a5mi.")}
    return out


def test_plugins_import_only_the_leaf_modules_of_a5mi() -> None:
    for path in sorted(PLUGINS.glob("*.py")):
        bad = {m for m in _a5mi_imports(path)
               if not any(m == leaf or m.startswith(f"{leaf}.") for leaf in LEAVES)
               and not m.startswith("a5mi.plugins")}
        assert not bad, f"{path.name} imports {sorted(bad)}"


def test_spec_constants_have_one_home() -> None:
    """TMIN, MIRROR_THRESHOLD and FRESNEL_MODES are assigned only in a5mi/spec.py among plugins and a5mi."""
    root = PLUGINS.parent
    for path in sorted([*PLUGINS.glob("*.py"), *(root / "a5mi").glob("*.py")]):
        if path.name == "spec.py":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
                node, ast.AnnAssign) else []
            names = {t.id for t in targets if isinstance(t, ast.Name)}
            assert not names & {"TMIN", "MIRROR_THRESHOLD", "FRESNEL_MODES"}, f"{path.name} defines {names}"

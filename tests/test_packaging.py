"""Packaging: one version source, an SPDX licence with its file, a build without deprecation warnings."""

from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import a5mi

ROOT = Path(__file__).resolve().parent.parent


def test_one_version_source_and_a_licence_file() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" not in project and project["dynamic"] == ["version"]
    assert project["license"] == "MIT" and (ROOT / "LICENSE").read_text().startswith("MIT License")
    assert a5mi.__version__.count(".") == 2


def test_the_wheel_builds_without_deprecation_warnings(tmp_path: Path) -> None:
    """What `make setup` runs, as a wheel build (same backend, same configuration): no setuptools deprecation
    warning (the old ``license = { text = ... }`` table printed three), and the wheel holds the three packages
    and their data files."""
    p = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(ROOT)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "deprecat" not in (p.stdout + p.stderr).lower(), p.stderr[-2000:]
    (wheel,) = tmp_path.glob("a5mi-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    sources = {f"a5mi/{p.relative_to(ROOT / 'a5mi').as_posix()}" for p in (ROOT / "a5mi").rglob("*.py")}
    sources |= {f"a5mi/{folder}/{p.relative_to(ROOT / folder).as_posix()}" for folder in ("plugins", "converters")
                for p in (ROOT / folder).rglob("*.py")}
    assert sources <= set(names), f"missing from the wheel: {sorted(sources - set(names))}"  # every package listed
    assert any(n.endswith("licenses/LICENSE") for n in names)
    assert "a5mi/converters/subsurface_presets.toml" in names  # package data read at run time
    assert "a5mi/diagnose/mistakes.tsv" in names   # docs/MISTAKES.md's catalogue, package data

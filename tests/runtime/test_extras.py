"""Optional dependencies (a5mi/runtime/extras.py, pyproject.toml): ``a5`` runs on the core packages alone; a command
that
needs an extra's module says which extra in one line, exit status 2, before it renders or writes anything; the
extras named in the code are the ones pyproject.toml declares. A missing module is simulated by
``sys.modules[name] = None`` (the import system then raises ModuleNotFoundError for it)."""

from __future__ import annotations

import ast
import importlib.metadata
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT

from a5mi.platform.errors import ExitStatus, MissingExtraError, UserError
from a5mi.runtime.extras import require

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
#: The modules of the core dependencies: all that ``a5`` imports besides the standard library.
CORE_MODULES = {"mitsuba", "drjit", "numpy", "OpenImageIO", "scipy"}  # scipy: the photon maps' k-d tree (E.16)
#: Every module that an extra brings and the code imports.
EXTRA_MODULES = ("distributed", "dask", "cryptography", "flip_evaluator", "imageio_ffmpeg", "tqdm", "dask_jobqueue")
SCENE = ("PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }\n"
         "Lights { numLights 1 DirectionalLight { direction -0.2 -0.2 -1 color 1 1 1 } }\n"
         "Background { color 0.2 0 0.6 ambientLight 0 0 0 }\n"
         "Materials { numMaterials 1 Material { diffuseColor 1 1 1 } }\n"
         "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n")
ANIMATION = "Animation { frames 2 fps 2 Track { Camera center linear key 0 0 0 10 key 1 0 0.5 10 } }\n"


def _message(extra: str, module: str) -> str:
    return f"needs the '{extra}' extra: pip install 'a5mi[{extra}]' (missing module {module})"


def _name(requirement: str) -> str:
    """The normalised distribution name of a requirement string (``flip-evaluator>=1.6`` -> ``flip_evaluator``)."""
    return re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0].lower().replace("-", "_")


def _distributions_of_extra(extra: str) -> set[str]:
    """The distributions ``pip install 'a5mi[extra]'`` asks for, nested extras (``a5mi[grade]``) expanded."""
    out: set[str] = set()
    for req in PYPROJECT["optional-dependencies"][extra]:
        if _name(req) == "a5mi":
            for inner in req[req.index("[") + 1:req.index("]")].split(","):
                out |= _distributions_of_extra(inner.strip())
        else:
            out.add(_name(req))
    return out


def _blocked(monkeypatch: pytest.MonkeyPatch, *modules: str) -> None:
    for m in modules:
        monkeypatch.setitem(sys.modules, m, None)


# ------------------------------------------------------------------------------------------- the helper
def test_require_returns_the_module() -> None:
    import json as json_module

    assert require("json", "grade") is json_module


def test_a_missing_module_is_a_user_error_naming_its_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    _blocked(monkeypatch, "flip_evaluator")
    with pytest.raises(MissingExtraError) as info:
        require("flip_evaluator", "grade")
    assert isinstance(info.value, UserError)
    assert str(info.value) == _message("grade", "flip_evaluator")
    assert (info.value.module, info.value.extra) == ("flip_evaluator", "grade")


def test_a_missing_dependency_of_an_installed_module_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The extra is half installed (its package is there, one it imports is not): the error names that one."""
    (tmp_path / "a5mi_half_installed.py").write_text("import a5mi_not_installed_anywhere\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(MissingExtraError, match=re.escape(_message("animate", "a5mi_not_installed_anywhere"))):
        require("a5mi_half_installed", "animate")


def test_other_import_failures_are_not_called_a_missing_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An installed module that fails for another reason is a bug to report (exit 70), not a missing extra."""
    (tmp_path / "a5mi_broken_module.py").write_text("raise ImportError('its shared library is broken')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ImportError, match="shared library is broken") as info:
        require("a5mi_broken_module", "grade")
    assert not isinstance(info.value, MissingExtraError)


# ------------------------------------------------------------------------------------------- the commands
def _images(tmp_path: Path) -> tuple[str, str]:
    from a5mi.platform.imageio import write_image

    a, b = tmp_path / "a.png", tmp_path / "b.png"
    img = np.full((6, 8, 3), 0.5, np.float32)
    write_image(a, img)
    img[2, 3] = 0.9
    write_image(b, img)
    return str(a), str(b)


def test_compare_needs_the_grade_extra_only_for_flip(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    from a5mi.cli import run_a5mi

    _blocked(monkeypatch, "flip_evaluator")
    a, b = _images(tmp_path)
    assert run_a5mi(["compare", a, b, "--json"]) == ExitStatus.DIFFER  # no FLIP asked for: works
    assert json.loads(capsys.readouterr().out)["flip"] is None
    flip_map = tmp_path / "flip.png"
    assert run_a5mi(["compare", a, b, "--flip-map", str(flip_map)]) == ExitStatus.USAGE
    out = capsys.readouterr()
    assert out.err == f"a5mi compare: error: {_message('grade', 'flip_evaluator')}\n" and out.out == ""
    assert not flip_map.exists()


@pytest.mark.parametrize("missing", ["distributed", "tqdm", "flip_evaluator"])
def test_grade_says_which_extra_before_it_starts(a5_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str], missing: str) -> None:
    from a5mi.cli import run_a5mi

    _blocked(monkeypatch, missing)
    (tmp_path / "subs" / "alice").mkdir(parents=True)
    report = tmp_path / "report"
    assert run_a5mi(["grade", str(tmp_path / "subs"), "-o", str(report)]) == ExitStatus.USAGE
    assert capsys.readouterr().err.splitlines()[-1] == f"a5mi grade: error: {_message('grade', missing)}"
    assert not report.exists()
    if missing == "flip_evaluator":  # --no-flip does not need it: the run gets past the check (to the cluster)
        _blocked(monkeypatch, "distributed")
        assert run_a5mi(["grade", str(tmp_path / "subs"), "-o", str(report), "--no-flip"]) == ExitStatus.USAGE
        assert capsys.readouterr().err.splitlines()[-1] == f"a5mi grade: error: {_message('grade', 'distributed')}"


@pytest.mark.parametrize("missing,flags", [
    ("tqdm", []),
    ("imageio_ffmpeg", ["--video", "clip.gif"]),
    ("distributed", ["--workers", "2"]),
])
def test_animate_says_which_extra_before_it_renders(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str], missing: str,
                                                    flags: list[str]) -> None:
    from a5mi.cli import run_a5mi

    _blocked(monkeypatch, missing)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "anim.txt").write_text(SCENE + ANIMATION)
    assert run_a5mi(["animate", "anim.txt", "-o", "frames", "-size", "8", "8", *flags]) == ExitStatus.USAGE
    assert capsys.readouterr().err == f"a5mi animate: error: {_message('animate', missing)}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["anim.txt"]  # no frame, no folder, no video


def test_a5_renders_with_the_core_packages_alone(tmp_path: Path) -> None:
    """A fresh interpreter in which no extra's module can be imported renders a scene with ``a5``."""
    (tmp_path / "s.txt").write_text(SCENE)
    code = (f"import sys\nfor m in {EXTRA_MODULES!r}:\n    sys.modules[m] = None\n"
            "from a5mi.entry import a5\nsys.argv = ['a5'] + sys.argv[1:]\na5()\n")
    p = subprocess.run([sys.executable, "-c", code, "-input", "s.txt", "-output", "o.png", "-size", "8", "8"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "o.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------------------------------- the declarations
def _third_party_imports(path: Path) -> set[str]:
    """Top-level names of the absolute imports of ``path`` that are neither the standard library nor a5mi."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        out |= {n.split(".")[0] for n in names}
    return out - set(sys.stdlib_module_names) - {"a5mi", "__future__"}


def _require_calls(path: Path) -> list[tuple[str, str]]:
    return [(node.args[0].value, node.args[1].value) for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "require"
            and len(node.args) == 2 and all(isinstance(a, ast.Constant) for a in node.args)]


SOURCES = sorted(p for folder in ("a5mi", "plugins", "converters") for p in (ROOT / folder).rglob("*.py"))


def test_the_code_imports_only_core_packages_directly() -> None:
    """Any other package is imported through :func:`a5mi.runtime.extras.require`, which names its extra."""
    direct = {str(p.relative_to(ROOT)): _third_party_imports(p) - CORE_MODULES for p in SOURCES}
    assert {k: v for k, v in direct.items() if v} == {}


def test_the_core_dependencies_are_the_core_modules() -> None:
    dists = importlib.metadata.packages_distributions()
    assert {_name(r) for r in PYPROJECT["dependencies"]} == {_name(dists[m][0]) for m in CORE_MODULES}
    assert not any("tomli" in r for r in PYPROJECT["dependencies"])


def test_each_required_module_comes_with_the_extra_it_names() -> None:
    """Every ``require(module, extra)`` in the code: ``extra`` is declared, and ``module``'s distribution is in
    it or is a dependency of one that is (``dask`` of ``distributed``). The ``test`` extra holds them all."""
    dists = importlib.metadata.packages_distributions()
    calls = {call for p in SOURCES for call in _require_calls(p)}
    assert {m for m, _ in calls} == set(EXTRA_MODULES)
    for module, extra in sorted(calls):
        listed = _distributions_of_extra(extra)
        brought = listed | {_name(r) for d in listed for r in importlib.metadata.requires(d) or ()
                            if "extra ==" not in r}
        assert _name(dists[module][0]) in brought, (module, extra, sorted(listed))
        assert listed <= _distributions_of_extra("test") and listed <= _distributions_of_extra("all")

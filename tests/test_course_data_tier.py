"""The course data is an opt-in tier (docs/INSTALL.md "The course data"): a fresh copy of the project in a 0700
folder with no ``../shared`` beside it and ``A5_DATA`` unset runs its tests green, the tests that need the data
skipped before they start and counted in one summary line that says why and how to provide the data; with
``A5MI_REQUIRE_COURSE_DATA=1`` (CI) the same tests fail instead.

The copy is the working tree's files as a clone would have them (``git ls-files``: tracked and untracked, not
ignored; no ``.venv``, no caches), run by this interpreter with the copy's own ``a5mi``, ``a5mi.plugins`` and
``a5mi.converters`` (:data:`BOOT`), so its ``a5mi.data_dir`` looks beside the copy. It runs three test files, not
the suite: ``test_reference.py`` (course-data tests by fixture and by a module-level list of the reference
images), ``test_geometry.py`` and ``test_obj_fast.py`` (module-level lists of the course's OBJ files, marked by
hand; tests without the data beside them, which must still pass)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import DATA_DOC, START_LINE, TIER_LINE

ROOT = Path(__file__).resolve().parent.parent
#: The three test files, by name wherever they live under tests/.
NAMES = ("test_reference.py", "test_geometry.py", "test_obj_fast.py")

#: Run pytest with the copy's packages: the copy's root first on sys.path (``a5mi``), and the two folders that
#: pyproject.toml maps into it (``plugins`` -> ``a5mi.plugins``, ``converters`` -> ``a5mi.converters``) loaded
#: from the copy before an installed (or editable) a5mi can supply them.
BOOT = r"""
import importlib.util, sys
from pathlib import Path
root = Path.cwd()
sys.path.insert(0, str(root))
import a5mi
assert a5mi.PROJECT_ROOT == root, a5mi.PROJECT_ROOT
for name, folder in (("a5mi.converters", "converters"), ("a5mi.plugins", "plugins")):
    spec = importlib.util.spec_from_file_location(name, root / folder / "__init__.py",
                                                  submodule_search_locations=[str(root / folder)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    setattr(a5mi, name.rpartition(".")[2], module)
import pytest
sys.exit(pytest.main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def fresh_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The project's files in ``<0700 folder>/a5mi``, nothing else in that folder."""
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs a git checkout of the project (the copy is what git ls-files lists)")
    names = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                           capture_output=True, check=True).stdout.decode().split("\0")
    home = tmp_path_factory.mktemp("fresh")
    home.chmod(0o700)
    copy = home / "a5mi"
    for name in filter(None, names):
        src = ROOT / name
        if src.is_file():  # a tracked file deleted in the working tree is not copied
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, copy / name)
    assert not (home / "shared").exists() and not (copy / "shared").exists()
    return copy


def _run(copy: Path, **env: str) -> subprocess.CompletedProcess[str]:
    environ = {k: v for k, v in os.environ.items() if k not in ("A5_DATA", "PYTHONPATH", "A5MI_REQUIRE_COURSE_DATA")}
    environ.update(env)
    files = [str(p.relative_to(copy)) for name in NAMES for p in sorted((copy / "tests").rglob(name))]
    assert len(files) == len(NAMES), files
    return subprocess.run([sys.executable, "-c", BOOT, "-q", "-n", "0", "-p", "no:cacheprovider", "-m", "not slow",
                           *files], cwd=copy, env=environ, capture_output=True, text=True, timeout=900)


def test_a_fresh_copy_without_course_data_skips_the_tier_in_one_line(fresh_copy: Path) -> None:
    p = _run(fresh_copy)
    out = p.stdout
    assert p.returncode == 0, out + p.stderr
    final = out.strip().splitlines()[-1]
    counts = dict((k, int(n)) for n, k in re.findall(r"(\d+) (passed|failed|errors?|skipped \(no course data\))",
                                                      final))
    n = counts.get("skipped (no course data)", 0)
    assert n > 0 and counts.get("passed", 0) > 0 and "failed" not in counts and "error" not in final, final
    tier = TIER_LINE.format(n=n, doc=DATA_DOC)
    assert out.count(tier) == 1 and out.splitlines()[0] == START_LINE, out  # one line before, one after
    assert "A5_DATA" in TIER_LINE and "../shared/a5" in TIER_LINE
    assert "course data not found" not in out.replace(tier, "").replace(START_LINE, ""), out  # no -ra list


def test_ci_can_require_the_course_data(fresh_copy: Path) -> None:
    p = _run(fresh_copy, A5MI_REQUIRE_COURSE_DATA="1")
    assert p.returncode == 1, p.stdout + p.stderr
    assert "course data not found at" in p.stdout and "course data tier" not in p.stdout, p.stdout

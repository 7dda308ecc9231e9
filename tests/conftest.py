"""Shared fixtures and settings of the whole suite (the only conftest).

* ``a5_data`` / ``scenes_dir``: the course data (``$A5_DATA`` or ../shared/a5). Every test that uses them is
  marked ``course_data`` automatically (``pytest -m "not course_data"`` runs the rest); a missing folder is a
  failure, never a skip: CI always has it.
* ``variant`` / ``mi``: the JIT variant activated once per session (llvm_ad_rgb unless ``A5MI_VARIANT`` says
  otherwise) with the a5mi plugins registered; ``mi`` is the ``mitsuba`` module.
* hypothesis profiles: ``fast`` (the default: ``make test``; derandomised, fixed example counts) and
  ``thorough`` (``make fuzz``, ``HYPOTHESIS_PROFILE=thorough``: ten times the examples, random seeds).
  Tests scale their own counts with :func:`examples`.
* ``A5MI_CACHE_DIR`` points at a temporary folder for the session (the glibc rand() prefix cache, the octree
  masks, the transformed-code cache), shared by the pytest-xdist workers (every cache file is written
  atomically): the controller sets it before it starts them.
* ``make test`` runs on pytest-xdist workers, a test file (or a group of files, :data:`XDIST_GROUPS`) one unit.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

from a5mi import data_dir

COURSE_DATA_FIXTURES = frozenset({"a5_data", "scenes_dir"})

settings.register_profile("fast", deadline=None, derandomize=True, database=None,
                          suppress_health_check=list(HealthCheck))
settings.register_profile("thorough", max_examples=1000, deadline=None, database=None,
                          suppress_health_check=list(HealthCheck))
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "fast"))


#: A textured unit square, the OBJ of the texture tests: z = 0, facing +z, corners (±1, ±1), uv (0,0)..(1,1)
#: (dp_du = (2, 0, 0), dp_dv = (0, 2, 0)).
QUAD_OBJ = """v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3
f 1/1 3/3 4/4
"""


def rgb(*v: float) -> dict[str, Any]:
    """A Mitsuba dict colour ``{'type': 'rgb', 'value': [r, g, b]}``."""
    return {"type": "rgb", "value": list(v)}


def a5_material(**kw: Any) -> dict[str, Any]:
    """An ``a5_material`` dict; tuple values become rgb colours (``diffuse_color=(1, 0, 0)``)."""
    out: dict[str, Any] = {"type": "a5_material"}
    for key, value in kw.items():
        out[key] = rgb(*value) if isinstance(value, tuple) else value
    return out


def assert_error_at(marked: str, message: str) -> None:
    """``marked`` is scene text with one ``^`` just before the character an error must point at: parsing the
    text without the mark raises a SceneError holding ``message`` at that 1-based line:col (the positioned
    errors ``FILE:LINE:COL: error: ...`` of docs/EXTENSIONS.md, at the offending keyword or number)."""
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.errors import SceneError

    before, mark, after = marked.partition("^")
    assert mark, "the scene text has no ^ mark"
    line, col = before.count("\n") + 1, len(before) - before.rfind("\n")
    with pytest.raises(SceneError) as err:
        parse_text(before + after)
    assert message in err.value.msg, err.value.msg
    assert (err.value.loc.line, err.value.loc.col) == (line, col), err.value.loc


def positioned_error_test(scene: Callable[[str], str], cases: list[tuple[str, str]]) -> Callable[[str, str], None]:
    """A test parametrized over ``cases`` (a fragment with its ``^`` mark, the message): the scene text
    ``scene(fragment)`` fails to parse at the mark (:func:`assert_error_at`). Bind it to a ``test_`` name."""

    @pytest.mark.parametrize(("fragment", "message"), cases)
    def test(fragment: str, message: str) -> None:
        assert_error_at(scene(fragment), message)

    return test


def examples(n: int) -> int:
    """``n`` examples under the ``fast`` profile, ten times as many under ``thorough``."""
    return n * (10 if settings().max_examples >= 1000 else 1)


@pytest.fixture(scope="session")
def a5_data() -> Path:
    """The course data; the suite needs it (CI has ../shared/a5 beside the clone)."""
    root = data_dir()
    if not (root / "SPEC.md").is_file():
        pytest.fail(f"course data not found at {root}: set A5_DATA to the folder holding SPEC.md and scenes/")
    return root


@pytest.fixture(scope="session")
def scenes_dir(a5_data: Path) -> Path:
    return a5_data / "scenes"


@pytest.fixture(scope="session")
def variant() -> str:
    """Activate the JIT variant once per session and register the a5mi plugins."""
    from a5mi.variant import activate

    return activate()


@pytest.fixture(scope="session")
def mi(variant: str) -> Any:
    """The ``mitsuba`` module with the session's variant active."""
    import mitsuba

    return mitsuba


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that reads the course data ``course_data``."""
    for item in items:
        if COURSE_DATA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.course_data)


#: Files that start sandboxed runs (user ids in a5mi.sandbox's range) run on one worker, one after the other:
#: test_grade_sandbox and test_hostile_class check that no process of that range is left after a run, which
#: another file's run in progress would break. (test_slurm grades in SLURM jobs: sandboxed runs too.)
XDIST_GROUPS = {name: "sandbox" for name in ("test_grade_sandbox.py", "test_grade_class.py", "test_hostile_class.py",
                                              "test_difftest.py", "test_view_engine.py", "test_slurm.py")}

if importlib.util.find_spec("xdist") is not None:
    def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
        """``make test``'s ``-n N --dist loadfile``: each test file is one unit of work, on one worker (its module
        fixtures are built once), except the files of one :data:`XDIST_GROUPS` group, which form one unit.
        (Grouping by ``xdist_group`` marks, ``--dist loadgroup``, does not work with pytest 9: xdist rewrites
        ``item._nodeid``, which pytest 9 no longer reads.)"""
        if config.getvalue("dist") != "loadfile":
            return None
        from xdist.scheduler import LoadScopeScheduling

        class FileGroups(LoadScopeScheduling):
            def _split_scope(self, nodeid: str) -> str:
                path = nodeid.split("::", 1)[0]
                return XDIST_GROUPS.get(Path(path).name, path)

        return FileGroups(config, log)


_SESSION_CACHE: str | None = None


def pytest_configure(config: pytest.Config) -> None:
    """Keep the glibc rand() prefix cache (a5mi.glibc_rand) of this test session out of the user's home."""
    global _SESSION_CACHE
    if "A5MI_CACHE_DIR" not in os.environ:
        _SESSION_CACHE = tempfile.mkdtemp(prefix="a5mi-test-cache-")
        os.environ["A5MI_CACHE_DIR"] = _SESSION_CACHE


def pytest_unconfigure(config: pytest.Config) -> None:
    if _SESSION_CACHE is not None:
        shutil.rmtree(_SESSION_CACHE, ignore_errors=True)
        os.environ.pop("A5MI_CACHE_DIR", None)

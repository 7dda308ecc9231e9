"""Shared fixtures and settings of the whole suite (the only conftest).

* ``a5_data`` / ``scenes_dir``: the course data (``$A5_DATA`` or ../shared/a5; docs/INSTALL.md "The course
  data"), an opt-in tier. Every test that uses them is marked ``course_data`` automatically, and a test that
  reads the data another way carries the mark itself (``pytest -m "not course_data"`` runs the rest). Without
  the data those tests are skipped before they start, and the run ends with one line saying how many, why and
  how to provide it (:data:`TIER_LINE`); with ``A5MI_REQUIRE_COURSE_DATA=1`` (CI) a missing folder is an
  error instead, so a lost data folder can never pass as a green run.
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


#: Where docs/INSTALL.md says what the course data is, where it comes from and how to point a5mi at it.
DATA_DOC = "docs/INSTALL.md#the-course-data"
#: The one summary line of a run without the course data (``{n}``: how many tests it skipped).
TIER_LINE = ("course data tier: {n} tests skipped: the course data (SPEC, scenes, meshes, reference renders) "
             "was not found; set A5_DATA to its folder or put it at ../shared/a5 ({doc})")
#: The line before such a run (also under ``-q``).
START_LINE = f"course data not found: its tests will be skipped (set A5_DATA; {DATA_DOC})"
#: The reason of each such skip (pytest's report), and the stats key they are counted under.
TIER_REASON = f"course data not found (set A5_DATA; {DATA_DOC})"
TIER_KEY = "skipped (no course data)"


def has_course_data() -> bool:
    """True when :func:`a5mi.data_dir` holds the course data (its SPEC.md)."""
    return (data_dir() / "SPEC.md").is_file()


@pytest.fixture(scope="session")
def a5_data() -> Path:
    """The course data (CI has ../shared/a5 beside the clone; without it these tests are skipped at
    collection, :func:`pytest_collection_modifyitems`, unless ``A5MI_REQUIRE_COURSE_DATA=1``)."""
    root = data_dir()
    if not (root / "SPEC.md").is_file():
        pytest.fail(f"course data not found at {root}: set A5_DATA to the folder holding SPEC.md and scenes/ "
                    f"({DATA_DOC})")
    return root


@pytest.fixture(scope="session")
def scenes_dir(a5_data: Path) -> Path:
    return a5_data / "scenes"


@pytest.fixture(scope="session")
def variant() -> str:
    """Activate the JIT variant once per session and register the a5mi plugins."""
    from a5mi.runtime.variant import activate

    return activate()


@pytest.fixture(scope="session")
def render_text(variant: str) -> Callable[..., Any]:
    """:func:`helpers.render_text` with the session's variant active: ``render_text(text, **RenderOptions)``."""
    from helpers import render_text as render

    return render


@pytest.fixture(scope="session")
def mi(variant: str) -> Any:
    """The ``mitsuba`` module with the session's variant active."""
    import mitsuba

    return mitsuba


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that reads the course data ``course_data``; without the data, skip them (with
    ``A5MI_REQUIRE_COURSE_DATA=1`` they run and fail instead)."""
    skip = not has_course_data() and os.environ.get("A5MI_REQUIRE_COURSE_DATA", "") in ("", "0")
    for item in items:
        if COURSE_DATA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.course_data)
        if skip and item.get_closest_marker("course_data") is not None:
            item.add_marker(pytest.mark.skip(reason=TIER_REASON), append=False)  # before an empty-set skip


def pytest_report_header(config: pytest.Config) -> str | None:
    """The header (without ``-q``): where the course data is."""
    return f"course data: {data_dir()}" if has_course_data() else None


def pytest_sessionstart(session: pytest.Session) -> None:
    """Before the run, also under ``-q`` (``make test``): one line when the course data is missing, saying that
    its tests will be skipped (or fail, under ``A5MI_REQUIRE_COURSE_DATA``). The controller only, under xdist."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if has_course_data() or reporter is None or hasattr(session.config, "workerinput"):
        return
    if os.environ.get("A5MI_REQUIRE_COURSE_DATA", "") not in ("", "0"):
        reporter.write_line("course data not found, and A5MI_REQUIRE_COURSE_DATA is set: its tests will fail")
    else:
        reporter.write_line(START_LINE)


@pytest.hookimpl(tryfirst=True)
def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    """The course data tier's one line: the skips of :data:`TIER_REASON` move from ``skipped`` to their own
    count (so ``-ra`` lists none of them and the final line says ``N skipped (no course data)``), and
    :data:`TIER_LINE` says how many, why and how to provide the data. Runs in the controller under
    pytest-xdist too (the reports carry the reason)."""
    stats = terminalreporter.stats
    tier = [r for r in stats.get("skipped", []) if _skip_reason(r) == TIER_REASON]
    if not tier:
        return
    stats["skipped"] = [r for r in stats["skipped"] if _skip_reason(r) != TIER_REASON]
    if not stats["skipped"]:
        del stats["skipped"]
    stats[TIER_KEY] = tier
    terminalreporter.write_sep("-", "course data")
    terminalreporter.write_line(TIER_LINE.format(n=len(tier), doc=DATA_DOC))


def _skip_reason(report: Any) -> str | None:
    """The reason of a skip report (``longrepr`` is ``(path, line, 'Skipped: REASON')``)."""
    longrepr = getattr(report, "longrepr", None)
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2]).removeprefix("Skipped: ")
    return None


#: Files that start sandboxed runs (user ids in a5mi.sandbox.bwrap's range) run on one worker, one after the other:
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
    """Keep the glibc rand() prefix cache (a5mi.render.glibc_rand) of this test session out of the user's home, and
    a running ``a5mi serve`` out of the suite's ``a5`` processes (their CPU and memory bounds are their own)."""
    global _SESSION_CACHE
    os.environ.setdefault("A5MI_NO_SERVE", "1")  # the suite's a5 processes run in-process (docs/SERVE.md)
    if "A5MI_CACHE_DIR" not in os.environ:
        _SESSION_CACHE = tempfile.mkdtemp(prefix="a5mi-test-cache-")
        os.environ["A5MI_CACHE_DIR"] = _SESSION_CACHE


def pytest_unconfigure(config: pytest.Config) -> None:
    if _SESSION_CACHE is not None:
        shutil.rmtree(_SESSION_CACHE, ignore_errors=True)
        os.environ.pop("A5MI_CACHE_DIR", None)

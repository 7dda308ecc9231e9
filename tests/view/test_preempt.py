"""``a5mi view`` and the work estimate (docs/VIEW.md, docs/USAGE.md "Work estimate and progress"): a long
render reports its tiles with the rays so far and an ETA, a newer control change pre-empts it at the next tile
and the newest request is the one rendered; a render over an hour is refused with the positioned line."""

from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from view_scenes import beside_loop, time_limit, write_scene

from a5mi.render import estimate as est
from a5mi.render.options import RenderOptions

OPTS = RenderOptions(width=40, height=40, shadows=True)


@pytest.fixture(scope="module")
def session(variant):  # noqa: ANN001, ANN201 - fixtures
    from a5mi.view.build import ViewSession

    return ViewSession()


def test_a_newer_control_change_pre_empts_a_long_render(tmp_path: Path, session: Any,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """With a kept rate of 100 rays/s the 40 x 40 render is estimated at minutes: it is cut into tiles (16 at
    most) that report ``rays`` and ``eta``. After its first tile a control change (-bounces 1) arrives: the
    render stops at that step (never reaching its last tile) and the one published frame is -bounces 1's, the
    image a render of those options gives."""
    from a5mi.view.controls import describe_controls
    from a5mi.view.engine import ViewEngine
    from a5mi.view.live import run_engine
    from a5mi.view.png import png_bytes
    from a5mi.view.server import Hub, Jobs
    from a5mi.view.watcher import Watcher

    monkeypatch.setattr(est, "measured_rate", lambda path=None: 100.0)
    newer = dataclasses.replace(OPTS, bounces=1)
    events: list[tuple[int, str, int, int, dict[str, Any]]] = []
    jobs = Jobs()

    class RecordingHub(Hub):
        renders = 0

        def progress(self, stage: str, done: int, total: int, **extra: Any) -> None:
            if stage == "render" and done == 0:
                self.renders += 1
            events.append((self.renders, stage, done, total, extra))
            if self.renders == 1 and stage == "render" and 0 < done < total:
                jobs.render(newer)  # the page's control change, while the first render runs
            super().progress(stage, done, total, **extra)

    with time_limit(300):
        engine = ViewEngine(str(write_scene(tmp_path / "s.txt")), session)
        hub, stop = RecordingHub(), threading.Event()
        watcher = Watcher(lambda: jobs.render(reload=True), interval=0.05)

        def drive() -> None:
            while hub.state().get("version", 0) < 1:
                time.sleep(0.02)

        beside_loop(drive, stop, lambda: run_engine(engine, hub, jobs, watcher, OPTS, stop=stop, preview=False))
    first = [e for e in events if e[0] == 1 and e[1] == "render"]
    second = [e for e in events if e[0] == 2 and e[1] == "render"]
    assert len(first) == 2, first  # the start and the first tile: pre-empted there
    assert first[-1][2] < first[-1][3]
    assert len(second) > 2 and second[-1][2] == second[-1][3]  # the newer request: every tile
    for _, _, done, total, extra in second:
        assert set(extra) == {"rays", "eta", "estimate"} and extra["eta"] >= 0
        work = est.estimate(engine.desc, newer)
        assert extra["rays"] == pytest.approx(work.rays * done / total)
    state = hub.state()
    assert state["version"] == 1 and state["error"] is None
    assert state["controls"] == describe_controls(newer) and engine.frame is not None
    assert engine.frame.options == newer
    expected = session.render(engine.desc, newer).image
    assert hub.image("render") == png_bytes(expected, str(tmp_path))


def test_view_refuses_a_render_over_an_hour_unless_forced(tmp_path: Path, session: Any,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    from a5mi.converters.errors import SceneError
    from a5mi.view.engine import ViewEngine

    monkeypatch.setattr(est, "measured_rate", lambda path=None: 0.1)  # 1600 camera rays: hours
    engine = ViewEngine(str(write_scene(tmp_path / "s.txt")), session)
    engine.load(False)
    with pytest.raises(SceneError) as caught:
        engine.render(OPTS)
    assert str(caught.value).startswith(f"{tmp_path / 's.txt'}:") and ": error: this render may trace " in str(
        caught.value) and "-force" in str(caught.value)
    forced = ViewEngine(str(tmp_path / "s.txt"), session, force=True)
    forced.load(False)
    assert forced.render(OPTS, compare=False).size == (40, 40)

"""Progress with the work estimate (docs/USAGE.md "Work estimate and progress"): ``-v`` lines off a terminal,
the rays so far and the ETA before the first tile."""

from __future__ import annotations

import io

import pytest
from helpers import FakeClock

from a5mi.cli.progress import ProgressBar

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def test_log_lines_every_interval_with_rays_and_eta_and_none_at_the_end() -> None:
    """Tiles of 250 of 1000 samples, a bound of 1e7 rays: no line before 10 s; at 12 s, half done, one whole
    line with half the bound and the ETA (12 s elapsed for half: 12 s left); the next line not before 10 s
    more; the last tile writes none (the render's own report follows)."""
    clock, out = FakeClock(), io.StringIO()
    bar = ProgressBar(out, enabled=False, log=True, log_every=10.0, rays=1e7, clock=clock)
    clock.now += 4.0
    bar(250, 1000)
    assert out.getvalue() == ""
    clock.now += 8.0
    bar(500, 1000)
    assert out.getvalue() == "a5: progress 50% (500 of 1000 samples), up to 5e+06 rays so far, 12 s, eta 12 s\n"
    clock.now += 4.0
    bar(750, 1000)
    assert out.getvalue().count("\n") == 1  # 4 s since the last line
    clock.now += 10.0
    bar(1000, 1000)
    assert out.getvalue().count("\n") == 1
    assert "\r" not in out.getvalue()


def test_eta_before_the_first_tile_is_the_estimate_s() -> None:
    clock = FakeClock()
    bar = ProgressBar(io.StringIO(), enabled=False, log=True, seconds=300.0, unit="bands", prog="a5mi render",
                      clock=clock)
    clock.now += 30.0
    assert bar.eta(clock.now) == 270.0
    assert bar.log_line(clock.now) == "a5mi render: progress 0% (0 of ? bands), 30 s, eta 4 min"
    assert ProgressBar(io.StringIO(), enabled=False, clock=clock).eta(clock.now) is None


def test_the_ticker_logs_while_one_long_tile_renders() -> None:
    """A render of one tile (no callback yet) still writes a line every ``log_every`` seconds from the thread."""
    import time

    out = io.StringIO()
    with ProgressBar(out, enabled=False, log=True, log_every=0.02, tick=0.005, seconds=5.0) as bar:
        deadline = time.monotonic() + 30.0
        while "progress" not in out.getvalue() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert bar.done == 0
    assert out.getvalue().startswith("a5: progress 0% (0 of ? samples), ")
    assert ", eta " in out.getvalue()


def test_the_terminal_bar_shows_the_rays_so_far_and_the_estimate_s_eta() -> None:
    clock = FakeClock()
    bar = ProgressBar(io.StringIO(), enabled=True, rays=2e6, seconds=60.0, width=10, clock=clock)
    clock.now += 2.0
    assert bar.line(clock.now).endswith("eta <   58 s")
    bar(500, 1000)
    assert bar.line(clock.now).endswith("up to 1e+06 rays")

"""The render progress bar: moves between tiles on the measured rate, only on a terminal."""

from __future__ import annotations

import io
import time

import pytest
from helpers import FakeClock

from a5mi.cli.progress import ProgressBar

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def test_estimate_moves_between_tiles_and_stops_at_the_tile_in_flight() -> None:
    """Tiles of 250 of 1000 samples: the first (with the compile) takes 3 s, the second 1 s, so the rate is
    250/s; 0.5 s after the second tile the estimate is 625, and it never passes 749 (the third tile's end - 1)."""
    clock = FakeClock()
    bar = ProgressBar(io.StringIO(), enabled=True, delay=1.0, clock=clock)
    clock.now += 3.0
    bar(250, 1000)
    assert 250 + 49 <= bar.estimate(clock.now + 0.6) <= 250 + 50  # only tile 1 measured: its rate, 250 / 3 s
    clock.now += 1.0
    bar(500, 1000)
    assert bar.estimate(clock.now + 0.5) == 625
    assert bar.estimate(clock.now + 60.0) == 749
    line = bar.line(clock.now + 0.5)
    assert line.startswith("[" + "#" * 15 + "-" * 3 + "." * 12 + "]") and "62%" in line


def test_line_before_any_tile_sweeps_and_the_last_tile_ends_the_line() -> None:
    clock = FakeClock()
    out = io.StringIO()
    bar = ProgressBar(out, enabled=True, delay=1.0, width=10, tick=0.1, clock=clock)
    sweeps = {bar.line(clock.now + 0.1 * k) for k in range(12)}
    assert len(sweeps) > 5 and all("####" in s for s in sweeps)  # the block moves while nothing is known
    bar(1, 2)  # before the delay: nothing drawn
    assert out.getvalue() == ""
    clock.now += 1.5
    bar(1, 2)
    assert out.getvalue().startswith("\r[#####") and "\n" not in out.getvalue()
    bar(2, 2)
    assert out.getvalue().endswith("\r[##########] 100%" + out.getvalue().rsplit("100%", 1)[1])
    assert out.getvalue().endswith("\n")
    bar(2, 2)
    assert out.getvalue().count("\n") == 1
    quick = io.StringIO()
    fast = ProgressBar(quick, enabled=True, delay=1.0, clock=clock)
    fast(2, 2)  # done before the delay: no bar at all
    assert quick.getvalue() == ""


def test_ticker_redraws_while_a_tile_renders_and_closes_the_line() -> None:
    """As a context manager the bar redraws from a thread (no callback needed), and leaving ends the line."""
    out = io.StringIO()
    with ProgressBar(out, enabled=True, delay=0.0, tick=0.01) as bar:
        deadline = time.monotonic() + 30.0
        while out.getvalue().count("\r") < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert bar.shown
    text = out.getvalue()
    assert text.count("\r") >= 3 and text.endswith("\n")


def test_disabled_bar_writes_nothing() -> None:
    out = io.StringIO()
    with ProgressBar(out, enabled=False, delay=0.0, tick=0.01) as bar:
        time.sleep(0.05)
        bar(5, 10)
        bar(10, 10)
    assert out.getvalue() == ""

"""``a5mi difftest`` campaign statistics and exit status: identical scenes (PSNR inf) are neither averaged
as a stand-in number nor written as ``null``; a campaign where a scene is below the threshold, or where the
other binary fails, exits 1 (so CI can use it), one where every scene passes exits 0."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

from a5mi.compare import Metrics
from a5mi.difftest import campaign
from a5mi.difftest.generate import random_scene
from a5mi.difftest.runner import Outcome
from a5mi.platform.errors import ExitStatus


def _row(i: int, psnr: float | None) -> campaign.Row:
    m = None if psnr is None else Metrics(psnr, 0.1, 0.0, 3.0, None, 2.0, 20, 20)
    return campaign.Row(i, random_scene(0, i, 20), Outcome(m, "ok" if m else "binary failed: exit status 3"))


def test_half_identical_scenes_have_an_infinite_median_not_a_stand_in() -> None:
    rows = [_row(0, math.inf), _row(1, 40.0), _row(2, math.inf), _row(3, 86.0)]
    s = campaign.summary(rows, 50.0)
    assert s["median_psnr"] == math.inf and s["identical"] == 2 and s["below_threshold"] == 1
    assert campaign.psnr_text(s["median_psnr"]) == "inf"
    assert campaign.summary(rows[1:], 50.0)["median_psnr"] == 86.0  # 40, 86, inf: the middle one
    assert campaign.summary([_row(0, 40.0), _row(1, 60.0)], 50.0)["median_psnr"] == 50.0
    assert campaign.summary([_row(0, None)], 50.0)["median_psnr"] is None
    doc = json.loads(campaign.report_json(rows + [_row(4, None)], 50.0, 0))
    assert [e["psnr"] for e in doc["scenes"]] == ["inf", 40.0, "inf", 86.0, None]
    assert doc["summary"]["median_psnr"] == "inf" and float(doc["scenes"][0]["psnr"]) == math.inf
    assert doc["passed"] is False
    assert "| inf |" in campaign.table_line(rows[0])


def test_passed_means_every_scene_compared_at_or_above_the_threshold() -> None:
    assert campaign.passed([_row(0, math.inf), _row(1, 50.0)], 50.0)
    assert not campaign.passed([_row(0, math.inf), _row(1, 49.9)], 50.0)
    assert not campaign.passed([_row(0, math.inf), _row(1, None)], 50.0)  # the other binary failed


def test_cli_exits_1_when_every_scene_fails(a5_data: Path, tmp_path: Path) -> None:
    """A binary that writes no image fails on every scene: the summary says so and the exit status is 1."""
    a5mi = shutil.which("a5mi", path=str(Path(sys.executable).parent))
    assert a5mi is not None
    broken = tmp_path / "broken"
    broken.write_text("#!/bin/sh\necho 'no image today' >&2\nexit 3\n")
    broken.chmod(0o755)
    proc = subprocess.run([a5mi, "difftest", "--binary", str(broken), "--count", "1", "--mean-size", "16",
                           "--budget", "1", "--seed", "2"], capture_output=True, text=True, timeout=300,
                          check=False)
    assert proc.returncode == ExitStatus.DIFFER, proc.stderr
    assert "1 failed runs, 1 below 50 dB" in proc.stdout and "median PSNR - dB" in proc.stdout
    help_text = subprocess.run([a5mi, "difftest", "-h"], capture_output=True, text=True, timeout=60,
                               check=False).stdout
    assert ("Exit status: 0 every scene at or above --threshold (identical scenes: inf dB); 1 a scene below"
            in " ".join(help_text.split()))

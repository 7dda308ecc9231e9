"""The limits a render's options keep together (a5mi/render/limits.py): one check for ``a5`` and the live page;
the memory estimate covers the integrators' own buffers (photon maps and kd-trees, ppm statistics, irradiance
records) and split renders' bands, so an impossible render is one line with figures, exit 2, before any work."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import TESTS

from a5mi.platform import resources
from a5mi.platform.errors import UsageError
from a5mi.render import limits
from a5mi.render.options import RenderOptions

BOX = (TESTS / "data" / "scenes" / "photon_box.txt").read_text()
BIG = str(1 << 26)


def _a5(tmp_path: Path, capsys, *flags: str) -> tuple[int, list[str]]:  # noqa: ANN001
    from a5mi.cli import run

    (tmp_path / "box.txt").write_text(BOX)
    status = run(["-input", str(tmp_path / "box.txt"), "-output", str(tmp_path / "o.png"), "-size", "16", "16",
                  *flags])
    return status, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("flags, words", [
    (("-integrator", "photon", "-photons", BIG, "-caustic_photons", BIG),
     f"-size 16 16 -integrator photon -photons {BIG} -caustic_photons {BIG} needs about 1369.2 GB of memory"),
    (("-integrator", "ppm", "-photons", BIG, "-caustic_photons", "0"),
     f"-size 16 16 -integrator ppm -photons {BIG} -caustic_photons 0 needs about 684.7 GB of memory"),
    (("-integrator", "photon", "-photons", str(1 << 24), "-caustic_photons", "0", "-workers", "4"),
     f"-size 16 16 -integrator photon -photons {1 << 24} -caustic_photons 0 on 4 workers needs about 685.6 GB"),
])
def test_an_integrator_too_large_for_memory_is_one_line_before_any_work(tmp_path: Path, capsys, monkeypatch,  # noqa: ANN001
                                                                          flags: tuple[str, ...], words: str) -> None:
    monkeypatch.setenv("A5MI_MEMORY_LIMIT", str(16 << 30))
    status, err = _a5(tmp_path, capsys, *flags)
    assert status == 2 and len(err) == 1, err
    assert words in err[0] and err[0].endswith("of memory; 17.2 GB is available"), err[0]
    assert not (tmp_path / "o.png").exists()


def test_irradiance_records_and_ppm_statistics_grow_with_the_samples() -> None:
    o = RenderOptions(width=1000, height=1000)
    base = limits.memory_need(o)
    n = 1000 * 1000
    ic = dataclasses.replace(o, integrator="irradiancecache")
    assert limits.memory_need(ic) - base == n * resources.IC_RECORD_BYTES + (1 << 20) * resources.TILE_RAY_BYTES
    ppm = dataclasses.replace(o, integrator="ppm", photons=10, caustic_photons=0)
    per_photon = resources.PHOTON_HIT_BYTES * resources.ROULETTE_MEAN_HITS  # photon_depth 0: Russian roulette
    assert limits.memory_need(ppm) - base == n * resources.PPM_SAMPLE_BYTES + 10 * per_photon
    # a split render: the client's bands, and every local worker is a renderer with its own photon maps
    photon = dataclasses.replace(o, integrator="photon", photons=1000, caustic_photons=0)
    one = limits.memory_need(dataclasses.replace(photon, integrator="whitted"))
    worker = resources.BASE_BYTES + 1000 * per_photon + (one - resources.BASE_BYTES) // 2
    assert limits.memory_need(photon, workers=2) == one + 12 * n + 2 * worker
    assert limits.memory_need(photon, workers=0) == one + 12 * n  # a remote scheduler: only the client here


@pytest.mark.parametrize("depth", [10, 0])
def test_the_photon_estimate_covers_a_measured_render(tmp_path: Path, depth: int) -> None:
    """A bright case for the maps (a closed box of albedo 0.9): the child's peak resident memory stays under
    :func:`a5mi.render.limits.memory_need` of its options. With ``-photon_depth 10`` every photon bounces until
    the cut, the case the per-hit figure was measured on, and the estimate is within 3x; with Russian roulette
    alone (0) the estimate assumes a lossless scene (51 hits), so here (10 hits on average) it is only a bound."""
    (tmp_path / "box.txt").write_text(BOX)
    n = 400_000
    # the render's own peak, written by the render process itself as it exits (RUSAGE_CHILDREN of this test's
    # process would be the largest child any earlier test of the same worker waited for)
    py = ("import atexit, resource, sys; from a5mi.entry import a5; atexit.register(lambda: open('peak', 'w')"
          ".write(str(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss))); sys.argv = ['a5'] + sys.argv[1:]; a5()")
    p = subprocess.run([sys.executable, "-c", py, "-input", "box.txt", "-output", "o.png", "-size", "16", "16",
                        "-integrator", "photon", "-photons", str(n), "-caustic_photons", str(n),
                        "-photon_depth", str(depth), "-force"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=900, env={**os.environ, "A5MI_CACHE_DIR": str(tmp_path)})
    assert p.returncode == 0, p.stderr
    peak = int((tmp_path / "peak").read_text()) * 1024
    need = limits.memory_need(RenderOptions(width=16, height=16, integrator="photon", photons=n, caustic_photons=n,
                                            photon_depth=depth))
    assert peak <= need, (peak, need)
    if depth:
        # and not a wild overestimate where the model is exact: the same command's own peak spreads from 0.70 GB
        # (alone: 0.70-0.84 GB in six runs on 7 Dec 2026; 0.79 GB was the lowest seen before, and 2.5x of it
        # failed at 0.70 and 0.72) to 1.54 GB (inside a loaded suite); the model (1.81 GB) covers the highest, so
        # it is 2.2-2.6x the lowest by construction: 3x of any single peak
        assert need <= 3 * peak, (peak, need)


def test_the_page_and_the_command_line_refuse_the_same_combinations() -> None:
    from a5mi.view.controls import ControlError, apply

    o = RenderOptions(width=16, height=16)
    for values in ({"indirect": 200, "bounces": 2}, {"indirect": 4096, "bounces": 64},
                   {"indirect": 5, "integrator": "path"}, {"filter": True, "width": 2}):
        with pytest.raises(ControlError) as page:
            apply(o, values)
        with pytest.raises(UsageError) as line:
            limits.check_options(dataclasses.replace(o, **values))
        assert str(page.value) == str(line.value)
    assert str(page.value).startswith("-filter without -jitter")
    assert apply(o, {"indirect": 100, "bounces": 2}).indirect == 100  # (100 + 1) 2 = 202 pending: allowed

"""``a5mi photons`` and ``a5 -integrator photon | ppm`` from the command line (docs/EXTENSIONS.md E.16, E.17)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from helpers import ROOT

from a5mi import cli
from a5mi.platform.errors import ExitStatus

SCENE = str(ROOT / "scenes" / "caustic_sphere.txt")
SMALL = ["-photons", "800", "-caustic_photons", "3000", "-bounces", "6"]


def test_photons_command_draws_the_maps_and_counts_per_surface(mi, tmp_path: Path, capsys) -> None:
    from a5mi.platform import imageio

    out = tmp_path / "map.png"
    assert cli.run_a5mi(["photons", SCENE, "-o", str(out), "--size", "24", "24", "-shadows", *SMALL, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["emitted"] == {"global": 800, "caustic": 3000}
    surfaces = {s["name"]: s for s in report["surfaces"]}
    floor = next(s for name, s in surfaces.items() if name.startswith("plane"))
    assert floor["direct"] > 0 and floor["caustic"] > 0            # the caustic lands on the floor
    assert all(s["caustic"] == 0 for name, s in surfaces.items() if name.startswith("sphere"))  # glass: kd = 0
    img = imageio.read_uint8(out)
    assert img.shape == (24, 24, 3)
    rgb = img.astype(np.int64)     # the caustic colour (1, 0.6, 0.1) after SPEC B.1's quantisation
    orange = (rgb[..., 0] == 255) & (np.abs(rgb[..., 1] - 153) <= 1) & (np.abs(rgb[..., 2] - 26) <= 1)
    assert orange.sum() > 0 and report["visible"]["caustic"] > 0


def test_photons_command_usage_errors(capsys) -> None:
    assert cli.run_a5mi(["photons", SCENE]) == ExitStatus.USAGE
    assert cli.run_a5mi(["photons", SCENE, "-o", "a.png", "--workers", "2"]) == ExitStatus.USAGE
    assert cli.run_a5mi(["photons", SCENE, "--ppm", "a.png", "--workers", "2", "--scheduler", "tls://x:1"]) == \
        ExitStatus.USAGE
    assert cli.run_a5mi(["photons", SCENE, "-o", "a.png", "-photon_filter", "gauss"]) == ExitStatus.USAGE
    err = capsys.readouterr().err
    assert "a5mi photons: error:" in err


def test_a5_renders_photon_and_ppm(mi, tmp_path: Path) -> None:
    from a5mi.platform import imageio

    a, b = tmp_path / "p.png", tmp_path / "q.png"
    assert cli.run(["-input", SCENE, "-output", str(a), "-size", "16", "16", "-integrator", "photon", *SMALL,
                    "-k", "20", "-photon_filter", "cone", "-shadows"]) == 0
    assert cli.run(["-input", SCENE, "-output", str(b), "-size", "16", "16", "-integrator", "ppm", *SMALL,
                    "-spp", "2", "-ppm_alpha", "0.5", "-shadows"]) == 0
    for p in (a, b):
        img = imageio.read_uint8(p).astype(np.float64)
        assert img.shape == (16, 16, 3) and img.mean() > 1.0

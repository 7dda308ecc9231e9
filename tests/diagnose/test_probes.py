"""The probe scenes of ``a5mi diagnose --binary`` (a5mi/diagnose/probes.py).

* Every catalogued mistake shows on some probe and any two mistakes give different images on some probe
  (a5mi's own mutants, glibc's jitter): "shows" and "apart" mean a mean squared difference over 5e-6 on [0, 1]
  levels (PSNR under 53 dB, SPEC C's level of a faithful renderer; rounding, the subtlest, is 7.7e-6). The whole
  catalogue is the slow tier; a subset across every layer runs every day.
* a5soln's own images (tests/data/diagnose/README.md says which command made each) are diagnosed against a5mi's
  reference: the correct one matches; a forgotten flag (no -shadows, -bounces 0, no -jitter -filter) and image
  edits (upside down, red/blue swapped, sRGB gamma) are named.
* ``--binary``: a wrapper that runs a5mi's ``a5`` with a ``-mistake`` is run in the sandbox on the probes and
  that mistake is found (slow: one a5 process per probe).
"""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pytest

from a5mi.render.options import MISTAKES

DATA = Path(__file__).parent.parent / "data" / "diagnose"
THRESHOLD = 5e-6


def _mse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((a - b) ** 2))


def _check_distinguishes(names: list[str]) -> None:
    from a5mi.diagnose.probes import signatures

    sig = signatures(names)
    weak = [m for m in names if max(_mse(x, r) for x, r in zip(sig[m], sig[""], strict=True)) <= THRESHOLD]
    assert not weak, f"mistakes that show on no probe: {weak}"
    alike = [(a, b) for a, b in itertools.combinations(names, 2)
             if max(_mse(x, y) for x, y in zip(sig[a], sig[b], strict=True)) <= THRESHOLD]
    assert not alike, f"pairs no probe tells apart: {alike}"


@pytest.mark.slow
def test_probes_show_every_mistake_and_tell_every_pair_apart(variant: str) -> None:
    _check_distinguishes(list(MISTAKES))


def test_probes_tell_a_subset_apart(variant: str) -> None:
    _check_distinguishes(["no_shadows", "shadow_first_light_only", "no_recursion", "bounces_minus_one",
                          "marble_no_octaves", "background_wrong_direction", "no_jitter", "blur_one_direction",
                          "rounding", "mirrored", "normal_by_m", "normal_not_normalised"])


def _spheres(tmp_path: Path):  # noqa: ANN202 - (description, options)
    from a5mi.diagnose.probes import PROBES, describe_probe

    probe = PROBES[3]
    return describe_probe(probe, tmp_path), probe.options()


@pytest.fixture(scope="module")
def session(variant: str):  # noqa: ANN201
    from a5mi.render.session import RenderSession

    return RenderSession()


def _read(name: str) -> np.ndarray:
    from a5mi.platform.imageio import read_uint8

    return read_uint8(DATA / f"a5soln_spheres_{name}.png")[..., :3]


@pytest.mark.parametrize("name,edit,expected", [
    ("correct", None, None),
    ("noshadows", None, "no_shadows"),
    ("bounces0", None, "no_recursion"),
    ("nofilter", None, "no_supersampling"),
    ("correct", "upside_down", "upside_down"),
    ("correct", "red_blue_swapped", "red_blue_swapped"),
    ("correct", "srgb_gamma", "srgb_gamma"),
])
def test_a5soln_images_diagnosed(session, tmp_path: Path, name: str, edit: str | None, expected: str | None) -> None:
    from a5mi.diagnose.rank import diagnose
    from a5mi.platform.imageio import quantize
    from a5mi.render.filters import srgb_encode

    img = _read(name)
    if edit == "upside_down":
        img = img[::-1]
    elif edit == "red_blue_swapped":
        img = img[..., ::-1]
    elif edit == "srgb_gamma":   # what an image editor's "apply sRGB" does to the bytes
        img = quantize(srgb_encode(img.astype(np.float32) / 255) + 0.5 / 255)
    desc, options = _spheres(tmp_path)
    d = diagnose(np.ascontiguousarray(img), desc, options, session=session)
    if expected is None:
        assert d.verdict == "match" and d.causes == [], (d.verdict, d.psnr)
    else:
        assert d.verdict == "diagnosis" and d.causes[0].mistakes == (expected,), \
            [(c.mistakes, c.explained) for c in d.causes]


def test_a5soln_placed_probe_matches(session, tmp_path: Path) -> None:
    """a5soln's own image of the ``placed`` probe (non-uniform Transforms of a sphere, a triangle and a plane)
    matches a5mi's reference: the normal-transform mistakes are not named on a correct image."""
    from a5mi.diagnose.probes import PROBES, describe_probe
    from a5mi.diagnose.rank import diagnose
    from a5mi.platform.imageio import read_uint8

    probe = PROBES[4]
    img = read_uint8(DATA / "a5soln_placed_correct.png")[..., :3]
    d = diagnose(np.ascontiguousarray(img), describe_probe(probe, tmp_path), probe.options(), session=session)
    assert probe.name == "placed" and d.verdict == "match" and d.causes == [], (d.verdict, d.psnr)


@pytest.mark.slow
def test_binary_with_a_mistake_is_found(tmp_path: Path, variant: str) -> None:
    """A wrapper script that runs this checkout's ``a5`` with ``-mistake eta_inverted``, run as ``--binary`` (in
    bubblewrap where the machine has it): the probes name eta_inverted, and only it."""
    from a5mi.diagnose.probes import diagnose_binary
    from a5mi.sandbox.bwrap import isolation

    a5 = Path(sys.executable).parent / "a5"
    (tmp_path / "bin").mkdir(mode=0o755)
    wrapper = tmp_path / "bin" / "a5-student"
    wrapper.write_text(f'#!/bin/sh\nexec {a5} "$@" -mistake eta_inverted\n')
    wrapper.chmod(0o755)
    tmp_path.chmod(0o755)
    root = Path(__file__).resolve().parents[2]
    report = diagnose_binary(str(wrapper), read_only=(str(root), sys.base_prefix, sys.prefix),
                             require_sandbox=isolation() == "bwrap")
    assert all(p.status == "ok" for p in report.probes), [(p.probe, p.status) for p in report.probes]
    assert set(report.found) == {"eta_inverted"} and not report.unexplained, report.to_dict()["found"]


def test_binary_that_writes_nothing_is_a_difference(tmp_path: Path, capsys) -> None:
    """``--binary`` with a program that writes no image: each probe says so, exit 1; a missing program: exit 2."""
    from a5mi.cli import run_a5mi
    from a5mi.diagnose.probes import PROBES

    assert run_a5mi(["diagnose", "--binary", "/bin/false"]) == 1
    out = capsys.readouterr().out
    assert out.count("binary failed") == len(PROBES) == 5 and "no mistake found" not in out
    assert run_a5mi(["diagnose", "--binary", str(tmp_path / "nope")]) == 2
    assert "is not a file" in capsys.readouterr().err

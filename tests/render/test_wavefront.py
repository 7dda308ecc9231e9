"""The E.5 wavefront (a5mi/render/passes.py, docs/EXTENSIONS.md E.24): many ``-spp`` passes traced in one integrator
call
give the image of the pass-by-pass render bit for bit (``a5_whitted``: area lights, lens, gloss, dispersion, a
medium; ``a5_path``), also when the passes are split over several calls and the sample count is no multiple of
the SIMD packet."""

from __future__ import annotations

import os

import numpy as np
import pytest
from helpers import ROOT

from a5mi.render import passes
from a5mi.render.options import RenderOptions

DATA = str(ROOT / "scenes")

CASES = [("soft_shadows.txt", {}), ("dof.txt", {}), ("glossy.txt", {}), ("prism.txt", {}), ("fog_shafts.txt", {}),
         ("colour_bleeding.txt", {"integrator": "path", "bounces": 3})]


def _render(name: str, options: RenderOptions) -> np.ndarray:
    from a5mi.render.session import describe_file, render
    from a5mi.runtime.variant import activate

    activate()
    desc, _ = describe_file(os.path.join(DATA, name))
    return render(desc, options).image


@pytest.mark.parametrize(("name", "extra"), CASES, ids=[c[0] for c in CASES])
def test_wavefront_is_bit_identical_to_pass_by_pass(name: str, extra: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    options = RenderOptions(width=21, height=13, shadows=True, spp=5, seed=3, **{"bounces": 2, **extra})
    stride = -(-21 * 13 // passes.PACKET) * passes.PACKET
    monkeypatch.setattr(passes, "WAVEFRONT_LANES", 0)             # one call per pass, as before the wavefront
    reference = _render(name, options)
    batches: list[int] = []
    batch_sum = passes._batch_sum
    monkeypatch.setattr(passes, "_batch_sum", lambda total, rgb, n, s, b: batches.append(b) or batch_sum(
        total, rgb, n, s, b))
    monkeypatch.setattr(passes, "WAVEFRONT_LANES", 2 * stride)    # batches of 2, 2, 1 passes
    split = _render(name, options)
    assert batches == [2, 2, 1]
    monkeypatch.setattr(passes, "WAVEFRONT_LANES", 1 << 20)       # one call
    whole = _render(name, options)
    assert batches[3:] == [5]
    assert np.array_equal(split, reference)
    assert np.array_equal(whole, reference)
    assert reference.std() > 0.0


def test_wavefront_aovs_and_counts_match_and_trace_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """-normals, -depth and the -v ray counts (pass 0's AOVs) are those of the pass-by-pass render, and the
    batch is traced by one kernel (an AOV gathered before it is evaluated would launch the integrator again)."""
    from a5mi.render.session import describe_file, render
    from a5mi.runtime.variant import activate

    activate()
    desc, _ = describe_file(os.path.join(DATA, "soft_shadows.txt"))
    options = RenderOptions(width=32, height=24, shadows=True, spp=4, seed=1, normals=True, depth=(1.0, 20.0),
                            count_rays=True)
    results = {}
    for lanes in (0, 1 << 20):
        monkeypatch.setattr(passes, "WAVEFRONT_LANES", lanes)
        render(desc, options)                                        # kernels cached
        results[lanes] = render(desc, options)
    before, after = results[0], results[1 << 20]
    for name in ("image", "normals", "depth"):
        assert np.array_equal(getattr(after, name), getattr(before, name)), name
    assert after.ray_counts == before.ray_counts and after.ray_counts["shadow"] > 0
    launches = {k: sum(r.kernels.values()) for k, r in results.items()}
    assert launches[1 << 20] <= 5 < launches[0], launches

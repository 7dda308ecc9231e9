"""Crop renders (a5mi/render/crop.py, docs/USAGE.md "Crop renders"): a region is bit for bit the same pixels of
the whole render, ``-jitter -filter`` included, and traces only its samples and the blur's margin.

The pure parts first (no Mitsuba): the traced samples' blocks, the region's blur against the whole image's
streamed filter on random buffers, the jitter offsets against the whole stream. Then renders of the project's
scenes, the whole image and regions of it compared with ``np.array_equal`` (0 ulp): regions touching each
border and each corner, an interior one, one pixel, the whole image; the ``-normals`` / ``-depth`` / class
images; refraction, ``-shadows``, area lights with ``-spp``, the path integrator with a thin lens, several
launches; the ray counts of a region against the whole image's.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from helpers import TESTS

from a5mi.render import crop
from a5mi.render.filters import FilterStream
from a5mi.render.options import RenderOptions
from a5mi.render.tiles import jitter_stream

SCENES = TESTS.parent / "scenes"


def regions(ow: int, oh: int) -> list[tuple[int, int, int, int]]:
    """Regions ``(X0, X1, Y0, Y1)`` of a ``ow x oh`` image: each border, each corner, an interior one, one
    pixel, the whole image."""
    return [
        (0, ow, 0, 3), (0, ow, oh - 2, oh), (0, 2, 0, oh), (ow - 3, ow, 0, oh),          # the four borders
        (0, 4, 0, 3), (ow - 5, ow, 0, 2), (0, 3, oh - 4, oh), (ow - 2, ow, oh - 3, oh),  # the four corners
        (ow // 3, 2 * ow // 3 + 1, oh // 4, oh // 2 + 2),                                # inside
        (ow // 2, ow // 2 + 1, oh // 2, oh // 2 + 1),                                    # one pixel
        (0, ow, 0, oh),                                                                  # everything
    ]


# ------------------------------------------------------------------------------------------------ pure parts
@pytest.mark.parametrize("rw,rh", [(90, 60), (31, 17), (64, 5), (3, 3)])
def test_aligned_samples_cover_the_rect_in_whole_aligned_blocks(rw: int, rh: int) -> None:
    rng = np.random.default_rng(rw * rh)
    for _ in range(30):
        i0, i1 = sorted(rng.choice(rw + 1, 2, replace=False))
        j0, j1 = sorted(rng.choice(rh + 1, 2, replace=False))
        rect = crop.Rect(int(i0), int(i1), int(j0), int(j1))
        s = crop.aligned_samples(rw, rh, rect)
        assert np.all(np.diff(s) > 0) and s[0] >= 0 and s[-1] < rw * rh
        wanted = (np.arange(j0, j1)[:, None] * rw + np.arange(i0, i1)).ravel()
        assert np.isin(wanted, s).all()
        blocks = s // crop.ALIGN   # whole blocks: every block present holds all its indices below rw * rh
        full = np.unique(blocks)[:, None] * crop.ALIGN + np.arange(crop.ALIGN)
        assert np.array_equal(s, full.ravel()[full.ravel() < rw * rh])
        # at most one partial block at each end of each row beyond the rect's own samples
        assert len(s) <= len(wanted) + 2 * (crop.ALIGN - 1) * (j1 - j0)


@pytest.mark.parametrize("w,h", [(30, 21), (31, 17), (10, 7)])
def test_filter_region_is_the_streamed_filter_of_the_whole_buffer(w: int, h: int) -> None:
    """SPEC B.5's blur + downsample of a region from its traced samples alone equals, bit for bit, the same
    pixels of the whole buffer's streamed filter (the one a whole render uses), at every border."""
    rw, rh = 3 * w, 3 * h
    buf = np.random.default_rng(w).random((rh, rw, 3), dtype=np.float32) * np.float32(3.0)
    stream = FilterStream(rw, rh, "binary")
    stream.push(buf)
    whole = stream.result()[::-1]              # row 0 = top, as the saved image
    for region in regions(w, h):
        options = RenderOptions(width=w, height=h, jitter=True, filter=True, crop=region)
        plan = crop.plan(options)
        t = plan.trace
        got = crop.filter_region(buf[t.j0:t.j1, t.i0:t.i1], plan, (rw, rh), "binary")[::-1]
        x0, x1, y0, y1 = region
        assert np.array_equal(got, whole[y0:y1, x0:x1]), region


@pytest.mark.parametrize("seed", [None, 7])
def test_region_offsets_are_the_whole_streams_values(seed: int | None) -> None:
    rw, rh = 60, 40
    options = RenderOptions(width=20, height=14, jitter=True, filter=True, crop=(5, 12, 3, 9), seed=seed)
    plan = crop.plan(options)
    jx, jy = jitter_stream(seed)(rw * rh)
    pieces = list(crop.region_offsets(plan.samples, seed, 48))
    assert len(pieces) == -(-len(plan.samples) // 48)
    idx = np.concatenate([p[0] for p in pieces])
    assert np.array_equal(idx, plan.samples)
    assert np.array_equal(np.concatenate([p[1][0] for p in pieces]), jx[idx])
    assert np.array_equal(np.concatenate([p[1][1] for p in pieces]), jy[idx])


def test_plan_rectangles_follow_the_module_docstring() -> None:
    """A 50 x 40 image under ``-jitter -filter``: region x 10..19, rows 5..14 from the top = rows 25..34 from
    the bottom; its samples 30..60 x 75..105; traced with 2 more on each side, clipped at the buffer."""
    p = crop.plan(RenderOptions(width=50, height=40, jitter=True, filter=True, crop=(10, 20, 5, 15)))
    assert p.out == (10, 20, 25, 35) and p.aov == (30, 60, 75, 105) and p.trace == (28, 62, 73, 107)
    p = crop.plan(RenderOptions(width=50, height=40, jitter=True, filter=True, crop=(0, 50, 0, 1)))
    assert p.trace == (0, 150, 115, 120)       # the top row: clipped at the top and both sides
    p = crop.plan(RenderOptions(width=50, height=40, jitter=True, crop=(3, 9, 0, 2)))
    assert p.out == p.aov == p.trace == (3, 9, 118, 120)   # -jitter alone: the saved image is the buffer


@pytest.mark.parametrize("region,why", [
    ((0, 51, 0, 5), "not a region of the 50x40 image"), ((5, 5, 0, 5), "0 <= X0 < X1 <= 50"),
    ((0, 5, 7, 6), "0 <= Y0 < Y1 <= 40"), ((0, 5, 0, 41), "not a region"),
])
def test_regions_outside_the_image_are_refused(region: tuple[int, int, int, int], why: str) -> None:
    options = RenderOptions(width=50, height=40, jitter=True, filter=True, crop=region)
    assert why in (crop.refusal(options) or "")
    with pytest.raises(ValueError, match="not a region"):
        crop.plan(options)


def test_modes_that_read_the_whole_image_are_refused() -> None:
    base = RenderOptions(width=30, height=30, crop=(0, 3, 0, 3))
    assert "keeps state" in (crop.refusal(dataclasses.replace(base, integrator="photon")) or "")
    assert "keeps state" in (crop.refusal(dataclasses.replace(base, integrator="irradiancecache")) or "")
    assert "mirrored" in (crop.refusal(dataclasses.replace(base, mistakes=("mirrored",))) or "")
    assert "no_blur" in (crop.refusal(dataclasses.replace(base, mistakes=("no_blur",))) or "")
    assert crop.refusal(dataclasses.replace(base, mistakes=("red_blue_swapped", "jitter_0_1"))) is None


def test_the_work_estimate_counts_the_regions_samples() -> None:
    """docs/USAGE.md "Work estimate": a crop's camera rays are its traced samples, the bound per camera ray is
    the whole image's."""
    from a5mi.render.estimate import estimate
    from a5mi.render.session import describe_file

    desc = describe_file(str(SCENES / "spec_glass.txt"))[0]
    whole = RenderOptions(width=300, height=300, jitter=True, filter=True, shadows=True)
    part = dataclasses.replace(whole, crop=(120, 180, 100, 150))
    e_whole, e_part = estimate(desc, whole, rate=1e6), estimate(desc, part, rate=1e6)
    assert e_whole.camera_rays == 810000
    assert e_part.camera_rays == crop.traced_samples(part) == len(crop.plan(part).samples)
    assert 184 * 154 <= e_part.camera_rays <= 184 * 154 + 2 * (crop.ALIGN - 1) * 154
    assert e_part.per_camera_ray == e_whole.per_camera_ray


# ------------------------------------------------------------------------------------------------- renders
@pytest.fixture(scope="module")
def session(variant: str):  # type: ignore[no-untyped-def]
    from a5mi.render.session import RenderSession

    return RenderSession(variant)


def _load(name: str):  # type: ignore[no-untyped-def]
    from a5mi.render.session import describe_file

    return describe_file(str(SCENES / name))[0]


def check_regions(session, desc, options: RenderOptions, picked: list[tuple[int, int, int, int]] | None = None
                  ) -> None:  # type: ignore[no-untyped-def]
    """Every region of :func:`regions` (or ``picked``) rendered alone is bit for bit the whole render's pixels,
    in the saved image and in each AOV image (the region's own samples, ``k = 3`` under ``-filter``)."""
    whole = session.render(desc, options)
    oh, ow = whole.image.shape[:2]
    k = 3 if options.filter else 1
    rh = whole.normals.shape[0] if whole.normals is not None else k * oh
    for region in picked or regions(ow, oh):
        x0, x1, y0, y1 = region
        part = session.render(desc, dataclasses.replace(options, crop=region))
        assert part.image.shape == (y1 - y0, x1 - x0, 3)
        assert np.array_equal(part.image, whole.image[y0:y1, x0:x1]), region
        top = rh - k * oh        # -filter alone: the buffer's top rows beyond 3 OH belong to no saved pixel
        for name in ("normals", "depth", "classes"):
            a, b = getattr(part, name), getattr(whole, name)
            if b is None:
                assert a is None
                continue
            assert np.array_equal(a, b[top + k * y0:top + k * y1, k * x0:k * x1]), (name, region)


def test_refraction_with_shadows_jitter_filter_and_aovs(session) -> None:  # type: ignore[no-untyped-def]
    options = RenderOptions(width=26, height=19, jitter=True, filter=True, shadows=True, normals=True,
                            depth=(2.0, 9.0), classes=True)
    check_regions(session, _load("spec_glass.txt"), options)


def test_jitter_alone_seeded_in_several_launches(session) -> None:  # type: ignore[no-untyped-def]
    """``-jitter`` alone (the saved image is the buffer, no margin), PCG64 offsets, tiles of 200 samples; the
    AOVs from the sample solution's quadrant rays (SPEC B.6 ``-normals_mode quadrant``, a second pass)."""
    options = RenderOptions(width=17, height=13, jitter=True, shadows=True, seed=11, tile_rays=200, normals=True,
                            depth=(3.0, 8.0), aov_mode="quadrant")
    check_regions(session, _load("spec_glass.txt"), options)


def test_filter_alone_height_not_a_multiple_of_3(session) -> None:  # type: ignore[no-untyped-def]
    options = RenderOptions(width=40, height=29, filter=True, shadows=True, normals=True, aov_mode="quadrant")
    check_regions(session, _load("spec_objects.txt"), options)


def test_area_lights_with_spp(session) -> None:  # type: ignore[no-untyped-def]
    """E.5 keys per sample: area-light samples stratified over ``-spp`` passes, the wavefront batch."""
    options = RenderOptions(width=24, height=18, jitter=True, filter=True, shadows=True, spp=3)
    check_regions(session, _load("soft_shadows.txt"), options, [(0, 5, 0, 4), (19, 24, 14, 18), (7, 15, 5, 11)])


def test_path_integrator_thin_lens(session) -> None:  # type: ignore[no-untyped-def]
    """``-integrator path`` with E.3's lens (the lens keys per sample) and one pass at a time (``spp 2``)."""
    options = RenderOptions(width=20, height=15, jitter=True, filter=True, integrator="path", spp=2, seed=3)
    check_regions(session, _load("dof.txt"), options, [(0, 6, 0, 4), (14, 20, 11, 15), (5, 13, 4, 10)])


def test_rays_scale_with_the_region(session) -> None:  # type: ignore[no-untyped-def]
    """The camera rays of a region are its traced samples (its own, the blur's margin, the block alignment:
    at most ``2 (ALIGN - 1)`` more per row); its secondary rays (the ``counts`` AOV) those of the samples it
    traces: each quadrant fewer than the whole image's, the four together at least the whole image's, and the
    whole image as a region exactly the whole render's."""
    desc = _load("spec_glass.txt")
    base = RenderOptions(width=32, height=32, jitter=True, filter=True, shadows=True, count_rays=True)
    whole = session.render(desc, base)
    rays_whole = sum(whole.ray_counts.values())
    secondary = 0
    for region in [(0, 16, 0, 16), (16, 32, 0, 16), (0, 16, 16, 32), (16, 32, 16, 32)]:
        options = dataclasses.replace(base, crop=region)
        part = session.render(desc, options)
        t = crop.plan(options).trace
        assert (t.width, t.height) == (50, 50)       # 48 x 48 own samples, 2 more on the inner sides
        assert part.camera_rays == crop.traced_samples(options) <= 50 * 50 + 2 * (crop.ALIGN - 1) * 50
        secondary += sum(part.ray_counts.values())
        assert sum(part.ray_counts.values()) < rays_whole
    assert secondary >= rays_whole
    everything = session.render(desc, dataclasses.replace(base, crop=(0, 32, 0, 32)))
    assert everything.camera_rays == whole.camera_rays and everything.ray_counts == whole.ray_counts


def test_scene10_with_the_handouts_flags(session, scenes_dir: Path) -> None:  # type: ignore[no-untyped-def]
    """The course's scene10 (refraction, the cube map, ``-shadows -bounces 4 -jitter -filter``), where
    :data:`a5mi.render.tiles.PACKET_ALIGN` once saw a sample depend on its SIMD packet."""
    from a5mi.render.session import describe_file

    desc = describe_file(str(scenes_dir / "scene10_sphere.txt"))[0]
    options = RenderOptions(width=30, height=30, jitter=True, filter=True, shadows=True, bounces=4)
    check_regions(session, desc, options, [(0, 30, 0, 1), (29, 30, 0, 30), (1, 8, 23, 30), (9, 22, 11, 19)])

"""The driver's sample order, jitter, tiling, orientation and AOVs (SPEC B.2, B.5, B.6); its modules
(:mod:`a5mi.render.driver`, :mod:`a5mi.render.render_pass`, :mod:`a5mi.render.tiles`) and the scene build beside it
(:mod:`a5mi.render.session`).

Stand-ins: ``_probe_rays`` encodes each sample's ``(x_pix, y_pix)`` into the ray origin, and ``_Probe``
(an integrator with the ``a5_whitted.sample`` signature) returns it as the colour, so the tests see exactly
which sample landed in which pixel. The last test renders through the real converter and plugins.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from a5mi.platform.arrays import aligned_float32
from a5mi.render import driver, tiles
from a5mi.render.driver import depth_gray, render_scene
from a5mi.render.filters import postprocess
from a5mi.render.glibc_rand import GlibcRand, jitter_offsets
from a5mi.render.options import TILE_RAYS, RenderOptions
from a5mi.render.tiles import tile_rows


@pytest.fixture
def unaligned(monkeypatch) -> None:
    """Tiles of exactly ``tile_rays // width`` rows: the stand-in integrator has no SIMD packets to keep aligned
    (:data:`a5mi.render.tiles.PACKET_ALIGN`), and these tests count tiles of a few rows."""
    monkeypatch.setattr(tiles, "PACKET_ALIGN", 1)


CAMERA = SimpleNamespace(center=(0.0, 0.0, 0.0), direction=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), angle=30.0)


def _probe_rays(center, direction, up, angle, x_pix, y_pix, width, height):
    import mitsuba as mi

    _probe_rays.size = (width, height)
    return mi.Ray3f(mi.Point3f(x_pix, y_pix, 0.0), mi.Vector3f(0.0, 0.0, 1.0))


class _Probe:
    """colour = (x_pix, y_pix, 0.25); AOVs n = (-x_pix, 0.5, 0), t = y_pix."""

    def aov_names(self):
        return ["nx", "ny", "nz", "t"]

    def sample(self, scene, sampler, ray, medium, active):
        import mitsuba as mi

        o = ray.o
        return mi.Color3f(o.x, o.y, 0.25), active, [-o.x, mi.Float(0.5) + 0 * o.x, 0 * o.x, o.y]


class _CountingProbe(_Probe):
    """Also the a5_whitted ``counts`` AOVs: 1 reflection, 2 refraction, 3 shadow rays per lane."""

    def aov_names(self):
        return [*super().aov_names(), "n_reflection", "n_refraction", "n_shadow"]

    def sample(self, scene, sampler, ray, medium, active):
        import mitsuba as mi

        rgb, valid, aovs = super().sample(scene, sampler, ray, medium, active)
        one = mi.Float(1.0) + 0 * ray.o.x
        return rgb, valid, aovs + [one, 2 * one, 3 * one]


def test_ray_counts_summed_over_tiles(variant, unaligned) -> None:
    res = render_scene(None, CAMERA, RenderOptions(width=5, height=4, tile_rays=7), integrator=_CountingProbe(),
                       camera_rays=_probe_rays)
    assert res.tiles == 4
    assert res.ray_counts == {"reflection": 20, "refraction": 40, "shadow": 60}
    assert _render(width=2, height=2).ray_counts == {}


class _ClassProbe(_Probe):
    """Also the a5_whitted ``class`` AOV, by name: class = y_pix mod 3 (0 miss, 1 opaque, 2 glass)."""

    def aov_names(self):
        return ["class", *super().aov_names()]

    def sample(self, scene, sampler, ray, medium, active):
        import drjit as dr

        rgb, valid, aovs = super().sample(scene, sampler, ray, medium, active)
        return rgb, valid, [ray.o.y - 3 * dr.floor(ray.o.y / 3), *aovs]


def test_class_image_read_by_name_with_row_0_at_the_top(variant, unaligned) -> None:
    res = render_scene(None, CAMERA, RenderOptions(width=3, height=4, tile_rays=5, classes=True),
                       integrator=_ClassProbe(), camera_rays=_probe_rays)
    assert res.classes is not None and res.classes.dtype == np.uint8 and res.classes.shape == (4, 3)
    np.testing.assert_array_equal(res.classes[::-1, 0], [0, 1, 2, 0])  # bottom-up rows j = 0..3
    np.testing.assert_array_equal(res.image[::-1, 0, 1], [0, 1, 2, 3])  # the colour is the probe's, as before
    assert render_scene(None, CAMERA, RenderOptions(width=3, height=4), integrator=_ClassProbe(),
                        camera_rays=_probe_rays).classes is None
    with pytest.raises(RuntimeError, match="no AOV class"):
        render_scene(None, CAMERA, RenderOptions(width=3, height=4, classes=True), integrator=_Probe(),
                     camera_rays=_probe_rays)


def test_class_aov_only_on_request() -> None:
    assert "class" not in RenderOptions(normals=True, depth=(0.0, 1.0), count_rays=True).aov_groups
    assert RenderOptions(classes=True).aov_groups == ("class",)
    assert RenderOptions(classes=True, normals=True).integrator_params()["aovs"] == "normal,class"


def test_progress_callback(variant, unaligned) -> None:
    seen = []
    render_scene(None, CAMERA, RenderOptions(width=4, height=3, tile_rays=4), integrator=_Probe(),
                 camera_rays=_probe_rays, progress=lambda done, total: seen.append((done, total)))
    assert seen == [(4, 12), (8, 12), (12, 12)]


def test_progress_called_once_per_aligned_tile(variant) -> None:
    """SPEC B.5 tiles: with the packet alignment on, a 64-wide render in tiles of 2 rows reports 12 steps, each a
    multiple of 64 samples, ending at the total."""
    seen = []
    res = render_scene(None, CAMERA, RenderOptions(width=64, height=24, tile_rays=128), integrator=_Probe(),
                       camera_rays=_probe_rays, progress=lambda done, total: seen.append((done, total)))
    assert res.tiles == len(seen) == 12 >= 10
    assert [d for d, _ in seen] == list(range(128, 64 * 24 + 1, 128)) and {t for _, t in seen} == {64 * 24}


def _render(**kw):
    return render_scene(None, CAMERA, RenderOptions(**kw), integrator=_Probe(), camera_rays=_probe_rays)


def test_b2_pixel_centres_and_orientation(variant) -> None:
    """Without jitter, pixel (i, j) is sampled at (i, j); row 0 of the result is j = H-1 (top)."""
    res = _render(width=5, height=3)
    assert res.image.shape == (3, 5, 3) and res.camera_rays == 15
    assert _probe_rays.size == (5, 3)
    for row in range(3):
        j = 2 - row
        np.testing.assert_array_equal(res.image[row, :, 0], np.arange(5, dtype=np.float32))
        np.testing.assert_array_equal(res.image[row, :, 1], np.full(5, j, np.float32))


def test_b5_jitter_glibc_order(variant) -> None:
    """-jitter: 3W x 3H samples, rows bottom-up, per sample r1 -> jy then r2 -> jx (float32)."""
    res = _render(width=4, height=2, jitter=True)
    assert res.image.shape == (6, 12, 3) and _probe_rays.size == (12, 6)
    r = GlibcRand().next(2 * 72).reshape(72, 2)
    jy, jx = jitter_offsets(r[:, 0]).reshape(6, 12), jitter_offsets(r[:, 1]).reshape(6, 12)
    i = np.arange(12, dtype=np.float32)[None, :]
    j = np.arange(6, dtype=np.float32)[:, None]
    bottom_up = res.image[::-1]
    np.testing.assert_array_equal(bottom_up[..., 0], i + jx)
    np.testing.assert_array_equal(bottom_up[..., 1], j + jy)
    # the very first rand() value (1804289383) is the y offset of the bottom-left sample
    assert bottom_up[0, 0, 1] == np.float32(1804289383) * np.float32(2**-31) - np.float32(0.5)


@pytest.mark.parametrize("seed", [None, 7])
def test_b5_tiles_do_not_change_the_image(variant, unaligned, seed) -> None:
    whole = _render(width=5, height=4, jitter=True, seed=seed)
    tiled = _render(width=5, height=4, jitter=True, seed=seed, tile_rays=16)  # 16 // 15 = 1 row per tile
    assert tiled.tiles == 12 and whole.tiles == 1
    np.testing.assert_array_equal(tiled.image, whole.image)


@pytest.mark.parametrize("rows_per_tile", [1, 2, 3, 4, 5, 7, 100])
def test_b5_streamed_filter_matches_whole_buffer(variant, unaligned, rows_per_tile) -> None:
    """-jitter -filter on a non-square image, tiles of any row count (also not multiples of 3): the streamed
    blur + downsample equals postprocess() of the whole unfiltered 3W x 3H buffer bit for bit."""
    whole = _render(width=7, height=5, jitter=True)  # 21 x 15 render buffer, row 0 = top
    expected = postprocess(whole.image[::-1], filter=True)[::-1]
    tiled = _render(width=7, height=5, jitter=True, filter=True, tile_rays=21 * rows_per_tile)
    assert tiled.tiles == -(-15 // rows_per_tile)
    np.testing.assert_array_equal(tiled.image, expected)


def test_b5_streamed_filter_memory_does_not_grow_with_height(variant) -> None:
    """Peak Python-side memory of -jitter -filter (numpy buffers, traced by tracemalloc) with a fixed tile
    size: doubling the image height adds only the output rows (W x H x 12 B), not the 3W x 3H buffer."""
    import tracemalloc

    def peak(height: int) -> int:
        tracemalloc.start()
        try:
            _render(width=40, height=height, jitter=True, filter=True, tile_rays=120 * 6)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    peak(50)  # warm-up: imports, kernel compile
    small, large = peak(100), peak(200)
    full_buffer_growth = 120 * 300 * 3 * 4  # the unstreamed render buffer would grow by this much
    assert large - small < full_buffer_growth / 4, (small, large)


def test_b5_seed_selects_numpy_generator(variant) -> None:
    a = _render(width=3, height=3, jitter=True, seed=1).image
    b = _render(width=3, height=3, jitter=True, seed=1).image
    c = _render(width=3, height=3, jitter=True).image
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    off = a[::-1, :, 0] - np.arange(9, dtype=np.float32)[None, :]
    assert off.min() >= -0.5 and off.max() < 0.5


@pytest.mark.parametrize(
    "jitter,filt,shape", [(True, True, (4, 7)), (True, False, (12, 21)), (False, True, (1, 2)), (False, False, (4, 7))]
)
def test_b5_flag_combination_sizes(variant, jitter, filt, shape) -> None:
    """Non-square -size 7 4: every flag combination of SPEC B.5's table."""
    res = _render(width=7, height=4, jitter=jitter, filter=filt)
    assert res.image.shape[:2] == shape
    assert res.render_size == ((21, 12) if jitter else (7, 4))


def test_b5_filter_applies_blur_then_downsample(variant) -> None:
    """The blue channel is the constant 0.25: blur gain 1.0001^2, box keeps it."""
    res = _render(width=4, height=4, jitter=True, filter=True)
    np.testing.assert_allclose(res.image[..., 2], 0.25 * 1.0001**2, rtol=2e-6)
    handout = _render(width=4, height=4, jitter=True, filter=True, kernel="handout")
    np.testing.assert_allclose(handout.image[..., 2], 0.25 * 1.0011**2, rtol=2e-6)


def test_b6_normals_and_depth_images(variant) -> None:
    res = _render(width=4, height=5, normals=True, depth=(1.0, 3.0))
    assert res.normals is not None and res.depth is not None
    assert res.normals.shape == res.depth.shape == (5, 4, 3)
    bottom_up_n = res.normals[::-1]
    np.testing.assert_array_equal(bottom_up_n[..., 0], np.tile(np.arange(4, dtype=np.float32), (5, 1)))  # |-x|
    np.testing.assert_array_equal(bottom_up_n[..., 1], 0.5)
    gray = res.depth[::-1, 0, 0]  # t = j
    np.testing.assert_allclose(gray, [1.0, 1.0, 0.5, 0.0, 0.0])


def test_b6_depth_formula_edges() -> None:
    t = np.array([0.0, 1.0, 1.5, 2.0, 5.0, np.inf, np.nan], np.float32)
    np.testing.assert_allclose(depth_gray(t, 1.0, 2.0), [1, 1, 0.5, 0, 0, 0, 0])
    np.testing.assert_allclose(depth_gray(t, 2.0, 2.0)[[0, 3, 4]], [1, 1, 0])  # dmin >= dmax: 0 past dmin


def test_tile_rows_bounded() -> None:
    assert tile_rows(10, 7, 25, align=1) == [(0, 2), (2, 4), (4, 6), (6, 7)]
    assert tile_rows(100, 2, 5, align=1) == [(0, 1), (1, 2)]  # at least one row per tile
    assert all((b - a) * 1920 * 3 <= TILE_RAYS for a, b in tile_rows(1920 * 3, 1080 * 3, TILE_RAYS))


@pytest.mark.parametrize("rw", [1, 15, 90, 96, 100, 128, 5760])
@pytest.mark.parametrize("tile_rays", [1, 450, 4096, 1 << 20])
def test_tiles_start_on_packet_boundaries(rw, tile_rays) -> None:
    """Every tile starts on a multiple of PACKET_ALIGN samples, the tiles cover the buffer, and a tile exceeds
    the requested size only by the alignment (align / gcd(rw, align) rows)."""
    rh = 200
    rows = tile_rows(rw, rh, tile_rays)
    assert rows[0][0] == 0 and rows[-1][1] == rh and all(a[1] == b[0] for a, b in zip(rows, rows[1:], strict=False))
    assert all(j0 * rw % tiles.PACKET_ALIGN == 0 for j0, _ in rows)
    m = tiles.PACKET_ALIGN // np.gcd(rw, tiles.PACKET_ALIGN)
    assert all((j1 - j0) * rw <= max(tile_rays, m * rw) for j0, j1 in rows)


def test_progress_steps_only_when_someone_watches(variant, monkeypatch) -> None:
    """With a progress callback the render is split into PROGRESS_STEPS tiles of at least MIN_TILE_RAYS
    samples; without one it stays one launch (each tile re-traces the integrator); the image is the same."""
    monkeypatch.setattr(tiles, "MIN_TILE_RAYS", 64)
    seen = []
    watched = render_scene(None, CAMERA, RenderOptions(width=64, height=16), integrator=_Probe(),
                           camera_rays=_probe_rays, progress=lambda done, total: seen.append(done))
    alone = _render(width=64, height=16)
    assert watched.tiles == len(seen) == tiles.PROGRESS_STEPS and alone.tiles == 1
    np.testing.assert_array_equal(watched.image, alone.image)


def test_large_renders_are_split_for_progress() -> None:
    """A render of many samples gets PROGRESS_STEPS tiles of at least MIN_TILE_RAYS samples (the bar's rate)."""
    assert len(tile_rows(3000, 3000, TILE_RAYS)) >= 9  # 9M samples: bounded by TILE_RAYS
    assert len(tile_rows(1024, 1024, TILE_RAYS)) == tiles.PROGRESS_STEPS  # 1M samples: 4 x 256k
    assert len(tile_rows(300, 300, TILE_RAYS)) == 1  # 90k samples: one launch, one trace


class _ThreadProbe(_Probe):
    """Records Dr.Jit's worker-thread count while the render traces."""

    def __init__(self) -> None:
        self.seen: list[int] = []

    def sample(self, scene, sampler, ray, medium, active):
        import drjit as dr

        self.seen.append(dr.thread_count())
        return super().sample(scene, sampler, ray, medium, active)


def test_thread_count_set_for_the_render_and_restored(variant) -> None:
    """``RenderOptions.threads`` holds while the render traces; afterwards (also after a failed render) the
    process-wide count is what it was; ``threads=None`` leaves it alone."""
    import drjit as dr

    before = dr.thread_count()
    outside = before + 1
    dr.set_thread_count(outside)
    try:
        probe = _ThreadProbe()
        render_scene(None, CAMERA, RenderOptions(width=3, height=2, threads=1), integrator=probe,
                     camera_rays=_probe_rays)
        assert probe.seen and set(probe.seen) == {1}
        assert dr.thread_count() == outside
        with pytest.raises(RuntimeError, match="no AOV class"):  # fails inside the tile loop
            render_scene(None, CAMERA, RenderOptions(width=3, height=2, threads=1, classes=True), integrator=probe,
                         camera_rays=_probe_rays)
        assert dr.thread_count() == outside
        probe.seen.clear()
        render_scene(None, CAMERA, RenderOptions(width=3, height=2), integrator=probe, camera_rays=_probe_rays)
        assert set(probe.seen) == {outside} and dr.thread_count() == outside
    finally:
        dr.set_thread_count(before)


def test_the_driver_builds_no_scene() -> None:
    """Data flows one way (description -> dict -> Mitsuba objects -> driver -> image): the render modules
    import no converter but the model's types, and not the module that builds scenes."""
    import ast
    from pathlib import Path

    root = Path(driver.__file__).resolve().parent
    for name in ("driver.py", "render_pass.py", "tiles.py", "passes.py"):
        imported = set()
        for node in ast.walk(ast.parse((root / name).read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module:
                imported.add(node.module)
            elif isinstance(node, ast.Import):
                imported |= {a.name for a in node.names}
        bad = {m for m in imported if (m.startswith("a5mi.converters") and m != "a5mi.converters.model")
               or m == "a5mi.render.session"}
        assert not bad, (name, bad)


def test_aligned_float32_copies_onto_a_64_byte_boundary() -> None:
    base = np.arange(40, dtype=np.float32)
    for start in range(5):
        a = aligned_float32(base[start : start + 30])
        assert a.ctypes.data % 64 == 0 and a.dtype == np.float32
        np.testing.assert_array_equal(a, base[start : start + 30])


@pytest.mark.parametrize("bad", [dict(width=0), dict(bounces=-1), dict(fresnel="x"), dict(kernel="gauss")])
def test_options_validated(bad) -> None:
    with pytest.raises(ValueError):
        RenderOptions(**bad)


# ---------------------------------------------------------------- with the real a5_whitted integrator


def test_b2_real_integrator_centre_pixel(variant) -> None:
    """Real camera_rays and a5_whitted. Unit sphere seen from z = 5, light along -z: the centre pixel
    (odd W) is irradiance ⊙ kd, t = 4,
    N = (0, 0, 1); a corner pixel misses (background black, depth 0)."""
    import mitsuba as mi

    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "a5_whitted", "max_depth": 0, "aovs": "normal,depth"},
        "ball": {"type": "sphere", "bsdf": {"type": "a5_material",
                                            "diffuse_color": {"type": "rgb", "value": [0.5, 0.25, 1.0]}}},
        "sun": {"type": "directional", "direction": [0, 0, -1], "irradiance": {"type": "rgb", "value": [1, 1, 0.5]}},
    })
    cam = SimpleNamespace(center=(0.0, 0.0, 5.0), direction=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), angle=30.0)
    res = render_scene(scene, cam, RenderOptions(width=5, height=5, normals=True, depth=(0.0, 8.0)))
    np.testing.assert_allclose(res.image[2, 2], [0.5, 0.25, 0.5], rtol=1e-6)
    np.testing.assert_allclose(res.normals[2, 2], [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(res.depth[2, 2], 0.5, rtol=1e-6)  # 1 - 4/8
    np.testing.assert_array_equal(res.image[0, 0], 0.0)
    np.testing.assert_array_equal(res.depth[0, 0], 0.0)


def test_b6_quadrant_mode_uses_the_binarys_aov_rays(variant) -> None:
    """aov_mode="quadrant": AOV pixel X sees camera x = (X+0.5-W/2)/max(W,H) + 0.5, i.e. x_pix = (x+1)(W-1)/2;
    the main image keeps its own rays. For W = H = 4: X = 0 -> x = 0.125 -> x_pix = 1.6875; X = 3 -> 2.8125."""
    res = _render(width=4, height=4, normals=True, depth=(0.0, 10.0), aov_mode="quadrant")
    bottom_up_n = res.normals[::-1, :, 0]  # |n.x| = x_pix in the probe
    np.testing.assert_allclose(bottom_up_n[0], [1.6875, 2.0625, 2.4375, 2.8125])
    np.testing.assert_allclose(res.depth[::-1, 0, 0], 1 - np.array([1.6875, 2.0625, 2.4375, 2.8125]) / 10, rtol=1e-6)
    np.testing.assert_array_equal(res.image[::-1][0, :, 0], [0, 1, 2, 3])  # main pass: pixel centres
    assert res.camera_rays == 32


def _ball_scene(color, light):
    import mitsuba as mi

    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "a5_whitted", "max_depth": 2, "shadows": True},
        "ball": {"type": "sphere", "bsdf": {"type": "a5_material",
                                            "diffuse_color": {"type": "rgb", "value": color},
                                            "specular_color": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}},
        "sun": {"type": "directional", "direction": light, "irradiance": {"type": "rgb", "value": [1, 1, 1]}},
    })  # fmt: skip


def _coords_at_alignment(coords, misaligned: bool):
    """Wrap :func:`a5mi.render.tiles.pixel_coords`: arrays on a 64-byte boundary, or with ``misaligned`` every other
    tile's arrays 4 bytes past one (what numpy's allocator did at random)."""
    calls = []

    def placed(rw, j0, j1, jit):
        calls.append(j0)
        out = []
        for a in coords(rw, j0, j1, jit):
            buf = aligned_float32(np.zeros(a.size + 1, np.float32))
            view = buf[1:] if misaligned and len(calls) % 2 else buf[:-1]
            view[:] = a
            out.append(view)
        return tuple(out)

    return placed


def test_repeated_renders_compile_nothing(variant, unaligned, monkeypatch) -> None:
    """Pixel coordinates used to be mapped from numpy at whatever alignment the allocator gave, which
    changed the kernel hash and recompiled the render kernel at random. Now (with the coordinate arrays'
    alignment made to differ from the first render's) a second render of the same scene, every tile of a many-tile
    render, and a scene of the same structure with other values all reuse the in-memory kernels."""
    import gc


    cam = SimpleNamespace(center=(0.0, 0.0, 5.0), direction=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), angle=30.0)
    opts = RenderOptions(width=10, height=12, jitter=True, filter=True, tile_rays=30 * 2)  # 18 tiles
    scene = _ball_scene([0.5, 0.25, 1.0], [0, 0, -1])
    coords = tiles.pixel_coords
    monkeypatch.setattr(tiles, "pixel_coords", _coords_at_alignment(coords, misaligned=False))
    first = render_scene(scene, cam, opts)
    assert sum(first.kernels.values()) >= first.tiles == 18
    monkeypatch.setattr(tiles, "pixel_coords", _coords_at_alignment(coords, misaligned=True))
    for _ in range(3):
        again = render_scene(scene, cam, opts)
        assert again.kernels["compiled"] == 0 and again.kernels["disk"] == 0, again.kernels
        np.testing.assert_array_equal(again.image, first.image)
    del scene
    gc.collect()
    other = render_scene(_ball_scene([0.1, 0.9, 0.3], [0.3, -0.2, -1]), cam, opts)
    assert other.kernels["compiled"] == 0 and other.kernels["disk"] == 0, other.kernels
    assert not np.array_equal(other.image, first.image)


def test_real_scene_bit_identical_for_any_tile_size(variant, scenes_dir) -> None:
    """SPEC B.5 tiles: scene10 (Embree-traced cube mesh, glass sphere, cube map) at 30x30 -jitter, a 90-sample-wide
    buffer. With tiles of 1 or 5 rows starting anywhere (PACKET_ALIGN = 1) pixels changed by up to 2.8e-5;
    aligned tiles give the one-launch image bit for bit."""
    from a5mi.render.session import describe_file, render

    desc, _ = describe_file(str(scenes_dir / "scene10_sphere.txt"))
    kw = dict(width=30, height=30, jitter=True, bounces=4, shadows=True)
    whole = render(desc, RenderOptions(**kw))
    assert whole.tiles == 1
    for rows in (1, 5):
        tiled = render(desc, RenderOptions(**kw, tile_rays=90 * rows))
        assert tiled.tiles == 3  # 32-row tiles: 32 * 90 is the first multiple of 64 samples
        np.testing.assert_array_equal(tiled.image, whole.image)

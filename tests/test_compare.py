"""a5mi.compare: the metrics every fidelity figure is stated in, checked against hand computations."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from a5mi.compare import CompareError, compare_arrays, write_diff
from a5mi.platform.errors import ImageReadError
from a5mi.platform.imageio import read_levels


def _img(h: int = 4, w: int = 5, value: float = 100.0) -> np.ndarray:
    return np.full((h, w, 3), value)


def test_identical_images_have_infinite_psnr_and_no_bbox() -> None:
    m = compare_arrays(_img(), _img())
    assert math.isinf(m.psnr)
    assert m.mean_error == 0 and m.max_error == 0 and m.share_over == 0 and m.bbox is None


def test_single_pixel_error_by_hand() -> None:
    a, b = _img(), _img()
    b[1, 3, 0] += 10.0  # one channel of one pixel off by 10 levels
    m = compare_arrays(a, b)
    n = 4 * 5 * 3
    assert m.psnr == pytest.approx(10 * math.log10(255**2 / (100.0 / n)))
    assert m.mean_error == pytest.approx(10.0 / n)
    assert m.share_over == pytest.approx(1 / 20)
    assert m.max_error == 10.0
    assert m.bbox == (3, 1, 3, 1)


def test_threshold_is_strict_greater_than() -> None:
    a, b = _img(), _img()
    b[0, 0, :] += 2.0  # exactly 2/255: not counted
    b[2, 4, 1] += 3.0  # over
    m = compare_arrays(a, b)
    assert m.share_over == pytest.approx(1 / 20)
    assert m.bbox == (4, 2, 4, 2)


def test_size_mismatch_is_a_user_error() -> None:
    with pytest.raises(CompareError, match="sizes differ: 5x4 vs 4x4"):
        compare_arrays(_img(), _img(w=4))


def test_files_round_trip_and_diff_montage(tmp_path) -> None:
    import OpenImageIO as oiio

    rng = np.random.default_rng(1)
    a = rng.integers(0, 256, size=(6, 7, 3)).astype(np.uint8)
    b = a.copy()
    b[5, 0] = np.minimum(b[5, 0].astype(int) + 40, 255).astype(np.uint8)
    for name, img in (("a.png", a), ("b.png", b)):
        out = oiio.ImageOutput.create(str(tmp_path / name))
        out.open(str(tmp_path / name), oiio.ImageSpec(7, 6, 3, oiio.UINT8))
        out.write_image(img)
        out.close()
    assert np.array_equal(read_levels(tmp_path / "a.png"), a.astype(np.float64))
    m = compare_arrays(read_levels(tmp_path / "a.png"), read_levels(tmp_path / "b.png"))
    assert m.bbox == (0, 5, 0, 5)
    write_diff(read_levels(tmp_path / "a.png"), read_levels(tmp_path / "b.png"), m, tmp_path / "d.png", ("a", "b"))
    d = read_levels(tmp_path / "d.png")
    assert d.shape[1] == 240  # 3 * 7 + 8 panels, widened to MIN_WIDTH for the caption
    assert np.array_equal(d[:6, :7], a)  # left panel is A, unchanged
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".a5mi-")] == []


def test_unreadable_image_is_a_user_error(tmp_path) -> None:

    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png")
    with pytest.raises(ImageReadError, match="cannot read image"):
        read_levels(bad)


def test_cli_compare_prints_metrics_json_and_writes_diff(tmp_path, capsys) -> None:
    import json

    from a5mi.cli import run_a5mi
    from a5mi.platform.imageio import write_image

    a = np.zeros((4, 5, 3), dtype=np.float32)
    b = a.copy()
    b[0, 0, 0] = 10 / 255 + 1e-4  # quantises to 10 levels
    write_image(tmp_path / "a.png", a)
    write_image(tmp_path / "b.png", b)
    assert run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--json",
                     "--diff", str(tmp_path / "d.png")]) == 1  # 1 of 20 pixels off: 5% > the 1.5% of 'close'
    out = json.loads(capsys.readouterr().out)
    assert out["max_error"] == 10.0 and out["share_over"] == pytest.approx(1 / 20) and out["bbox"] == [0, 0, 0, 0]
    assert out["verdict"] == "wrong" and out["beyond_noise"] == pytest.approx(1 / 20)
    assert (tmp_path / "d.png").is_file()


@pytest.mark.parametrize(
    ("args", "message"),
    [(["compare", "x.png"], "a5mi compare: error: missing A B (2 expected, found 1) (see a5mi compare -h)"),
     (["compare", "a.png", "b.png", "--bogus"], "a5mi compare: error: unknown flag '--bogus' (see a5mi compare -h)"),
     (["compare", "a.png", "b.png", "--diff"], "a5mi compare: error: --diff expects a value, found end of arguments"),
     (["compare", "a.png", "b.png", "--match", "0.5", "--close", "0.1"],
      "a5mi compare: error: --match and --close must satisfy 0 <= match <= close <= 1 (found 0.5, 0.1)"),
     (["fidelity", "extra"], "a5mi fidelity: error: unexpected argument 'extra' (see a5mi fidelity -h)")],
)
def test_cli_subcommand_misuse_is_one_line_exit_2(args, message, tmp_path, capsys, monkeypatch) -> None:
    from a5mi.cli import run_a5mi

    monkeypatch.chdir(tmp_path)
    assert run_a5mi(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [message]  # each sub-command's errors carry its own name


def _write_pair(tmp_path, b_levels):
    from a5mi.platform.imageio import write_image

    a = np.full(b_levels.shape, 100.0)
    write_image(tmp_path / "a.png", (a + 0.5) / 255)
    write_image(tmp_path / "b.png", (b_levels + 0.5) / 255)
    return a


def test_cli_compare_exit_status_is_the_verdict(tmp_path, capsys) -> None:
    """0 for match, 1 for close / wrong / wrong size: scripts and CI can gate on it."""
    from a5mi.cli import run_a5mi

    a = np.full((20, 20, 3), 100.0)
    b = a.copy()
    b[0, :4] += 3  # 1% of pixels beyond 1/255: match (<= 1%)
    _write_pair(tmp_path, b)
    assert run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png")]) == 0
    assert "verdict: match (1.00% of pixels beyond 1/255)" in capsys.readouterr().out
    b[0, 4] += 3  # 1.25%: close (<= 1.5%) -> differ
    _write_pair(tmp_path, b)
    assert run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png")]) == 1
    assert "verdict: close" in capsys.readouterr().out
    from a5mi.platform.imageio import write_image

    write_image(tmp_path / "c.png", np.zeros((5, 20, 3)))
    assert run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "c.png"), "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["verdict"] == "wrong size"


def test_cli_compare_noise_band_and_flip(tmp_path, capsys) -> None:
    """With --noise, errors within 4 sigma + 2 levels are noise; --flip reports FLIP and writes its map."""
    from a5mi.cli import run_a5mi

    a = np.full((10, 10, 3), 100.0)
    b = a.copy()
    b[:5] += 10  # half the pixels 10 levels off
    _write_pair(tmp_path, b)
    sigma = np.zeros((10, 10, 3), dtype=np.float32)
    sigma[:5] = 2.25  # band 4*2.25 + 1 = 10 levels: the error is noise there
    np.save(tmp_path / "s.npy", sigma)
    args = ["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--json"]
    assert run_a5mi(args) == 1
    assert json.loads(capsys.readouterr().out)["beyond_noise"] == pytest.approx(0.5)
    assert run_a5mi([*args, "--noise", str(tmp_path / "s.npy"), "--flip-map", str(tmp_path / "f.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["verdict"] == "match" and out["beyond_noise"] == 0.0 and 0 < out["flip"] < 1
    assert read_levels(tmp_path / "f.png").shape == (10, 10, 3)
    sigma[:5] = 2.2  # band 9.8 < 10: beyond
    np.save(tmp_path / "s.npy", sigma)
    assert run_a5mi([*args, "--noise", str(tmp_path / "s.npy")]) == 1
    assert json.loads(capsys.readouterr().out)["beyond_noise"] == pytest.approx(0.5)


def test_flip_is_zero_for_identical_and_grows_with_error() -> None:
    from a5mi.grade.verdict import flip_map

    a = np.random.default_rng(3).uniform(0, 255, (16, 16, 3)).round()
    heat, same = flip_map(a, a)
    assert same == 0.0 and heat.shape == (16, 16, 3)
    _, small = flip_map(a, np.clip(a + 5, 0, 255))
    _, large = flip_map(a, np.clip(a + 60, 0, 255))
    assert 0 < small < large <= 1


# ------------------------------------------------------------------------------------ the --diff picture
LONG = ("reference_scene12_vase_at_300.png | my render with a long name.png | |A-B|, largest channel, colour bar "
        "0..16/255\nPSNR 44.6 dB, mean 0.750/255, 25.00% of pixels > 2/255, max 8/255")


@pytest.fixture(params=["oiio", "bitmap"])
def font(request, monkeypatch):
    """Each text backend: OpenImageIO's render_text with the wheel's font, and the embedded bitmap font."""
    from a5mi import compare

    if request.param == "bitmap":
        monkeypatch.setattr(compare, "font_path", lambda: None)
    elif compare.font_path() is None:
        pytest.skip("OpenImageIO finds no font here")
    return request.param


@pytest.mark.parametrize("w", [20, 150, 300])
def test_caption_is_wrapped_inside_the_picture(w, font) -> None:
    """The caption drawn in the montage equals the same lines drawn on a canvas 8x wider, cropped: no glyph
    column is cut off at the right edge, and every line measures within the margins."""
    from a5mi import compare

    a = np.zeros((w, w, 3))
    img = compare.montage(a, a, LONG)
    lay = compare.layout(w, w, LONG)
    assert img.shape == (lay.height, lay.width, 3) and len(lay.caption_lines) >= 2
    assert "".join(lay.caption_lines).replace(" ", "") == LONG.replace(" ", "").replace("\n", "")
    assert all(compare.text_width(line) <= lay.width - 2 * compare.MARGIN for line in lay.caption_lines)
    top = lay.caption_top
    canvas = np.full((lay.height - top + 8, 8 * lay.width, 3), 32, np.uint8)
    wide = compare.draw_text(canvas, [(compare.MARGIN, i * compare.LINE_HEIGHT, line)
                                      for i, line in enumerate(lay.caption_lines)])
    assert (wide[:, lay.width - compare.MARGIN:] == 32).all()  # nothing drawn past the margin
    np.testing.assert_array_equal(img[top:], wide[: lay.height - top, : lay.width])
    assert (img[top:] > 32).sum() > 50 * len(lay.caption_lines)  # there is ink


def test_colour_bar_runs_black_to_red_monotonically_with_labels(font) -> None:
    from a5mi import compare

    a = np.zeros((150, 150, 3))
    img = compare.montage(a, a, "x", scale=6.0)
    lay = compare.layout(150, 150, "x")
    (r0, r1), (c0, c1) = lay.bar_rows, lay.bar_cols
    bar = img[(r0 + r1) // 2, c0:c1].astype(np.float64)
    np.testing.assert_array_equal(bar[0], [0, 0, 0])
    np.testing.assert_array_equal(bar[-1], [255, 0, 0])
    table = compare.colormap(np.linspace(0.0, 1.0, 2041))
    position = np.argmin(((bar[:, None, :] - table[None, :, :]) ** 2).sum(axis=2), axis=1)
    assert (np.diff(position) >= 0).all() and position[-1] == 2040  # colours in scale order, 0 .. full scale
    assert [t for _, t in compare.bar_labels(6.0, lay.bar_cols)] == ["0", "3", "6/255"]
    assert (img[lay.labels_top : lay.caption_top, c0 : c0 + 12] > 32).any()  # "0" is drawn under the left end


def _heat_pixel(path, h, w, y, x):
    d = read_levels(path)
    return d[y, 2 * (w + 4) + x]


@pytest.mark.parametrize(("scale", "colour"), [(None, [0, 255, 0]), ("8", [255, 0, 0]), ("32", [0, 0, 255]),
                                               ("auto", [255, 0, 0])])
def test_cli_scale_sets_the_full_scale(tmp_path, scale, colour, capsys) -> None:
    """A pixel 8 levels off: green at the default 16 (half scale), red with --scale 8 (error = scale: the top
    colour), blue at 32 (a quarter); auto = the 99.9th percentile of the error, here 8: red."""
    import os

    from a5mi.cli import run_a5mi

    b = np.full((20, 20, 3), 100.0)
    b[3:, :, 1] += 8  # most pixels 8 off, so the percentile is 8
    _write_pair(tmp_path, b)
    args = ["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--diff", str(tmp_path / "d.png")]
    old = os.umask(0o027)
    try:
        assert run_a5mi(args + ([] if scale is None else ["--scale", scale])) == 1  # exit status: the verdict
    finally:
        os.umask(old)
    assert f"d.png: A | B | |A-B| heatmap, full scale {8 if scale in ('8', 'auto') else int(scale or 16)}/255" in \
        capsys.readouterr().out
    assert (tmp_path / "d.png").stat().st_mode & 0o777 == 0o640
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # written atomically
    np.testing.assert_array_equal(_heat_pixel(tmp_path / "d.png", 20, 20, 10, 10), colour)
    np.testing.assert_array_equal(_heat_pixel(tmp_path / "d.png", 20, 20, 0, 0), [0, 0, 0])  # no error: black


def test_auto_scale_ignores_rare_outliers() -> None:
    from a5mi.compare import auto_scale

    a = np.zeros((100, 100, 3))
    b = a.copy()
    b[:50] = 3.0
    b[0, 0] = 200.0  # one pixel in 10 000: above the 99.9th percentile
    assert auto_scale(a, b) == 3.0
    assert auto_scale(a, a) == 1.0


@pytest.mark.parametrize("value", ["0", "-3", "abc", "nan"])
def test_cli_bad_scale_is_a_usage_error(tmp_path, value, capsys) -> None:
    from a5mi.cli import run_a5mi

    _write_pair(tmp_path, np.full((4, 4, 3), 100.0))
    assert run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--diff",
                     str(tmp_path / "d.png"), "--scale", value]) == 2
    assert "--scale" in capsys.readouterr().err and not (tmp_path / "d.png").exists()


# ------------------------------------------------------------------------------- non-finite pixels
def _exr_pair(tmp_path, size: int = 20):
    """Two float images (EXR) equal but for one NaN and one +inf pixel in B: 2 of size^2 pixels."""
    from a5mi.platform.imageio import write_image

    a = np.full((size, size, 3), 0.5, np.float32)
    b = a.copy()
    b[0, 0, 0], b[3, 4, 1] = np.nan, np.inf
    write_image(tmp_path / "a.exr", a)
    write_image(tmp_path / "b.exr", b)
    return tmp_path / "a.exr", tmp_path / "b.exr"


def test_non_finite_channels_are_infinite_errors() -> None:
    """A NaN or infinite channel in either image is an error of +inf (module docstring): over every threshold,
    max and mean inf, PSNR -inf, counted in ``nonfinite``; the JSON stays strict (null, never NaN)."""
    a, b = _img(3, 3), _img(3, 3)
    b[0, 0, 0], b[1, 1, 2], a[2, 2, 1] = math.nan, math.inf, -math.inf
    m = compare_arrays(a, b, 2.0)
    assert m.nonfinite == 3 and m.share_over == pytest.approx(3 / 9)
    assert math.isinf(m.max_error) and math.isinf(m.mean_error) and m.psnr == -math.inf
    assert m.bbox == (0, 0, 2, 2)
    doc = json.loads(m.to_json())
    assert doc["psnr"] is None and doc["max_error"] is None and doc["nonfinite"] == 3
    both_nan = compare_arrays(np.full((2, 2, 3), math.nan), np.full((2, 2, 3), math.nan))
    assert both_nan.nonfinite == 4 and both_nan.share_over == 1.0  # NaN is no match for NaN either


def test_grade_verdict_never_scores_non_finite_pixels() -> None:
    """docs/GRADING.md: one non-finite pixel in 10,000 (0.01%, under the 1% 'match' share) is still 'wrong',
    with or without a noise band; a NaN in sigma does not hide a pixel either."""
    from a5mi.grade.verdict import beyond_noise, judge, measure

    ref = _img(100, 100)
    for bad in (math.nan, math.inf):
        student = ref.copy()
        student[50, 50, 0] = bad
        for sigma in (None, np.full(ref.shape, 0.5)):
            metrics, _ = measure(student, ref, sigma, flip=False)
            assert metrics.beyond_noise == pytest.approx(1e-4)
            assert judge(metrics) == "wrong"
            assert metrics.as_dict()["max_error"] is None
    sigma = np.zeros(ref.shape)
    sigma[1, 1, 1] = math.nan
    assert beyond_noise(ref, ref, sigma)[1, 1] and beyond_noise(ref, ref, sigma).sum() == 1
    assert judge(measure(ref.copy(), ref, flip=False)[0]) == "match"


def test_cli_compare_nan_and_inf_pixels_differ(tmp_path, capsys) -> None:
    """``a5mi compare`` of EXRs with a NaN and an inf pixel (0.5% of the pixels): verdict wrong, exit 1, strict
    JSON; the --diff montage paints them red."""
    from a5mi.cli import run_a5mi

    a, b = _exr_pair(tmp_path)
    assert run_a5mi(["compare", str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "verdict: wrong" in out and "2 pixels not finite" in out and "PSNR -inf dB" in out and "nan/" not in out
    assert run_a5mi(["compare", str(a), str(b), "--json", "--diff", str(tmp_path / "d.png"), "--scale", "auto"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["verdict"] == "wrong" and doc["nonfinite"] == 2 and doc["psnr"] is None
    heat = read_levels(tmp_path / "d.png")[:20, 2 * (20 + 4):]
    assert heat[0, 0].tolist() == [255, 0, 0] and heat[3, 4].tolist() == [255, 0, 0]
    assert heat[10, 10].tolist() == [0, 0, 0]


@pytest.mark.parametrize("value", ["-1", "-0.5", "nan"])
def test_cli_negative_threshold_is_a_usage_error(tmp_path, value, capsys) -> None:
    """--threshold counts pixels whose error exceeds it: errors are >= 0, so it must be a number >= 0."""
    from a5mi.cli import run_a5mi

    a, _ = _exr_pair(tmp_path)
    assert run_a5mi(["compare", str(a), str(a), "--threshold", value]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("a5mi compare: error: --threshold expects")

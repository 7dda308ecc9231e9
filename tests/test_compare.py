"""a5mi.compare: the metrics every fidelity figure is stated in, checked against hand computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from a5mi.compare import CompareError, compare_arrays, compare_files, read_levels, write_diff
from a5mi.errors import ImageReadError


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
    m = compare_files(tmp_path / "a.png", tmp_path / "b.png")
    assert m.bbox == (0, 5, 0, 5)
    write_diff(read_levels(tmp_path / "a.png"), read_levels(tmp_path / "b.png"), m, tmp_path / "d.png", ("a", "b"))
    d = read_levels(tmp_path / "d.png")
    assert d.shape[1] == 3 * 7 + 8
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
    from a5mi.imageio import write_image

    a = np.zeros((4, 5, 3), dtype=np.float32)
    b = a.copy()
    b[0, 0, 0] = 10 / 255 + 1e-4  # quantises to 10 levels
    write_image(tmp_path / "a.png", a)
    write_image(tmp_path / "b.png", b)
    assert run_a5mi(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--json",
                     "--diff", str(tmp_path / "d.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["max_error"] == 10.0 and out["share_over"] == pytest.approx(1 / 20) and out["bbox"] == [0, 0, 0, 0]
    assert (tmp_path / "d.png").is_file()


@pytest.mark.parametrize(
    ("args", "message"),
    [(["compare", "x.png"], "a5mi compare: error: missing A B (2 expected, found 1) (see a5mi compare -h)"),
     (["compare", "a.png", "b.png", "--bogus"], "a5mi compare: error: unknown flag '--bogus' (see a5mi compare -h)"),
     (["compare", "a.png", "b.png", "--diff"], "a5mi compare: error: --diff expects a value, found end of arguments"),
     (["fidelity", "extra"], "a5mi fidelity: error: unexpected argument 'extra' (see a5mi fidelity -h)")],
)
def test_cli_subcommand_misuse_is_one_line_exit_2(args, message, tmp_path, capsys, monkeypatch) -> None:
    from a5mi.cli import run_a5mi

    monkeypatch.chdir(tmp_path)
    assert run_a5mi(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [message]  # each sub-command's errors carry its own name

"""Blur and 3x3 downsample (SPEC B.5) against direct loops of the formulas."""

from __future__ import annotations

import numpy as np
import pytest

from a5mi.render.filters import FilterStream, blur, downsample3, kernel_taps, output_size, postprocess

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def _blur_loop(img: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Direct transcription: along y into a new buffer, then along x; clamp per axis; float32 sums."""
    h, w = img.shape[:2]
    tmp = np.zeros_like(img)
    for j in range(h):
        for i in range(w):
            s = np.zeros(img.shape[2:], np.float32)
            for k in range(5):
                s = s + taps[k] * img[min(max(j + k - 2, 0), h - 1), i]
            tmp[j, i] = s
    out = np.zeros_like(img)
    for j in range(h):
        for i in range(w):
            s = np.zeros(img.shape[2:], np.float32)
            for k in range(5):
                s = s + taps[k] * tmp[j, min(max(i + k - 2, 0), w - 1)]
            out[j, i] = s
    return out


def _down_loop(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[0] // 3, img.shape[1] // 3
    out = np.zeros((h, w) + img.shape[2:], np.float32)
    for y in range(h):
        for x in range(w):
            s = np.zeros(img.shape[2:], np.float32)
            for dx in range(3):
                for dy in range(3):
                    s = s + img[3 * y + dy, 3 * x + dx]
            out[y, x] = s / np.float32(9.0)
    return out


@pytest.mark.parametrize("strip_rows", [64, 2, 1])
@pytest.mark.parametrize("kernel", ["binary", "handout"])
@pytest.mark.parametrize("shape", [(9, 9, 3), (7, 12, 3), (12, 7, 1), (3, 3, 3), (1, 4, 3), (5, 6)])
def test_b5_blur_matches_loop(shape, kernel, strip_rows) -> None:
    """Bit-exact against the loop, whatever the strip size (strip borders use the clamped rows too)."""
    img = np.random.default_rng(1).random(shape).astype(np.float32)
    got = blur(img, kernel, strip_rows=strip_rows)
    assert got.dtype == np.float32 and got.shape == img.shape
    np.testing.assert_array_equal(got, _blur_loop(img, kernel_taps(kernel)))


def test_b5_blur_edges_clamp_per_axis() -> None:
    """A spike in the corner of a non-square image: the clamped taps pile onto the border pixel."""
    img = np.zeros((4, 8, 1), np.float32)
    img[0, 0, 0] = 1.0
    k = kernel_taps("binary")
    edge = k[0] + k[1] + k[2]  # taps -2, -1, 0 all read the corner
    got = blur(img)
    assert got[0, 0, 0] == pytest.approx(edge * edge, rel=1e-6)
    assert got[3, 7, 0] == 0.0


@pytest.mark.parametrize("kernel,gain", [("binary", 1.0001**2), ("handout", 1.0011**2)])
def test_b5_blur_constant_gain(kernel, gain) -> None:
    img = np.full((10, 6, 3), 0.5, np.float32)
    np.testing.assert_allclose(blur(img, kernel), 0.5 * gain, rtol=2e-6)


@pytest.mark.parametrize("shape", [(9, 9, 3), (10, 14, 3), (8, 5, 3)])
def test_b5_downsample_matches_loop(shape) -> None:
    img = np.random.default_rng(2).random(shape).astype(np.float32)
    got = downsample3(img)
    assert got.shape == (shape[0] // 3, shape[1] // 3, 3)
    np.testing.assert_array_equal(got, _down_loop(img))


def test_b5_downsample_constant_and_lone_sample() -> None:
    img = np.full((6, 6, 3), 0.25, np.float32)
    np.testing.assert_allclose(downsample3(img), 0.25, rtol=1e-7)
    spike = np.zeros((3, 3, 1), np.float32)
    spike[1, 2] = 1.0
    assert downsample3(spike)[0, 0, 0] == np.float32(1.0) / np.float32(9.0)


def test_b5_unknown_kernel() -> None:
    with pytest.raises(ValueError, match="unknown blur kernel"):
        kernel_taps("gauss")


@pytest.mark.parametrize(
    "jitter,filt,expected",
    [(True, True, (30, 20)), (True, False, (90, 60)), (False, True, (10, 6)), (False, False, (30, 20))],
)
def test_b5_flag_combinations(jitter, filt, expected) -> None:
    """Output size of every flag combination for -size 30 20 (W x H), from the render buffer."""
    w, h = 30, 20
    assert output_size(w, h, jitter=jitter, filter=filt) == expected
    rw, rh = (3 * w, 3 * h) if jitter else (w, h)
    out = postprocess(np.zeros((rh, rw, 3), np.float32), filter=filt)
    assert (out.shape[1], out.shape[0]) == expected


# ---------------------------------------------------------------- streamed filter (bounded memory)


@pytest.mark.parametrize("band", [1, 2, 3, 4, 5, 7, 10, 33])
@pytest.mark.parametrize("shape", [(33, 21, 3), (13, 20, 3), (6, 9, 3), (152, 12, 3)])  # 152: several 48-row strips
@pytest.mark.parametrize("kernel", ["binary", "handout"])
def test_b5_stream_bit_identical_to_whole_image(shape, band, kernel) -> None:
    """Bands of any height (also not multiples of 3, and heights not multiples of 3: -filter without -jitter)
    give exactly postprocess() of the whole buffer, and the stream never holds more than band + 6 rows."""
    img = np.random.default_rng(3).random(shape).astype(np.float32)
    stream = FilterStream(shape[1], shape[0], kernel)
    for j0 in range(0, shape[0], band):
        stream.push(img[j0 : j0 + band])
    np.testing.assert_array_equal(stream.result(), postprocess(img, filter=True, kernel=kernel))
    assert stream.peak_window_rows <= min(shape[0], band + 6)


def test_b5_stream_rows_final_as_soon_as_their_taps_arrived() -> None:
    """Output row y needs render rows up to 3y+4: after 5 rows one output row is done, after 7 rows still
    one, after 8 rows two; the window then starts 2 rows below the next block (its lowest blur tap)."""
    stream = FilterStream(6, 30)
    rows = np.ones((30, 6, 3), np.float32)
    stream.push(rows[:4])
    assert stream.rows_out == 0
    stream.push(rows[4:5])
    assert stream.rows_out == 1
    stream.push(rows[5:7])
    assert stream.rows_out == 1
    stream.push(rows[7:8])
    assert stream.rows_out == 2 and stream.rows_in == 8
    np.testing.assert_allclose(stream.image[:2], 1.0001**2, rtol=2e-6)  # constant image: blur gain only


def test_b5_stream_rejects_bad_input() -> None:
    stream = FilterStream(6, 6)
    with pytest.raises(ValueError, match="shape"):
        stream.push(np.zeros((2, 5, 3), np.float32))
    stream.push(np.zeros((4, 6, 3), np.float32))
    with pytest.raises(ValueError, match="only 4 of 6"):
        stream.result()
    with pytest.raises(ValueError, match="more than 6"):
        stream.push(np.zeros((3, 6, 3), np.float32))
    with pytest.raises(ValueError, match="cannot downsample"):
        FilterStream(2, 9)

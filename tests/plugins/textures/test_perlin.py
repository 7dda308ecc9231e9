"""Improved noise and the octave sum (SPEC B.4) against a pure-Python port of Perlin's 2002 Java reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

# Ken Perlin's ImprovedNoise.java (2002), ported line by line; independent of plugins/textures/perlin.py.
REF_PERMUTATION = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69, 142, 8, 99,
    37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32,
    57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175, 74, 165, 71, 134, 139, 48, 27,
    166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244,
    102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169, 200, 196, 135, 130,
    116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147,
    118, 126, 255, 82, 85, 212, 207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213,
    119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108,
    110, 79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12,
    191, 179, 162, 241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84,
    204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
]  # fmt: skip
_P = REF_PERMUTATION * 2


def _fade(t: float) -> float:
    return t * t * t * (t * (t * 6 - 15) + 10)


def _lerp(t: float, a: float, b: float) -> float:
    return a + t * (b - a)


def _grad(hash_: int, x: float, y: float, z: float) -> float:
    h = hash_ & 15
    u = x if h < 8 else y
    v = y if h < 4 else (x if h in (12, 14) else z)
    return (u if (h & 1) == 0 else -u) + (v if (h & 2) == 0 else -v)


def ref_noise(x: float, y: float, z: float) -> float:
    X, Y, Z = math.floor(x) & 255, math.floor(y) & 255, math.floor(z) & 255
    x -= math.floor(x)
    y -= math.floor(y)
    z -= math.floor(z)
    u, v, w = _fade(x), _fade(y), _fade(z)
    A = _P[X] + Y
    AA = _P[A] + Z
    AB = _P[A + 1] + Z
    B = _P[X + 1] + Y
    BA = _P[B] + Z
    BB = _P[B + 1] + Z
    return _lerp(
        w,
        _lerp(v, _lerp(u, _grad(_P[AA], x, y, z), _grad(_P[BA], x - 1, y, z)),
              _lerp(u, _grad(_P[AB], x, y - 1, z), _grad(_P[BB], x - 1, y - 1, z))),
        _lerp(v, _lerp(u, _grad(_P[AA + 1], x, y, z - 1), _grad(_P[BA + 1], x - 1, y, z - 1)),
              _lerp(u, _grad(_P[AB + 1], x, y - 1, z - 1), _grad(_P[BB + 1], x - 1, y - 1, z - 1))),
    )  # fmt: skip


def ref_octave_noise(p: np.ndarray, octaves: int) -> float:
    """The binary's perlinOctaveNoise: float32 p*(float)2^i, double noise, double sum."""
    n = 0.0
    for i in range(octaves):
        scale = np.float32(2.0**i)
        q = (p.astype(np.float32) * scale).astype(np.float64)
        n += ref_noise(float(q[0]), float(q[1]), float(q[2])) / float(scale)
    return n


def _points(rng: np.random.Generator, n: int, lo: float, hi: float) -> np.ndarray:
    return rng.uniform(lo, hi, size=(n, 3)).astype(np.float32)


def test_b4_permutation_is_the_reference(variant: str) -> None:
    from a5mi.plugins.textures.perlin import PERMUTATION

    assert len(PERMUTATION) == 256
    assert sorted(PERMUTATION) == list(range(256))
    assert list(PERMUTATION) == REF_PERMUTATION


def test_b4_noise_matches_reference(variant: str) -> None:
    import mitsuba as mi

    from a5mi.plugins.textures.perlin import noise

    pts = np.random.default_rng(1).uniform(-300.0, 300.0, size=(10_000, 3))
    got = noise(*(mi.Float64(pts[:, k]) for k in range(3))).numpy()
    want = np.array([ref_noise(*row) for row in pts])
    assert np.max(np.abs(got - want)) < 1e-6
    assert np.std(want) > 0.1  # the sample actually exercises the noise


@pytest.mark.parametrize("octaves", [1, 3, 8])
def test_b4_octave_noise_matches_reference(variant: str, octaves: int) -> None:
    import mitsuba as mi

    from a5mi.plugins.textures.perlin import octave_noise

    pts = _points(np.random.default_rng(octaves), 2_000, -20.0, 20.0)
    got = octave_noise(mi.Point3f(pts[:, 0], pts[:, 1], pts[:, 2]), mi.UInt32(octaves)).numpy()
    want = np.array([ref_octave_noise(row, octaves) for row in pts])
    assert np.max(np.abs(got - want)) < 1e-6


@pytest.mark.parametrize("octaves", [0, 1, 2, 5, 12])
def test_b4_octave_noise_zero_on_lattice(variant: str, octaves: int) -> None:
    import mitsuba as mi

    from a5mi.plugins.textures.perlin import octave_noise

    pts = np.random.default_rng(7).integers(-1000, 1000, size=(500, 3)).astype(np.float32)
    got = octave_noise(mi.Point3f(pts[:, 0], pts[:, 1], pts[:, 2]), mi.UInt32(octaves)).numpy()
    assert np.all(got == 0.0)


def test_b4_octave_noise_per_lane_counts(variant: str) -> None:
    """The symbolic loop honours a per-lane octave count (one kernel for any count)."""
    import mitsuba as mi

    from a5mi.plugins.textures.perlin import octave_noise

    pt = np.array([0.3, 1.7, -2.2], dtype=np.float32)
    counts = [0, 1, 2, 4]
    p = mi.Point3f(*(np.full(len(counts), pt[k], dtype=np.float32) for k in range(3)))
    got = octave_noise(p, mi.UInt32(counts)).numpy()
    want = [ref_octave_noise(pt, c) for c in counts]
    assert np.allclose(got, want, atol=1e-9, rtol=0)
    assert got[0] == 0.0 and got[1] != got[2]

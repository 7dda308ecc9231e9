"""Ken Perlin's improved noise and the octave sum of the sample solution (SPEC B.4), in Dr.Jit.

Pure functions, split as pbrt splits ``util/noise.cpp`` from ``MarbleTexture``: this module knows nothing
about textures or colours; :mod:`a5mi.plugins.textures.marble` maps a hit point through them.

Precision follows the binary (SPEC B.4): ``noise`` runs in double (``Float64``), the octave point is the
float32 product ``p * (float)2^i`` (exact, since 2^i is a power of two), and the sum N is kept in double.

Reference: K. Perlin, "Improving Noise", SIGGRAPH 2002, and its published Java reference implementation
(``ImprovedNoise``): the 256-entry permutation below, repeated to 512 entries; fade 6t⁵ − 15t⁴ + 10t³;
the 12-gradient ``grad``.
"""

from __future__ import annotations

from functools import cache

import drjit as dr
import mitsuba as mi

from a5mi.plugins.syntax import syntax

#: The 256-entry permutation of Perlin's 2002 reference (``ImprovedNoise.permutation``).
PERMUTATION: tuple[int, ...] = (
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69, 142,
    8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117,
    35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175, 74, 165, 71,
    134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230, 220, 105, 92, 41,
    55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89,
    18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64, 52, 217, 226,
    250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206, 59, 227, 47, 16, 58, 17, 182,
    189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43,
    172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97,
    228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162, 241, 81, 51, 145, 235, 249, 14, 239,
    107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254,
    138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180,
)  # fmt: skip

@cache
def _pair_table(variant: str) -> mi.UInt64:
    """The 512-entry table ``p[i] = PERMUTATION[i & 255]`` as pairs, ``pairs[i] = p[i] | p[i + 1] << 32``
    (``p[512]`` taken as ``p[0]``), an opaque device array of ``variant``: the hash chain reads ``p[i]`` and
    ``p[i + 1]`` together, so one 64-bit gather gives both (its indices stay <= 510). Seven gathers per noise
    instead of fourteen: the vase's kernel -12..-25% (measured: BENCHMARKS.md), bit for bit the same.

    Cached per variant (``functools.cache``), on purpose: the table is a constant of :data:`PERMUTATION`, not of a
    scene or a render, so the cache carries nothing from one call to the next; building it per texture call
    would upload it again each time, and one opaque array shared by every noise call keeps one compiled kernel
    for every scene."""
    p = list(PERMUTATION) * 2 + [PERMUTATION[0]]
    table = mi.UInt64([p[i] | (p[i + 1] << 32) for i in range(512)])
    dr.make_opaque(table)
    return table


def fade(t: mi.Float64) -> mi.Float64:
    """Perlin's quintic fade curve: f(t) = 6t⁵ − 15t⁴ + 10t³, evaluated as t³(t(6t − 15) + 10)."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def lerp(t: mi.Float64, a: mi.Float64, b: mi.Float64) -> mi.Float64:
    """a + t·(b − a), in the reference's operation order."""
    return a + t * (b - a)


def grad(hash_: mi.UInt32, x: mi.Float64, y: mi.Float64, z: mi.Float64) -> mi.Float64:
    """The reference's 12-gradient dot product (16 cases, 4 repeated).

    h = hash & 15; u = x if h < 8 else y; v = y if h < 4 else (x if h in (12, 14) else z);
    result = (u if h & 1 == 0 else −u) + (v if h & 2 == 0 else −v).
    """
    h = hash_ & 15
    u = dr.select(h < 8, x, y)
    v = dr.select(h < 4, y, dr.select((h == 12) | (h == 14), x, z))
    return dr.select((h & 1) == 0, u, -u) + dr.select((h & 2) == 0, v, -v)


def noise(x: mi.Float64, y: mi.Float64, z: mi.Float64) -> mi.Float64:
    """Improved noise at (x, y, z) in double precision, exactly as the 2002 Java reference computes it.

    X = ⌊x⌋ & 255 (likewise Y, Z); x ← x − ⌊x⌋; u, v, w = fade(x, y, z); hashes
    A = p[X]+Y, AA = p[A]+Z, AB = p[A+1]+Z, B = p[X+1]+Y, BA = p[B]+Z, BB = p[B+1]+Z; trilinear ``lerp`` of
    the eight corner ``grad`` values. Zero at every integer lattice point. Range about [−1, 1].
    """
    fx, fy, fz = dr.floor(x), dr.floor(y), dr.floor(z)
    X = mi.UInt32(mi.Int32(fx) & 255)  # two's-complement AND, as (int)floor(x) & 255
    Y = mi.UInt32(mi.Int32(fy) & 255)
    Z = mi.UInt32(mi.Int32(fz) & 255)
    x, y, z = x - fx, y - fy, z - fz
    u, v, w = fade(x), fade(y), fade(z)

    pairs = _pair_table(mi.variant())

    def P2(i: mi.UInt32) -> tuple[mi.UInt32, mi.UInt32]:
        """``(p[i], p[i + 1])`` in one 64-bit gather."""
        both = dr.gather(mi.UInt64, pairs, i)
        return mi.UInt32(both & 0xFFFFFFFF), mi.UInt32(both >> 32)

    pX, pX1 = P2(X)
    A, B = pX + Y, pX1 + Y
    pA, pA1 = P2(A)
    pB, pB1 = P2(B)
    AA, AB, BA, BB = pA + Z, pA1 + Z, pB + Z, pB1 + Z
    gAA, gAA1 = P2(AA)
    gBA, gBA1 = P2(BA)
    gAB, gAB1 = P2(AB)
    gBB, gBB1 = P2(BB)
    x1, y1, z1 = x - 1.0, y - 1.0, z - 1.0
    return lerp(
        w,
        lerp(
            v,
            lerp(u, grad(gAA, x, y, z), grad(gBA, x1, y, z)),
            lerp(u, grad(gAB, x, y1, z), grad(gBB, x1, y1, z)),
        ),
        lerp(
            v,
            lerp(u, grad(gAA1, x, y, z1), grad(gBA1, x1, y, z1)),
            lerp(u, grad(gAB1, x, y1, z1), grad(gBB1, x1, y1, z1)),
        ),
    )


@syntax
def octave_noise(p: mi.Point3f, octaves: mi.UInt32) -> mi.Float64:
    """perlinOctaveNoise (SPEC B.4): N = Σ_{i=0}^{octaves−1} noise(2^i · p) / 2^i, in double.

    Parameter ``p`` (mi.Point3f): the float32 world-space point, unscaled.
    Parameter ``octaves`` (mi.UInt32): octave count (pass it opaque so one kernel serves every scene).
    Output: N as ``mi.Float64``; 0 when ``octaves`` is 0 and at integer lattice points for any count.

    As in the binary, scale = (float)2^i and the point is the float32 product p·scale, widened to double.
    The loop is symbolic, so the octave count does not enter the kernel's code.
    """
    n = dr.zeros(mi.Float64, dr.width(p))  # N, accumulated in double
    scale = dr.full(mi.Float, 1.0, dr.width(p))  # (float)pow(2, i)
    i = dr.zeros(mi.UInt32, dr.width(p))  # octave index
    while dr.hint(i < octaves, label="a5_octave_noise"):
        q = p * scale  # float32 product
        n += noise(mi.Float64(q.x), mi.Float64(q.y), mi.Float64(q.z)) / mi.Float64(scale)
        scale *= 2.0
        i += 1
    return n


@syntax
def turbulence(p: mi.Point3f, octaves: mi.UInt32) -> mi.Float64:
    """Perlin's turbulence (docs/EXTENSIONS.md E.6): T = Σ_{i=0}^{octaves−1} |noise(2^i · p)| / 2^i, in double.

    The same octave points as :func:`octave_noise` (float32 product ``p · (float)2^i``, widened to double),
    with the absolute value of each octave: T ≥ 0, 0 at integer lattice points and for ``octaves`` = 0.
    A separate loop, so the marble's :func:`octave_noise` kernel is untouched.
    """
    n = dr.zeros(mi.Float64, dr.width(p))
    scale = dr.full(mi.Float, 1.0, dr.width(p))
    i = dr.zeros(mi.UInt32, dr.width(p))
    while dr.hint(i < octaves, label="a5_turbulence"):
        q = p * scale
        n += dr.abs(noise(mi.Float64(q.x), mi.Float64(q.y), mi.Float64(q.z))) / mi.Float64(scale)
        scale *= 2.0
        i += 1
    return n

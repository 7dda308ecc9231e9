"""Rainbows from a droplet cloud (docs/EXTENSIONS.md E.21): the scene, its render and the bow angles measured on it.

    python scenes/rainbow.py [--size 1000] [--spp 6] [--droplets 1000]    # docs/rainbow.png, prints the angles
    python scenes/rainbow.py --write scenes/rainbow.txt --droplets 2000     # the scene text for `a5`

The picture is the render box-averaged 5 x 5 (``--size`` a multiple of 5); the float render is kept beside it
(``.npy``, not committed). The scene: the camera at the origin looks at the antisolar point (−z); the sun is a
SphereLight 10⁴ units behind it (+z) of angular radius ``SUN_RADIUS_DEG`` (a Whitted tracer sees a light through
a droplet only if the refracted ray can hit it: a DirectionalLight, a delta, cannot be hit); the droplets are
spheres of water
(``refractionIndex dispersion`` :data:`WATER`, E.10) spread uniformly (seeded) in the shell ``R_MIN < |p| < R_MAX``
within ``CONE_DEG`` of the view axis. The camera's thin lens (E.3) has ``aperture`` = :data:`APERTURE` and focus
at infinity, so a pixel is one direction and each ``-spp`` pass sends its ray through another point of the lens:
another droplet, another impact parameter. A pixel at ``x = 2i/(W − 1) − 1``, ``y = 2j/(H − 1) − 1`` (SPEC B.2)
looks at ``θ = atan(√(x² + y²) tan(angle/2))`` from the antisolar point (:func:`angles`).

Measurement (:func:`measure`): the share of pixels that see the sun through a droplet, in rings of ``BIN_DEG``
of θ (:func:`profile`); the primary bow is the steepest fall of that profile in 30°-47° (its sharp outer edge, where
Alexander's dark band begins), the secondary the steepest rise in 47°-60° (its inner edge); both edges are blurred
by the sun's disc (±SUN_RADIUS_DEG).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np

#: Cauchy's A and B (µm²) of water, fitted to its index at the F and C lines (486.1 nm: 1.33712, 656.3 nm: 1.33110)
WATER = (1.3238, 0.00315)
SUN_RADIUS_DEG = 3.0
SUN_DISTANCE = 1.0e4
SUN_COLOR = 3000.0
FOV_DEG = 120.0
APERTURE = 4.0
R_MIN, R_MAX, CONE_DEG = 4.0, 12.0, 72.0
DROPLET_RADIUS = 0.25
TEST_DROPLETS = 1000
BIN_DEG = 0.5


def scene_text(droplets: int, seed: int = 1) -> str:
    """The scene (module docstring) with ``droplets`` spheres placed by a seeded generator."""
    rng = np.random.default_rng(seed)
    cos_max = math.cos(math.radians(CONE_DEG))
    z = rng.uniform(cos_max, 1.0, droplets)                      # uniform directions in the cone about −z
    phi = rng.uniform(0.0, 2 * math.pi, droplets)
    r = np.cbrt(rng.uniform(R_MIN ** 3, R_MAX ** 3, droplets))   # uniform in the shell's volume
    s = np.sqrt(1.0 - z * z)
    pts = np.stack([r * s * np.cos(phi), r * s * np.sin(phi), -r * z], axis=1)
    spheres = "\n".join(f"    Sphere {{ center {x:.4f} {y:.4f} {w:.4f} radius {DROPLET_RADIUS} }}" for x, y, w in pts)
    sun_r = SUN_DISTANCE * math.tan(math.radians(SUN_RADIUS_DEG))
    a, b = WATER
    sun = f"{SUN_COLOR:g} {SUN_COLOR:g} {SUN_COLOR:g}"
    return f"""PerspectiveCamera {{
    center 0 0 0
    direction 0 0 -1
    up 0 1 0
    angle {FOV_DEG}
    aperture {APERTURE}
    focusDistance 1e6
}}
Lights {{
    numLights 1
    SphereLight {{ center 0 0 {SUN_DISTANCE:g} radius {sun_r:.3f} color {sun} samples 1 }}
}}
Background {{
    color 0 0 0
    ambientLight 0 0 0
}}
Materials {{
    numMaterials 1
    Material {{ diffuseColor 0 0 0 specularColor 1 1 1 refractionIndex dispersion {a} {b} }}
}}
Group {{
    numObjects {droplets}
    MaterialIndex 0
{spheres}
}}
"""


def angles(width: int, height: int) -> np.ndarray:
    """θ (degrees from the antisolar point) of every pixel's direction (SPEC B.2; row 0 = top)."""
    x = 2.0 * np.arange(width) / (width - 1) - 1.0
    y = 2.0 * np.arange(height) / (height - 1) - 1.0
    rr = np.hypot(x[None, :], y[:, None])
    return np.degrees(np.arctan(rr * math.tan(math.radians(FOV_DEG / 2))))


def render(size: int, spp: int, droplets: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The float image (H, W, 3) of the cloud at ``size`` x ``size``, ``spp`` passes, and :func:`angles`."""
    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.plugins import register_all
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import render as render_scene
    from a5mi.runtime.variant import activate

    activate()
    register_all()

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rainbow.txt"
        path.write_text(scene_text(droplets))
        desc = describe(parse_text(path.read_text(), str(path)))
    opts = RenderOptions(width=size, height=size, spp=spp, seed=seed, bounces=4)
    return np.asarray(render_scene(desc, opts).image, dtype=np.float64), angles(size, size)


def profile(img: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bin centres (degrees) and, per ring of :data:`BIN_DEG`, the share of its finite pixels that see the sun
    through a droplet (some channel non-zero; the background is black): the hit rate, whose bins are
    binomial counts (the colours carry E.10's signed w(λ) weights, a noisier statistic). Empty rings: NaN."""
    finite = np.isfinite(img).all(axis=2)
    lit = (np.abs(np.nan_to_num(img)).max(axis=2) > 0.0) & finite
    edges = np.arange(0.0, theta.max() + BIN_DEG, BIN_DEG)
    idx = np.digitize(theta[finite], edges) - 1
    hits = np.bincount(idx, lit[finite].astype(np.float64), len(edges))
    count = np.bincount(idx, None, len(edges))
    with np.errstate(invalid="ignore"):
        return edges + BIN_DEG / 2, hits / count


def edges(centres: np.ndarray, prof: np.ndarray) -> tuple[float, float]:
    """(primary, secondary) of a ring profile: the steepest fall of its 3-bin running mean in 30°-47° and its
    steepest rise in 47°-60°, at the midpoint between two bins."""
    prof = np.convolve(np.nan_to_num(prof), np.ones(3) / 3, mode="same")
    slope = np.diff(prof)
    mids = (centres[:-1] + centres[1:]) / 2
    first = (mids > 30.0) & (mids < 47.0)
    second = (mids > 47.0) & (mids < 60.0)
    return float(mids[first][np.argmin(slope[first])]), float(mids[second][np.argmax(slope[second])])


def measure(img: np.ndarray, theta: np.ndarray) -> tuple[float, float]:
    """(primary, secondary) bow angles in degrees (module docstring): :func:`edges` of the :func:`profile`."""
    return edges(*profile(img, theta))


def sectors(img: np.ndarray, theta: np.ndarray, n: int = 4) -> list[tuple[float, float]]:
    """:func:`measure` on ``n`` azimuthal sectors of the image apart (their spread: the measurement's noise)."""
    h, w = theta.shape
    az = np.arctan2(np.arange(h)[:, None] - (h - 1) / 2, np.arange(w)[None, :] - (w - 1) / 2)
    k = ((az + np.pi) / (2 * np.pi) * n).astype(int) % n
    return [measure(np.where((k == s)[..., None], img, np.nan), theta) for s in range(n)]


def model_profile(samples: int = 4_000_000, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The hit-rate profile geometric optics predicts for :func:`profile` (up to scale, without the light
    scattered by several droplets): rays uniform over a droplet's disc (``b² ~ U(0, 1)``), ``λ ~ U(400, 700)``
    nm, each leaving after one and after two internal reflections at ``θ1 = 4r − 2i``, ``θ2 = 180° + 2i − 6r``
    from the antisolar point; a pixel at ``θ`` sees the sun if the ray's direction lies within the sun's disc:
    each is moved by a uniform point of a disc of radius SUN_RADIUS_DEG (small-angle, in the plane of the sky),
    and the counts per ring are divided by the ring's solid angle."""
    rng = np.random.default_rng(seed)
    b = np.sqrt(rng.uniform(0.0, 1.0, samples))
    lam = rng.uniform(0.4, 0.7, samples)
    n = WATER[0] + WATER[1] / lam ** 2
    i, r = np.arcsin(b), np.arcsin(b / n)
    theta = np.concatenate([np.degrees(4 * r - 2 * i), 180.0 + np.degrees(2 * i - 6 * r)])
    rho = SUN_RADIUS_DEG * np.sqrt(rng.uniform(0.0, 1.0, theta.size))
    psi = rng.uniform(0.0, 2 * np.pi, theta.size)
    seen = np.hypot(theta + rho * np.cos(psi), rho * np.sin(psi))
    bins = np.arange(0.0, 90.0 + BIN_DEG, BIN_DEG)
    counts, _ = np.histogram(seen, bins)
    solid = np.cos(np.radians(bins[:-1])) - np.cos(np.radians(bins[1:]))
    return bins[:-1] + BIN_DEG / 2, counts / solid


def write_png(img: np.ndarray, path: Path, exposure: float) -> None:
    """``img`` scaled by ``exposure``, gamma 1/2.2, quantised (a picture, not a measurement)."""
    from a5mi.platform.imageio import write_images

    out = np.clip(np.clip(img * exposure, 0.0, 1.0) ** (1 / 2.2) * 255.0 + 0.5, 0, 255).astype(np.uint8)
    write_images([(path, out)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1000)
    ap.add_argument("--spp", type=int, default=6)
    ap.add_argument("--droplets", type=int, default=1000)
    ap.add_argument("--write", type=Path, help="write the scene text there and stop")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "rainbow.png")
    args = ap.parse_args()
    if args.write:
        args.write.write_text(scene_text(args.droplets))
        return
    img, theta = render(args.size, args.spp, args.droplets)
    primary, secondary = measure(img, theta)
    a, b = WATER
    n = a + b / 0.55 ** 2
    i1, i2 = math.acos(math.sqrt((n * n - 1) / 3)), math.acos(math.sqrt((n * n - 1) / 8))
    d1 = math.degrees(4 * math.asin(math.sin(i1) / n) - 2 * i1)
    d2 = 180 + math.degrees(2 * i2 - 6 * math.asin(math.sin(i2) / n))
    m1, m2 = edges(*model_profile())
    spread = np.array(sectors(img, theta))
    print(f"measured primary {primary:.2f} deg, secondary {secondary:.2f} deg (four quadrants: primary "
          f"{spread[:, 0].min():.2f}-{spread[:, 0].max():.2f}, secondary {spread[:, 1].min():.2f}-"
          f"{spread[:, 1].max():.2f}); the same edges of the geometric-optics model {m1:.2f}, {m2:.2f}; "
          f"Descartes at 550 nm {d1:.2f}, {d2:.2f} (sun radius {SUN_RADIUS_DEG} deg, bins {BIN_DEG} deg)")
    np.save(args.out.with_suffix(".npy"), img.astype(np.float32))
    print(f"{int((~np.isfinite(img).all(axis=2)).sum())} non-finite pixels (left out of the profile)")
    small = np.nan_to_num(img).reshape(args.size // 5, 5, args.size // 5, 5, 3).mean(axis=(1, 3))
    lum = small.mean(axis=2)
    write_png(small, args.out, 1.0 / np.percentile(lum[lum > 0], 97))


if __name__ == "__main__":
    main()

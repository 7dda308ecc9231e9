"""Camera rays (SPEC B.2): x = 2 x_pix/(W-1) - 1 in float32, dir = normalize((f w + x u) + y v), and the
a5_camera sensor that maps Mitsuba's film positions onto them."""

from __future__ import annotations

import math

import numpy as np
import pytest

F32 = np.float32


def _norm32(a: np.ndarray) -> np.ndarray:
    """Rows of (n, 3) float32 divided by sqrtf((x*x + y*y) + z*z), operation by operation."""
    a = a.astype(F32)
    n = np.sqrt((a[..., 0] * a[..., 0] + a[..., 1] * a[..., 1]) + a[..., 2] * a[..., 2])
    return a / n[..., None]


def _cross32(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a, b = a.astype(F32), b.astype(F32)
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]], F32)


def ref_rays(center, direction, up, angle_deg, xp, yp, W, H) -> tuple[np.ndarray, np.ndarray]:
    """Independent numpy float32 re-implementation of the binary's camera (SPEC B.2; its cross products take
    the direction as written, not w: read with gdb from the binary's camera, docs/FIDELITY.md)."""
    w = _norm32(np.array(direction, F32))
    u = _norm32(_cross32(np.array(direction, F32), np.array(up, F32)))
    v = _norm32(_cross32(u, np.array(direction, F32)))
    angle = F32(math.pi * float(F32(angle_deg)) / 180.0)
    f = F32(1.0 / math.tan(float(angle) * 0.5))
    x = np.asarray(xp, F32) / F32(W - 1)
    x = (x + x) - F32(1)
    y = np.asarray(yp, F32) / F32(H - 1)
    y = (y + y) - F32(1)
    d = (f * w[None, :] + x[:, None] * u[None, :]) + y[:, None] * v[None, :]
    return np.broadcast_to(np.array(center, F32), d.shape), _norm32(d)


def _rays(center, direction, up, angle, xp, yp, W, H):
    import mitsuba as mi

    from a5mi.plugins.sensors.camera import camera_rays

    ray = camera_rays(center, direction, up, angle, mi.Float(np.asarray(xp, F32)), mi.Float(np.asarray(yp, F32)), W, H)
    return np.asarray(ray.o).T, np.asarray(ray.d).T


CAMERAS = [
    ((0, 0.8, 5), (0, 0, -1), (0, 1, 0), 30.0),
    ((0, 1.5, 5), (0, -0.2, -1), (0, 1, 0), 30.0),  # scene10: direction not unit, not perpendicular to up
    ((1.3, -2.1, 7.7), (-0.3, 0.45, -1.1), (0.2, 1.0, 0.15), 47.5),
]


@pytest.mark.parametrize("cam", CAMERAS)
@pytest.mark.parametrize(("W", "H"), [(5, 5), (60, 40), (40, 60)])
def test_b2_bit_exact_float32_order(variant: str, cam, W: int, H: int) -> None:
    """Every pixel centre, plus jittered positions, bit for bit against the numpy float32 version."""
    jj, ii = np.mgrid[0:H, 0:W]
    rng = np.random.default_rng(W * H)
    xp = np.concatenate([ii.ravel(), ii.ravel() + rng.uniform(-0.5, 0.5, ii.size)]).astype(F32)
    yp = np.concatenate([jj.ravel(), jj.ravel() + rng.uniform(-0.5, 0.5, jj.size)]).astype(F32)
    o, d = _rays(*cam, xp, yp, W, H)
    ro, rd = ref_rays(*cam, xp, yp, W, H)
    assert np.array_equal(o, ro)
    assert np.array_equal(d.view(np.uint32), rd.view(np.uint32))


def test_b2_centre_pixel_is_direction(variant: str) -> None:
    """Odd W = H: the centre pixel has x = y = 0 exactly, so its ray is normalize(f w) = normalize(direction)
    (to the last bit of the float32 renormalisation of f w)."""
    center, direction, up, angle = CAMERAS[2]
    _, d = _rays(center, direction, up, angle, [50], [50], 101, 101)
    assert np.allclose(d[0], _norm32(np.array(direction, F32)), rtol=0, atol=1.2e-7)
    # and x = y = 0 really is hit exactly: f w alone, renormalised, bit for bit
    w = _norm32(np.array(direction, F32))
    f = F32(1.0 / math.tan(float(F32(math.pi * float(F32(angle)) / 180.0)) * 0.5))
    assert np.array_equal(d[0], _norm32(f * w))


def test_b2_corner_pixels_through_minus_one_plus_one(variant: str) -> None:
    """Pixel (0, 0) (bottom-left) has x = y = -1, pixel (W-1, H-1) has x = y = +1: with w = -z, u = +x,
    v = +y and f = 1/tan(45 deg) = 1 they are normalize((-1, -1, -1)) and normalize((1, 1, -1))."""
    _, d = _rays((0, 0, 0), (0, 0, -2), (0, 3, 0), 90.0, [0, 6, 0, 6], [0, 4, 4, 0], 7, 5)
    s = 1 / math.sqrt(3)
    assert np.allclose(d, [[-s, -s, -s], [s, s, -s], [-s, s, -s], [s, -s, -s]], atol=1e-7)


def test_b2_same_factor_both_axes_no_aspect(variant: str) -> None:
    """60x40: the last column and the top row both reach coordinate 1 (no aspect-ratio correction)."""
    _, d = _rays((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, [59, 0], [0, 39], 60, 40)
    s = 1 / math.sqrt(3)
    assert np.allclose(d, [[s, -s, -s], [-s, s, -s]], atol=1e-7)


def test_b2_single_pixel_axis(variant: str) -> None:
    """W = 1 or H = 1: that coordinate is 0 instead of a division by zero."""
    _, d = _rays((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, [0, 0], [0, 2], 1, 3)
    s = 1 / math.sqrt(2)
    assert np.allclose(d, [[0, -s, -s], [0, s, -s]], atol=1e-7)
    _, d = _rays((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, [0], [0], 1, 1)
    assert np.allclose(d, [[0, 0, -1]], atol=0)


def test_b2_bad_basis(variant: str) -> None:
    from a5mi.plugins.sensors.camera import camera_basis, focal_factor

    with pytest.raises(ValueError, match="basis"):
        camera_basis((0, 1, 0), (0, 2, 0))
    with pytest.raises(ValueError, match="angle"):
        focal_factor(180.0)


def _sensor(W: int, H: int, **kw):
    import mitsuba as mi

    d = {
        "type": "a5_camera",
        "center": [1.3, -2.1, 7.7],
        "direction": [-0.3, 0.45, -1.1],
        "up": [0.2, 1.0, 0.15],
        "angle": 47.5,
        "film": {"type": "hdrfilm", "width": W, "height": H, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "stratified", "sample_count": 1, "jitter": False},
    }
    d.update(kw)
    return mi.load_dict(d)


def test_b2_sensor_sample_ray_maps_film_rows(variant: str) -> None:
    """Film position of pixel (col, row) centre, row 0 = top, gives the a5 ray of (i, j) = (col, H-1-row),
    bit for bit. At W = 300, 77 of the 300 float32 positions (i + 0.5)*(1/W) map back to i only up to
    3e-5 pixel: the sensor's snap to pixel centres is what makes this exact."""
    import mitsuba as mi

    W, H = 300, 3
    sensor = _sensor(W, H)
    rows, cols = np.mgrid[0:H, 0:W]
    scale = F32(1) / np.array([W, H], F32)  # what Mitsuba's render loop does: (pixel + 0.5) * (1/size)
    px = ((cols.ravel() + F32(0.5)) * scale[0]).astype(F32)
    py = ((rows.ravel() + F32(0.5)) * scale[1]).astype(F32)
    ray, weight = sensor.sample_ray(mi.Float(0.0), mi.Float(0.5), mi.Point2f(px, py), mi.Point2f(0.5))
    _, want = ref_rays(*CAMERAS[2], cols.ravel(), (H - 1 - rows).ravel(), W, H)
    assert np.array_equal(np.asarray(ray.d).T, want)
    assert np.allclose(np.asarray(weight), 1.0)


def test_b2_sensor_render_pixel_centres(variant: str) -> None:
    """mi.render with the stratified/jitter-off sampler and a box filter traces one ray per pixel centre:
    the hit positions on the plane z = -10 are centre + t d for the reference rays, top row first."""
    import mitsuba as mi

    W, H = 5, 3
    scene = mi.load_dict(
        {
            "type": "scene",
            "sensor": _sensor(W, H, center=[0, 0, 0], direction=[0, 0, -1], up=[0, 1, 0], angle=60.0),
            "integrator": {"type": "aov", "aovs": "p:position"},
            "plane": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().translate([0, 0, -10]).scale(100),
            },
        }
    )
    img = np.asarray(mi.render(scene))
    assert img.shape == (H, W, 3)
    rows, cols = np.mgrid[0:H, 0:W]
    _, d = ref_rays((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, cols.ravel(), (H - 1 - rows).ravel(), W, H)
    want = d * (-10.0 / d[:, 2:3])
    assert np.allclose(img.reshape(-1, 3), want, atol=1e-4)
    assert img[0, 0, 1] > 0 > img[-1, 0, 1]  # top row of the image looks up
    assert "sensor.angle" in mi.traverse(scene).keys()


def test_e3_sensor_thin_lens_is_the_driver_lens(variant: str) -> None:
    """docs/EXTENSIONS.md E.3 in a5_camera: with ``aperture`` the sensor's ray for aperture sample ``s`` is the
    driver's thin-lens ray of the same pinhole ray and sample (bit for bit); its origin lies on the lens disc
    of radius A/2 around the centre and it passes through the pinhole ray's point on the focus plane."""
    import mitsuba as mi

    from a5mi.render.passes import thin_lens
    from a5mi.vecmath32 import camera_basis

    W, H = 7, 5
    cam = dict(center=[0.5, 1.0, 6.0], direction=[0.1, -0.2, -1.0], up=[0, 1, 0], angle=40.0)
    sensor = _sensor(W, H, **cam, aperture=0.8, focus_distance=5.0)
    rng = np.random.default_rng(3)
    px, py = rng.random(40, dtype=F32), rng.random(40, dtype=F32)
    s3 = mi.Point2f(rng.random(40, dtype=F32), rng.random(40, dtype=F32))
    ray, _ = sensor.sample_ray(mi.Float(0.0), mi.Float(0.5), mi.Point2f(px, py), s3)
    pinhole, _ = _sensor(W, H, **cam).sample_ray(mi.Float(0.0), mi.Float(0.5), mi.Point2f(px, py), s3)
    camera = type("C", (), {"direction": cam["direction"], "up": cam["up"], "aperture": 0.8, "focus_distance": 5.0})
    want = thin_lens(pinhole, camera, s3)
    assert np.array_equal(np.asarray(ray.o), np.asarray(want.o)) and np.array_equal(np.asarray(ray.d),
                                                                                  np.asarray(want.d))
    o, d = np.asarray(ray.o).T.astype(np.float64), np.asarray(ray.d).T.astype(np.float64)
    assert np.all(np.linalg.norm(o - cam["center"], axis=1) <= 0.4 + 1e-6)
    w = np.asarray(camera_basis(cam["direction"], cam["up"])[0], dtype=np.float64)
    p_o, p_d = np.asarray(pinhole.o).T.astype(np.float64), np.asarray(pinhole.d).T.astype(np.float64)
    focus = p_o + (5.0 / (p_d @ w))[:, None] * p_d
    t = ((focus - o) @ w) / (d @ w)
    assert np.allclose(o + t[:, None] * d, focus, atol=1e-4)
    assert not np.allclose(o, cam["center"])  # the lens moved the origins: the test can fail
    assert "sensor.aperture" not in mi.traverse(sensor).keys() and "aperture" in mi.traverse(sensor).keys()


def test_sensor_pixel_centres_ignores_the_position_inside_the_pixel(variant: str) -> None:
    """``pixel_centres``: any film position inside pixel (col, row) gives the ray of its centre, (i, j) =
    (col, H-1-row), bit for bit; without it the position moves the ray."""
    import mitsuba as mi

    W, H = 9, 4
    rng = np.random.default_rng(5)
    cols, rows = rng.integers(0, W, 60), rng.integers(0, H, 60)
    px = ((cols + rng.random(60)) / W).astype(F32)
    py = ((rows + rng.random(60)) / H).astype(F32)
    args = (mi.Float(0.0), mi.Float(0.5), mi.Point2f(px, py), mi.Point2f(0.5))
    ray, _ = _sensor(W, H, pixel_centres=True).sample_ray(*args)
    _, want = ref_rays(*CAMERAS[2], cols, H - 1 - rows, W, H)
    assert np.array_equal(np.asarray(ray.d).T, want)
    moved, _ = _sensor(W, H).sample_ray(*args)
    assert not np.array_equal(np.asarray(moved.d).T, want)

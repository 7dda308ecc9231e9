"""a5mi's emitters inside Mitsuba's own light tracer (docs/MITSUBA.md): every a5 emitter answers the calls that
``ptracer`` makes on every emitter alive in the process (``sample_ray``, ``sample_wavelengths``,
``sample_position``), so a stock render works while an a5 scene is loaded; the light rays they give carry the
light's power (area lights) and the environment's radiance (cube maps)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT


def _ptracer_scene(mi, extra: dict | None = None, spp: int = 4, size: int = 16) -> object:
    d = {"type": "scene", "integrator": {"type": "ptracer", "max_depth": 3, "hide_emitters": True},
         "sensor": {"type": "perspective", "fov": 30,
                    "to_world": mi.ScalarTransform4f().look_at([0, 0, 5], [0, 0, 0], [0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}},
                    "sampler": {"type": "independent", "sample_count": spp}},
         "s": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.7}}}}
    d.update(extra or {"l": {"type": "point", "position": [0, 2, 2], "intensity": {"type": "rgb", "value": 5}}})
    return mi.load_dict(d)


@pytest.mark.parametrize("scene", ["scenes/soft_shadows.txt", "scenes/spot.txt", "COURSE/scene10_sphere.txt"])
def test_stock_ptracer_renders_while_an_a5_scene_is_alive(mi, scene: str, scenes_dir: Path) -> None:
    """Before: 'tried to call a pure virtual function' (a5_point / a5_area sample_wavelengths, a5_cubemap
    sample_position / sample_ray) as soon as an a5 scene was loaded in the process."""
    from a5mi.render import session
    from a5mi.render.options import RenderOptions

    path = scenes_dir / scene.split("/", 1)[1] if scene.startswith("COURSE/") else ROOT / scene
    desc, _ = session.describe_file(str(path))
    alive = session.build_scene(desc, RenderOptions(width=8, height=8))
    image = np.asarray(mi.render(_ptracer_scene(mi), seed=1))
    assert alive is not None and np.isfinite(image).all() and image.mean() > 0.0


def test_area_light_rays_carry_its_power(mi) -> None:
    """A parallelogram's light rays start on it, leave through the chosen face's hemisphere, and weigh
    ``2 π A color`` (its two faces' power); a sphere's start on it and leave outwards, ``4 π² R² color``."""
    import drjit as dr

    n = 4096
    rng = np.random.default_rng(3)
    s1 = mi.Float(rng.random(n))
    s2 = mi.Point2f(rng.random(n), rng.random(n))
    s3 = mi.Point2f(rng.random(n), rng.random(n))
    quad = mi.load_dict({"type": "a5_area", "shape": "parallelogram", "corner": [0, 0, 0], "edge1": [2, 0, 0],
                         "edge2": [0, 3, 0], "color": {"type": "rgb", "value": [0.5, 1, 2]}})
    ray, weight = quad.sample_ray(mi.Float(0.0), s1, s2, s3)
    o, d, w = (np.array(dr.detach(x)) for x in (ray.o, ray.d, weight))
    assert np.allclose(o[2], 0.0) and (o[0] >= 0).all() and (o[0] <= 2).all() and (o[1] <= 3).all()
    front = np.asarray(s1) < 0.5
    assert (d[2][front] >= 0).all() and (d[2][~front] <= 0).all()
    assert np.allclose(w.T, 2 * np.pi * 6.0 * np.array([0.5, 1, 2]), rtol=1e-5)
    ball = mi.load_dict({"type": "a5_area", "shape": "sphere", "center": [1, 2, 3], "radius": 0.5})
    ray, weight = ball.sample_ray(mi.Float(0.0), s1, s2, s3)
    o, d, w = (np.array(dr.detach(x)) for x in (ray.o, ray.d, weight))
    outward = o - np.array([[1], [2], [3]])
    assert np.allclose(np.linalg.norm(outward, axis=0), 0.5, rtol=1e-5)
    assert ((outward * d).sum(axis=0) >= -1e-6).all()
    assert np.allclose(w, 4 * np.pi**2 * 0.25, rtol=1e-5)


def test_cube_map_light_rays_give_what_path_tracing_gives(mi, scenes_dir: Path) -> None:
    """A diffuse sphere lit only by an ``a5_cubemap``: light tracing (``ptracer``, the environment's
    ``sample_ray``) and path tracing (``path``, its ``sample_direction``) agree on the sphere's mean colour
    within 4 standard errors, the error of the light-traced mean estimated from four seeds."""
    env = {"env": {"type": "a5_cubemap", "filename": str(scenes_dir / "tex" / "church")}}
    yy, xx = np.mgrid[:24, :24]
    disc = (xx - 11.5) ** 2 + (yy - 11.5) ** 2 < 36
    traced = np.array([np.asarray(mi.render(_ptracer_scene(mi, env, 64, 24), seed=s))[disc].mean(axis=0)
                       for s in range(4)])
    scene = _ptracer_scene(mi, env, 256, 24)
    path = mi.load_dict({"type": "path", "max_depth": 2, "hide_emitters": True})
    reference = np.asarray(mi.render(scene, integrator=path, seed=9))[disc].mean(axis=0)
    stderr = traced.std(axis=0, ddof=1) / 2.0  # of the mean of 4 renders
    # 2e-3 of the reference: its own error (256 spp over ~110 pixels, about 1e-3 measured across seeds)
    assert (np.abs(traced.mean(axis=0) - reference) < 4 * stderr + 2e-3 * reference).all(), (traced, reference)

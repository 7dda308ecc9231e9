"""The integrator base (plugins/integrators/base.py; SPEC B.3, B.4, docs/EXTENSIONS.md E.13): every a5 integrator
reads the shared parameters through it, so a bad shared parameter gives the same one-line error from each; a
minimal integrator written on it loads with ``mi.load_dict`` and renders the analytic image of a sphere."""

from __future__ import annotations

import math
import re
from typing import Any

import pytest

INTEGRATORS = ("a5_whitted", "a5_path", "a5_photon", "a5_ppm", "a5_irradiancecache")
#: a bad value of every shared parameter, and the wording of its error after ``<plugin>: '<name>' must be``
BAD_SHARED = {
    "max_depth": (-1, "an integer >= 0, got -1"),
    "tmin": (-0.5, "a finite number >= 0, got -0.5"),
    "fresnel": ("fast", "one of a5, schlick, exact, got 'fast'"),
    "reflection": (3, "a boolean, got 3"),
    "refraction": ("no", "a boolean, got 'no'"),
    "bump": (1, "a boolean, got 1"),
    "shadows": (2, "a boolean, got 2"),
    "phong": (0.5, "a boolean, got 0.5"),
    "glossy": ("yes", "a boolean, got 'yes'"),
    "glossy_samples": (0, "an integer >= 1, got 0"),
    "dispersion": (7, "a boolean, got 7"),
    "ambient": ("red", "an rgb colour, got 'red'"),
}


def _error(mi: Any, params: dict[str, Any]) -> str:
    """The one line a plugin's ValueError ends in, as ``mi.load_dict`` reports it."""
    with pytest.raises(Exception) as info:   # noqa: PT011 - Mitsuba wraps the plugin's ValueError
        mi.load_dict(params)
    return str(info.value).strip().splitlines()[-1].removeprefix("ValueError: ")


@pytest.mark.parametrize("key", sorted(BAD_SHARED))
def test_a_bad_shared_parameter_reads_the_same_from_every_integrator(mi: Any, key: str) -> None:
    value, wording = BAD_SHARED[key]
    for name in INTEGRATORS:
        assert _error(mi, {"type": name, key: value}) == f"{name}: '{key}' must be {wording}"


def test_aovs_and_media_are_checked_by_the_base(mi: Any) -> None:
    groups = {"a5_whitted": "normal, depth, class, counts", "a5_path": "normal, depth, counts",
              "a5_photon": "counts", "a5_irradiancecache": "normal, depth, counts"}
    for name, offered in groups.items():
        assert _error(mi, {"type": name, "aovs": "colour"}) == f"{name}: 'aovs' must list groups of {offered}, " \
                                                               "got 'colour'"
    for name in ("a5_path", "a5_photon", "a5_irradiancecache"):
        assert _error(mi, {"type": name, "medium": "fog"}) == (
            f"{name}: participating media are not part of E.13 (medium 'fog')")


def test_e13_integrators_fix_the_whitted_options(mi: Any) -> None:
    """The physically based integrators accept the Whitted options and build their kernel without them; the
    irradiance cache's camera tree keeps one stack level more than its bounce budget."""
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    opts = {"shadows": False, "phong": True, "glossy": True, "glossy_samples": 3, "dispersion": True,
            "ambient": {"type": "rgb", "value": [0.5, 0.5, 0.5]}, "max_depth": 9}
    for name in ("a5_path", "a5_irradiancecache"):
        integ = mi.load_dict({"type": name, **opts})
        f = integ.features(scene, integ.scene_data(scene))
        assert (f.shadows, f.phong, f.glossy, f.dispersion, integ.ambient) == (True, False, False, False, [0.0] * 3)
    ic = mi.load_dict({"type": "a5_irradiancecache", "max_depth": 9})
    assert ic.features(scene, ic.scene_data(scene)).stack_size == 11
    whitted = mi.load_dict({"type": "a5_whitted", **opts})
    f = whitted.features(scene, whitted.scene_data(scene))
    assert (f.shadows, f.phong, f.glossy, f.dispersion, f.stack_size) == (False, True, True, True, 14)


def _eyelight(mi: Any) -> type:
    """A minimal integrator on the base: ``kd |d·N|`` of the first hit, AOVs ``normal`` and ``depth``."""
    import drjit as dr

    from a5mi.plugins.integrators.base import E13_FIXED, A5Integrator, camera_rays
    from a5mi.plugins.kernel.intersect import intersect
    from a5mi.plugins.kernel.surfaces import surface_at

    class EyeLight(A5Integrator):
        name = "a5_test_eyelight"
        aov_groups = ("normal", "depth")
        fixed = E13_FIXED
        exposed = ("max_depth", "tmin", "aovs")

        def sample(self, scene: Any, sampler: Any, ray: Any, medium: Any = None, active: Any = True,
                   ) -> tuple[Any, Any, list[Any]]:
            data = self.scene_data(scene)
            o, d, go = camera_rays(ray, active)
            zero = dr.zeros(mi.UInt32, dr.width(go))
            h = intersect(scene, data.planes, data.rules, o, d, mi.Float(zero), zero)
            s = surface_at(h.bsdf, h.si, h.hit & go, h.n, self.features(scene, data), None, mi.UInt32(1))
            color = dr.select(h.hit & go, s.kd * dr.abs(dr.dot(d, s.n)), 0.0)
            depth = dr.select(h.hit, h.t, dr.inf)
            return color, go, self.aov_values({"normal": [s.n.x, s.n.y, s.n.z], "depth": [depth]})

    return EyeLight


def test_a_minimal_integrator_on_the_base_loads_and_renders(mi: Any) -> None:
    """A unit sphere 5 units in front of the camera: the centre pixel sees ``kd`` (``|d·N| > cos 6°``: the
    pixel's rays leave the axis by < 0.9°) at ``t`` within 0.01 of 4; a corner pixel misses (black, t = inf)."""
    import numpy as np

    cls = _eyelight(mi)
    mi.register_integrator("a5_test_eyelight", lambda props: cls(props))
    integ = mi.load_dict({"type": "a5_test_eyelight", "aovs": "depth,normal", "max_depth": 2})
    assert integ.aov_names() == ["nx", "ny", "nz", "t"]
    assert set(mi.traverse(integ).keys()) == {"max_depth", "tmin", "aovs"}
    kd = [0.2, 0.4, 0.6]
    scene = mi.load_dict({
        "type": "scene", "integrator": integ,
        "sensor": {"type": "perspective", "fov": 30.0, "to_world": mi.ScalarTransform4f().look_at(
            origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {"type": "hdrfilm", "width": 17, "height": 17, "rfilter": {"type": "box"}}},
        "ball": {"type": "sphere", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": kd}}}})
    image = np.asarray(mi.render(scene))
    assert image.shape == (17, 17, 7)
    centre, corner = image[8, 8], image[0, 0]
    assert np.all(np.abs(centre[:3] / kd - 1.0) < 1.0 - math.cos(math.radians(6.0)))
    assert abs(centre[6] - 4.0) < 0.01 and centre[5] > 0.99          # depth; the normal faces the camera
    assert np.all(corner[:3] == 0.0) and math.isinf(corner[6])
    with pytest.raises(Exception, match=re.escape("a5_test_eyelight: 'aovs' must list groups of normal, depth")):
        mi.load_dict({"type": "a5_test_eyelight", "aovs": "class"})

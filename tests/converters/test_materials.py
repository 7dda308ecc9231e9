"""Stock material mapping (converters/materials.py): the a5 sum ``kd·D + ks·M`` as a physically based blend.

With ``d = max kd``, ``m = max ks``, ``s = min(d + m, 1)``: ``blendbsdf(w = m/(d+m), diffuse(kd·s/d), mirror(ks·s/m))``
whose effective diffuse and mirror colours are ``(1 − w)·kd·s/d = kd·s/(d+m)`` and ``w·ks·s/m = ks·s/(d+m)``:
the a5 colours exactly when ``d + m ≤ 1``, both divided by ``d + m`` otherwise.
"""

from __future__ import annotations

import numpy as np
import pytest

from a5mi.converters.describe import MaterialDescription
from a5mi.converters.materials import stock_bsdf

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def _mat(kd, ks, ior=0.0) -> MaterialDescription:
    return MaterialDescription(tuple(kd), tuple(ks), 0.0, ior, None)


def _effective(d: dict) -> tuple[np.ndarray, np.ndarray]:
    """(effective diffuse colour, effective specular colour) of a stock BSDF dict."""
    if d["type"] == "diffuse":
        return np.asarray(d["reflectance"]["value"]), np.zeros(3)
    if d["type"] in ("conductor", "dielectric"):
        return np.zeros(3), np.asarray(d["specular_reflectance"]["value"])
    w = d["weight"]
    return ((1 - w) * np.asarray(d["bsdf_0"]["reflectance"]["value"]),
            w * np.asarray(d["bsdf_1"]["specular_reflectance"]["value"]))


@pytest.mark.parametrize(("kd", "ks"), [((0.5, 0.3, 0.1), (0.3, 0.3, 0.3)), ((0.2, 0.4, 0.0), (0.5, 0.1, 0.0)),
                                        ((0.6, 0.6, 0.6), (0.0, 0.0, 0.4))])
def test_sum_that_fits_in_energy_is_exact(kd, ks) -> None:
    dif, spec = _effective(stock_bsdf(_mat(kd, ks), with_uv=False))
    assert np.allclose(dif, kd, atol=1e-12) and np.allclose(spec, ks, atol=1e-12)


def test_coloured_diffuse_under_a_white_mirror_keeps_its_hue() -> None:
    """The issue's case: diffuse (0.8, 0.2, 0.2) + specular white; the old mapping gave a plain white mirror."""
    d = stock_bsdf(_mat((0.8, 0.2, 0.2), (1.0, 1.0, 1.0)), with_uv=False)
    assert d["type"] == "blendbsdf" and d["weight"] == pytest.approx(1 / 1.8)
    dif, spec = _effective(d)
    assert np.allclose(dif, np.array([0.8, 0.2, 0.2]) / 1.8) and np.allclose(spec, np.ones(3) / 1.8)
    assert np.all(np.asarray(d["bsdf_0"]["reflectance"]["value"]) <= 1.0)  # every reflectance stays physical


def test_clear_glass_and_plain_diffuse_are_unblended() -> None:
    glass = stock_bsdf(_mat((0, 0, 0), (0.9, 0.9, 0.9), ior=1.5), with_uv=False)
    assert glass["type"] == "dielectric" and glass["int_ior"] == 1.5
    assert glass["specular_reflectance"] == glass["specular_transmittance"]
    assert glass["specular_reflectance"]["value"] == pytest.approx([0.9] * 3)
    plain = stock_bsdf(_mat((0.3, 0.2, 0.1), (0.0005, 0.0005, 0.0005)), with_uv=False)  # |ks| <= 0.001
    assert plain == {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.3, 0.2, 0.1]}}

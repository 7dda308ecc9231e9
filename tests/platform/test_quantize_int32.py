"""SPEC B.1's ``byte = clamp(int(c * 255), 0, 255)`` with the x86 int32 conversion (a5mi/platform/imageio.py).

Measured on a5soln (``-size 20 20``, a diffuse sphere of ``diffuseColor 0.5`` lit head-on by a
``DirectionalLight`` of colour ``C``, centre pixel ``0.5 C``): ``C`` = 1e5 .. 1.6e7 renders 255, ``C`` = 1.7e7,
2e7, 1e8 .. 1e20, 1e30 and 1e38 render 0. The boundary lies between ``c`` = 8.0e6 and 8.5e6: ``c · 255 = 2³¹``
at ``c = 8,421,504.5``, where ``cvttss2si`` stops holding the product and returns ``INT_MIN``.
"""

from __future__ import annotations

import numpy as np
import pytest

from a5mi.platform.imageio import quantize

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def test_in_range_truncates_and_clamps() -> None:
    q = quantize([0.5, 1.2, -0.1, 1.0, 0.0, 254.9 / 255, 8.0e6, -5.0])
    assert q.tolist() == [127, 255, 0, 255, 0, 254, 255, 0]


def test_beyond_int32_is_black_as_in_the_sample_solution() -> None:
    """0.5 C for the measured C (module docstring): 255 up to 8.0e6, 0 from 8.5e6 on; NaN and ±inf are 0 too
    (the same conversion)."""
    white = 0.5 * np.array([1e5, 8e6, 9e6, 1e7, 1.6e7], dtype=np.float32)
    black = 0.5 * np.array([1.7e7, 2e7, 4e7, 1e8, 1e12, 1e20, 1e30, 1e38], dtype=np.float32)
    assert quantize(white).tolist() == [255] * 5
    assert quantize(black).tolist() == [0] * 8
    assert quantize([float("nan"), float("inf"), -float("inf"), -1e30]).tolist() == [0, 0, 0, 0]


def test_the_boundary_is_two_to_the_31() -> None:
    """``c · 255`` in float32: the largest float32 below ``2³¹/255`` still converts, the next ones do not."""
    edge = np.float32(2.0**31) / np.float32(255.0)
    below = np.nextafter(np.float32(2.0**31 - 128) / np.float32(255.0), np.float32(0))
    assert quantize([below]).tolist() == [255]
    assert quantize([edge, np.nextafter(edge, np.float32(np.inf))]).tolist() == [0, 0]

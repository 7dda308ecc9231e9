"""The irradiance cache's formulas against closed forms (docs/EXTENSIONS.md E.23): numpy only, no Mitsuba.

Hemisphere estimates use seeded stratified samples; each tolerance is stated against the spread measured
over seeds (σ) and the estimator's known bias (the cell-difference gradients of Ward and Heckbert are first
order in the stratum size: a bias of about 1/M).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from a5mi.plugins.integrators.irradiance_cache import formulas as icm
from a5mi.plugins.integrators.irradiance_cache.grid import RecordSet, cell_keys

pytestmark = pytest.mark.unit  # the fast tier (`make check`): no Mitsuba, no child process


def _hemisphere(n: np.ndarray, m: int, nn: int, seed: int) -> np.ndarray:
    return icm.directions(n, m, nn, np.random.default_rng(seed).random((n.shape[0], m, nn, 2)))


def _rgb(L: np.ndarray) -> np.ndarray:
    return np.repeat(L[..., None], 3, axis=-1)


def test_strata_follow_n_equals_pi_m() -> None:
    assert icm.strata(256) == (9, 28)
    assert icm.strata(1000) == (18, 56)
    with pytest.raises(ValueError):
        icm.strata(5)


def test_frames_are_right_handed_orthonormal() -> None:
    n = np.random.default_rng(0).normal(size=(200, 3))
    n[0] = (0, 0, -1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    s, t = icm.frames(n)
    for a, b in ((s, t), (s, n), (t, n)):
        assert np.allclose(np.einsum("kx,kx->k", a, b), 0.0, atol=1e-12)
    assert np.allclose(np.cross(s, t), n, atol=1e-12)


def test_directions_are_stratified_in_projected_solid_angle() -> None:
    """Sample (j, k) lies in its stratum: (j)/M <= sin²θ < (j+1)/M and 2πk/N <= φ < 2π(k+1)/N."""
    n = np.array([[0.0, 0.0, 1.0]])
    d = _hemisphere(n, 6, 19, 3)[0]
    sin2 = 1.0 - d[..., 2] ** 2
    j = np.arange(6)[:, None]
    assert np.all((sin2 >= j / 6 - 1e-12) & (sin2 < (j + 1) / 6 + 1e-12))
    phi = np.mod(np.arctan2(d[..., 1], d[..., 0]), 2 * np.pi)
    k = np.arange(19)[None, :]
    assert np.all((phi >= 2 * np.pi * k / 19 - 1e-9) & (phi < 2 * np.pi * (k + 1) / 19 + 1e-9))


def test_uniform_sky_gives_pi_and_no_gradient() -> None:
    """L = 1 from every direction, no hit: E = π exactly (stratified sum of π/(MN)), R = ∞, both gradients 0
    (Σ_k over N evenly spaced tangents vanishes)."""
    n = np.array([[0.0, 0.6, 0.8]])
    L = np.ones((1, 9, 28, 3))
    est = icm.estimate(n, L, np.full((1, 9, 28), np.inf))
    assert np.allclose(est.E, math.pi, rtol=1e-12)
    assert est.R[0] == np.inf
    assert np.abs(est.grad_r).max() < 1e-12 and np.abs(est.grad_t).max() < 1e-12


def test_linear_radiance_irradiance_and_rotation_gradient() -> None:
    """L(ω) = c0 + c·ω at distance 1: E(n) = π c0 + (2π/3) c·n, and ∇r E = (2π/3) n × c (so that
    E(n') ≈ E(n) + (n × n')·∇r E). At 18 x 56 strata the relative error of ∇r over 50 seeds is 0.42% ± 0.21%
    (max 0.97%) and of E 0.045% (σ); tolerances 2% and 0.3%."""
    n = np.array([[0.3, -0.2, 0.9]])
    n /= np.linalg.norm(n)
    c, c0 = np.array([0.4, -0.7, 0.2]), 1.0
    m, nn = icm.strata(1000)
    d = _hemisphere(n, m, nn, 7)
    est = icm.estimate(n, _rgb(c0 + d @ c), np.ones((1, m, nn)))
    exact_e = math.pi * c0 + 2 * math.pi / 3 * c @ n[0]
    exact_g = 2 * math.pi / 3 * np.cross(n[0], c)
    assert abs(est.E[0, 0] / exact_e - 1) < 3e-3
    assert np.linalg.norm(est.grad_r[0, :, 0] - exact_g) < 0.02 * np.linalg.norm(exact_g)
    assert np.allclose(est.grad_r[0, :, 0], est.grad_r[0, :, 2])      # every channel alike


@pytest.mark.parametrize("x", [-1.0, -0.3, 0.0, 0.5, 1.0])
def test_half_plane_emitter_translation_gradient(x: float) -> None:
    """A point on the floor z = 0 under an emitting ceiling z = h over x > 0 (radiance 1): view factor
    ½(1 + x/√(x² + h²)), so E = π/2 (1 + x/√(x² + h²)) and dE/dx = (π/2) h²/(x² + h²)^{3/2}; the harmonic
    mean distance to a plane is 3h/2. At 40 x 126 strata (20 seeds) E is within 0.1% ± 0.4%, ∂E/∂x has a
    bias of +0.3% .. +1.7% (the cell differences, first order in 1/M) with σ <= 0.44%, ∂E/∂y is 0 ± 0.5%:
    tolerances 2% for E, 4% for ∂E/∂x, 3% (of ∂E/∂x) for ∂E/∂y."""
    h = 1.0
    p, n = np.array([[x, 0.2, 0.0]]), np.array([[0.0, 0.0, 1.0]])
    d = _hemisphere(n, 40, 126, 11)
    t = (h - p[0, 2]) / d[..., 2]
    L = np.where(p[0, 0] + t * d[..., 0] > 0.0, 1.0, 0.0)
    est = icm.estimate(n, _rgb(L), t)
    exact_e = math.pi / 2 * (1 + x / math.hypot(x, h))
    exact_g = math.pi / 2 * h * h / (x * x + h * h) ** 1.5
    assert abs(est.E[0, 0] / exact_e - 1) < 0.02
    assert abs(est.grad_t[0, 0, 0] / exact_g - 1) < 0.04
    assert abs(est.grad_t[0, 1, 0]) < 0.03 * exact_g and abs(est.grad_t[0, 2, 0]) < 1e-12
    assert est.R[0] == pytest.approx(1.5 * h, rel=1e-3)     # stratified: 1.5001 here


def test_ward_weight_of_a_record_on_a_plane() -> None:
    """ε = |p − p_i|/R_i + sqrt(1 − n·n_i), w = 1/ε, used where ε < a."""
    pi, ni = np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]])
    tilt = math.radians(20)
    n = np.array([[math.sin(tilt), 0.0, math.cos(tilt)]])
    eps = icm.epsilon(np.array([[0.5, 0.0, 0.0]]), n, pi, ni, np.array([2.0]))
    assert eps[0] == pytest.approx(0.25 + math.sqrt(1 - math.cos(tilt)), rel=1e-12)

    cache = RecordSet(a=0.5)
    z3 = np.zeros((1, 3, 3))
    cache.add(pi, ni, np.array([[1.0, 2.0, 3.0]]), np.array([2.0]), z3, z3, np.array([0.01]))
    q = np.array([[0.5, 0.0, 0.0], [0.99, 0.0, 0.0], [1.01, 0.0, 0.0], [0.0, 0.3, 0.0]])
    qn = np.repeat(ni, 4, axis=0)
    look = cache.lookup(q, qn, pairs=True)
    assert look.covered.tolist() == [True, True, False, True]         # reach a R = 1 on the plane
    assert np.allclose(look.E[look.covered], [1.0, 2.0, 3.0])
    assert look.pair_weight is not None
    assert np.allclose(sorted(look.pair_weight), sorted([1 / 0.25, 1 / 0.495, 1 / 0.15]))
    # a tilted normal eats into the reach: ε = 0.25 + sqrt(1 − cos 20°) = 0.4956 < 0.5; at 35°: 0.6754
    steep = math.radians(35)
    qn2 = np.array([[math.sin(tilt), 0, math.cos(tilt)], [math.sin(steep), 0, math.cos(steep)]])
    assert cache.lookup(q[:2] * [1, 0, 0], qn2).covered.tolist() == [True, False]


def test_in_front_records_are_rejected() -> None:
    """Ward's test: a record whose tangent plane lies above p by more than 0.05 R_i is not used (here
    d = −1 < −0.5 below, d = +0.4 above; both within reach, ε ≈ 0.1 and 0.04 < a)."""
    cache = RecordSet(a=0.5)
    z3 = np.zeros((1, 3, 3))
    cache.add(np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]), np.ones((1, 3)), np.array([10.0]),
              z3, z3, np.ones(1))
    look = cache.lookup(np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 1.4]]), np.array([[0.0, 0, 1.0], [0.0, 0, 1.0]]))
    assert look.covered.tolist() == [False, True]


def test_linear_field_is_interpolated_exactly_with_gradients() -> None:
    """Records of E(p) = E0 + G (p − p0) (per channel) carrying ∇t E = G reproduce E everywhere they reach
    (each extrapolation is exact, so the weighted mean is); without the gradients the error is first order."""
    rng = np.random.default_rng(5)
    k = 400
    p = np.column_stack([rng.random((k, 2)) * 4.0, np.zeros(k)])
    n = np.tile([0.0, 0.0, 1.0], (k, 1))
    G = np.array([[0.3, -0.1, 0.05], [0.2, 0.4, -0.3], [0.0, 0.0, 0.0]])     # axes x channels
    E0 = np.array([2.0, 2.5, 3.0])
    field = lambda q: E0 + q @ G                                         # noqa: E731
    grad_t = np.repeat(G[None], k, axis=0)
    cache = RecordSet(a=0.4)
    cache.add(p, n, field(p), np.full(k, 1.0), np.zeros((k, 3, 3)), grad_t, np.full(k, 0.01))
    q = np.column_stack([0.5 + rng.random((300, 2)) * 3.0, np.zeros(300)])
    qn = np.tile([0.0, 0.0, 1.0], (300, 1))
    with_g = cache.lookup(q, qn)
    assert with_g.covered.all()
    assert np.abs(with_g.E - field(q)).max() < 1e-12
    without = cache.lookup(q, qn, gradients=False)
    assert np.abs(without.E - field(q)).max() > 0.01


def test_rotation_gradient_extrapolates_to_second_order() -> None:
    """A record of E(n) = π + (2π/3) c·n with ∇r E = (2π/3) n_i × c: at a normal tilted by δ the error is
    O(δ²) (here < 2% of the O(δ) error without the gradient)."""
    c = np.array([0.4, -0.7, 0.2])
    ni = np.array([[0.0, 0.0, 1.0]])
    Ei = np.full((1, 3), math.pi + 2 * math.pi / 3 * c @ ni[0])
    grad_r = np.repeat((2 * math.pi / 3 * np.cross(ni[0], c))[None, :, None], 3, axis=2)
    delta = 0.02
    n = np.array([[math.sin(delta), 0.0, math.cos(delta)]])
    exact = math.pi + 2 * math.pi / 3 * c @ n[0]
    value = icm.extrapolate(np.zeros((1, 3)), n, np.zeros((1, 3)), ni, Ei, grad_r, np.zeros((1, 3, 3)))
    assert abs(value[0, 0] - exact) < 0.02 * abs(Ei[0, 0] - exact)


def test_radius_limits() -> None:
    """R ← min(R, E_c/|∇t E_c|), then clamped to [m_min, m_max] · spacing / a; ∇t scaled by min(1, r_min/R_lo)."""
    R = np.array([10.0, 10.0, 10.0, 0.001])
    E = np.array([[1.0, 1, 1], [1.0, 1, 1], [1.0, 1, 1], [1.0, 1, 1]])
    g = np.zeros((4, 3, 3))
    g[1, 0, :] = 2.0                      # E/|∇| = 0.5
    g[3, 1, :] = 4.0
    spacing = np.array([0.01, 0.01, 1.0, 0.01])
    r_min = np.array([1.0, 1.0, 1.0, 0.01])
    out, grad = icm.limit_radius(R, E, g, r_min, spacing, a=0.5, m_min=2.5, m_max=15.0)
    assert out.tolist() == pytest.approx([0.3, 0.3, 10.0, 0.05])
    assert np.array_equal(grad[:3], g[:3])            # nearest hit beyond R_lo: unchanged
    assert np.allclose(grad[3], g[3] * 0.01 / 0.05)   # R_lo = 2.5 · 0.01 / 0.5


def test_grid_keys_and_candidates_cover_every_reach() -> None:
    """Every record whose reach a R_i holds a query point is among its candidates (the grid loses none), for
    records of many sizes."""
    assert cell_keys(np.array([[1, 2, 3]])) != cell_keys(np.array([[1, 3, 2]]))
    rng = np.random.default_rng(9)
    k = 300
    cache = RecordSet(a=0.3)
    p = rng.random((k, 3)) * 10
    cache.add(p, np.tile([0, 0, 1.0], (k, 1)), np.ones((k, 3)), np.exp(rng.uniform(-3, 2, k)),
              np.zeros((k, 3, 3)), np.zeros((k, 3, 3)), np.ones(k))
    q = rng.random((500, 3)) * 10
    cq, cr = cache.candidates(q)
    found = set(zip(cq.tolist(), cr.tolist(), strict=True))
    dist = np.linalg.norm(q[:, None, :] - p[None, :, :], axis=2)
    need = np.argwhere(dist < 0.3 * cache.R[None, :])
    assert need.shape[0] > 50
    assert all((int(a), int(b)) in found for a, b in need)

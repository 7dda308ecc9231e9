"""The measures of ``a5mi diagnose`` (a5mi/diagnose/measure.py, docs/MISTAKES.md "The measure: explained share",
"Closest causes: the likelihood with the noise") on synthetic images whose noise is known."""

from __future__ import annotations

import math

import numpy as np

from a5mi.diagnose.measure import QUANTISATION_VARIANCE, box_mean, explained, log_likelihood


def test_log_likelihood_of_an_exact_noise_free_mutant_is_the_gaussian_peak() -> None:
    m = np.full((8, 8, 3), 0.5)
    assert math.isclose(log_likelihood(m, m, m), -0.5 * math.log(2 * math.pi * QUANTISATION_VARIANCE))


def test_box_mean_averages_the_neighbourhood_with_edges_repeated() -> None:
    a = np.zeros((5, 5, 1))
    a[2, 2] = 9.0
    b = box_mean(a)
    assert b[1:4, 1:4].ravel().tolist() == [1.0] * 9 and b.sum() == 9.0
    corner = np.zeros((3, 3, 1))
    corner[0, 0] = 9.0   # repeated twice down and right: counted 4 times in the corner's box
    assert box_mean(corner)[0, 0, 0] == 4.0


def _noisy(rng: np.random.Generator, mean: np.ndarray, sd: np.ndarray) -> np.ndarray:
    return mean + sd * rng.standard_normal(mean.shape)


def test_likelihood_ranks_a_noisier_mutant_first_where_the_explained_share_cannot() -> None:
    """The image is the noisy mutant A (noise on "edges", every fourth column, sd 0.05) whose mean differs from the
    reference R (noise sd 0.02 on the same columns) by 0.01 there. Under A the image's squared distance is A's own
    noise twice, more than it is from R: E(A) < 0. The likelihood, each hypothesis with its own variance from a
    second draw, ranks A above R and above B, a hypothesis with A's mean and R's noise."""
    rng = np.random.default_rng(3)
    shape = (40, 40, 3)
    edges = np.zeros(shape)
    edges[:, ::4] = 1.0
    mu_r = np.full(shape, 0.4)
    mu_a = mu_r + 0.01 * edges
    sd_a, sd_r = 0.05 * edges, 0.02 * edges
    image = _noisy(rng, mu_a, sd_a)
    a1, a2 = _noisy(rng, mu_a, sd_a), _noisy(rng, mu_a, sd_a)
    r1, r2 = _noisy(rng, mu_r, sd_r), _noisy(rng, mu_r, sd_r)
    b1, b2 = _noisy(rng, mu_a, sd_r), _noisy(rng, mu_a, sd_r)
    assert explained(image, r1, a1) < 0.0
    ll = {k: log_likelihood(image, m1, m2) for k, (m1, m2) in {"A": (a1, a2), "R": (r1, r2), "B": (b1, b2)}.items()}
    assert ll["A"] > ll["B"] and ll["A"] > ll["R"], ll

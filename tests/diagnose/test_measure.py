"""The measures of ``a5mi diagnose`` (a5mi/diagnose/measure.py, docs/MISTAKES.md "The measure: explained share",
"Closest causes: the likelihood with the noise", "Partners: the paired score") on synthetic images whose
noise is known."""

from __future__ import annotations

import math

import numpy as np

from a5mi.diagnose.measure import QUANTISATION_VARIANCE, box_mean, crps, explained, log_likelihood, paired_z


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


def test_crps_is_the_fair_ensemble_estimate_summed_over_channels() -> None:
    """``(|I - M1| + |I - M2|) / 2 - |M1 - M2| / 2``; one member: ``|I - M|``."""
    m1, m2 = np.zeros((1, 1, 2)), np.ones((1, 1, 2))
    for x, want in ((0.5, 0.0), (0.0, 0.0), (2.0, 1.0)):
        assert crps(np.full((1, 1, 2), x), [m1, m2])[0, 0] == 2 * want
    assert crps(np.full((1, 1, 3), 0.25), [np.full((1, 1, 3), 1.0)])[0, 0] == 3 * 0.75


def _gaussian_crps(x: float, sd: float) -> float:
    """The closed form for N(0, sd²) at x: ``sd (z (2Φ(z) - 1) + 2φ(z) - 1/√π)``, z = x / sd."""
    z = x / sd
    cdf, pdf = 0.5 * (1.0 + math.erf(z / math.sqrt(2.0))), math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
    return sd * (z * (2.0 * cdf - 1.0) + 2.0 * pdf - 1.0 / math.sqrt(math.pi))


def test_crps_of_two_renders_is_unbiased_for_the_closed_form() -> None:
    """A value x = 0.7 scored under N(0, 1) from two draws, over 10^6 independent pixels: the mean is the
    closed form within 4 standard errors (the two-member estimate is unbiased, not only consistent)."""
    rng = np.random.default_rng(5)
    shape = (1000, 1000, 1)
    scores = crps(np.full(shape, 0.7), [rng.standard_normal(shape), rng.standard_normal(shape)])
    se = float(np.std(scores)) / math.sqrt(scores.size)
    assert abs(float(np.mean(scores)) - _gaussian_crps(0.7, 1.0)) < 4.0 * se, (np.mean(scores), se)


def test_crps_is_proper_a_noisier_or_noise_free_hypothesis_scores_worse() -> None:
    """Images drawn from N(0.5, 0.05²): in the mean they score best under their own hypothesis (closed form
    0.05/√π), worse under one twice as noisy and under the noise-free mean (0.05 √(2/π)), both from renders."""
    rng = np.random.default_rng(8)
    shape = (200, 200, 3)

    def draw(sd: float) -> np.ndarray:
        return 0.5 + sd * rng.standard_normal(shape)

    image = draw(0.05)
    own = float(np.mean(crps(image, [draw(0.05), draw(0.05)]))) / 3
    noisier = float(np.mean(crps(image, [draw(0.1), draw(0.1)]))) / 3
    still = float(np.mean(crps(image, [np.full(shape, 0.5)]))) / 3
    assert math.isclose(own, 0.05 / math.sqrt(math.pi), rel_tol=0.02), own
    assert math.isclose(still, 0.05 * math.sqrt(2 / math.pi), rel_tol=0.02), still
    assert own < noisier and own < still, (own, noisier, still)


def test_paired_z_is_the_block_sums_mean_over_its_standard_error() -> None:
    """Four 4x4 blocks whose gains sum to 1, 2, 3 and 6: mean 3, sd √(14/3), z = 3 / (sd / 2)."""
    gain = np.zeros((8, 8))
    for (y, x), total in zip(((0, 0), (0, 4), (4, 0), (4, 4)), (1.0, 2.0, 3.0, 6.0), strict=True):
        gain[y, x] = total
    assert math.isclose(paired_z(gain), 3.0 / (math.sqrt(14.0 / 3.0) / 2.0))
    assert paired_z(np.full((8, 8), 0.01)) == math.inf
    assert paired_z(np.zeros((8, 8))) == 0.0 and paired_z(np.ones((3, 3))) == 0.0

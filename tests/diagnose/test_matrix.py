"""The confusion matrix of ``a5mi diagnose`` (tests/diagnose/matrix.py; figures in BENCHMARKS.md).

Slow tier: every catalogued mistake on the three probe scenes where it shows most, with jitter seeds other than
the diagnosis uses; 30 random pairs; the correct renders with three other seeds. Everyday tier: a few mistakes of
each layer on one scene each, and the correct renders."""

from __future__ import annotations

from pathlib import Path

import pytest
from matrix import Figures, run_matrix

from a5mi.render.options import MISTAKES


@pytest.fixture(scope="module")
def matrix(tmp_path_factory: pytest.TempPathFactory, variant: str, scenes_dir: Path) -> Figures:
    fig = run_matrix(tmp_path_factory.mktemp("matrix"), list(MISTAKES), course=scenes_dir)
    print(fig.summary())
    return fig


@pytest.mark.slow
def test_confusion_matrix(matrix: Figures) -> None:
    """The issue's figures over the images whose mistake rises above the jitter noise of two seeds (the others,
    reported in the summary, must get verdict ``match``: a mistake smaller than the noise is never named wrongly);
    every mistake on three scenes; correct renders never named."""
    fig = matrix
    assert all(v == "match" for _, _, v in fig.correct), fig.correct     # never a mistake named on a correct image
    assert not fig.wrong(), fig.wrong()
    counts: dict[str, int] = {}
    for m, *_ in fig.singles:
        counts[m] = counts.get(m, 0) + 1
    assert all(counts.get(m, 0) >= 3 for m in MISTAKES), {m: counts.get(m, 0) for m in MISTAKES if counts.get(m, 0) < 3}
    assert fig.rate(2, above_noise=True) >= 0.90 and fig.rate(3, above_noise=True) >= 0.98, fig.summary()


@pytest.mark.slow
def test_confusion_matrix_pairs(matrix: Figures) -> None:
    assert sum(p[2] for p in matrix.pairs) >= 0.8 * len(matrix.pairs), matrix.summary()


def test_confusion_matrix_subset(tmp_path: Path, variant: str) -> None:
    fig = run_matrix(tmp_path, ["no_ambient", "eta_inside_inverted", "marble_sine_unmapped", "fov_full_angle",
                                "blur_not_normalised", "mirrored"], n_scenes=1,
                     pairs=[("no_ambient", "mirrored"), ("marble_sine_unmapped", "mirrored")])
    assert all(v == "match" for _, _, v in fig.correct), fig.correct
    assert all(s[2] for s in fig.singles) and all(ok for _, _, ok in fig.pairs), fig.summary()

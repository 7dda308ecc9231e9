"""Step 2 of ``a5mi diagnose`` (docs/MISTAKES.md "How the diagnosis works"): the causes an image within the seed
noise of the reference may still have. Two kinds of mistake hide there: one without jitter noise
(:data:`DETERMINISTIC_MISTAKES`), which a correct image made with other jitter offsets never reproduces as closely
as its own image, and a bias of a fraction of a level (:data:`BIASED`), which hides under the squared error's noise
but not in the mean difference.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from a5mi.diagnose.causes import Cause
from a5mi.diagnose.measure import Image, blocks, evidence, explained, mse

#: Mistakes without jitter noise: when one reproduces a seemingly matching image within DETERMINISTIC · σ², it is
#: named (a correct image made with other jitter offsets is never reproduced that closely).
DETERMINISTIC_MISTAKES: tuple[str, ...] = ("no_jitter", "no_supersampling")
DETERMINISTIC = 0.1
#: Mistakes that shift every level a little (a bias below the squared error's noise): looked for in a seemingly
#: matching image's mean difference ``mean(I - R)``, named when that is beyond BIAS_SE standard errors of a mean of
#: the seed noise (from the 4x4-block noise σ_b², ``sqrt(2 σ_b² / blocks)``) and at least BIAS_LEVELS levels, and
#: the mutant leaves at most BIAS_LEFT of it.
BIASED: tuple[str, ...] = ("rounding",)
BIAS_SE = 6.0
BIAS_LEVELS = 0.25
BIAS_LEFT = 0.25


def hidden_in_noise(img: Image, ref: Image, noise: float, noise_blocks: float, names: list[str],
                    full: Callable[[tuple[str, ...]], Image]) -> tuple[Cause, float] | None:
    """The cause of an image ``img`` within the seed noise of the reference ``ref`` (σ² ``noise``, at 4x4 blocks
    ``noise_blocks``), among the candidate ``names``, and what it leaves (mse); None when there is none. ``full(key)``
    renders a mutant at full size. A :data:`DETERMINISTIC_MISTAKES` mutant is named when it leaves at most
    ``DETERMINISTIC · σ²``; else a :data:`BIASED` one when ``|mean(I - R)| > max(BIAS_SE sqrt(2 σ_b² / n),
    BIAS_LEVELS / 255)`` (n block means) and the mutant leaves at most ``BIAS_LEFT`` of that mean."""
    for n in (n for n in DETERMINISTIC_MISTAKES if n in names and noise > 0.0):
        m = full((n,))
        left = mse(img, m)
        if left <= DETERMINISTIC * noise:
            return Cause((n,), explained(img, ref, m), evidence=evidence(img, ref, m, noise)), left
    shift = float(np.mean(img - ref))
    spread = BIAS_SE * math.sqrt(2.0 * noise_blocks / blocks(ref).size)
    for n in (n for n in BIASED if n in names and abs(shift) > max(spread, BIAS_LEVELS / 255.0)):
        m = full((n,))
        if abs(float(np.mean(img - m))) <= BIAS_LEFT * abs(shift):
            return Cause((n,), explained(img, ref, m), evidence=evidence(img, ref, m, noise)), mse(img, m)
    return None

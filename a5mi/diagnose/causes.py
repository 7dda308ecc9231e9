"""What ``a5mi diagnose`` finds (docs/MISTAKES.md "How the diagnosis works"): :class:`Cause` and :class:`Diagnosis`,
which mistakes :func:`combinable` can be made together, and :func:`closest`, the causes of an image no cause
explains ranked by the likelihood with each mistake's jitter noise (docs/MISTAKES.md "Closest causes: the likelihood
with the noise"). :func:`a5mi.diagnose.rank.diagnose` makes them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from a5mi.diagnose.catalogue import BY_NAME, Mistake
from a5mi.diagnose.measure import Evidence, Image
from a5mi.render.options import FILTER_MISTAKES, JITTER_MISTAKES


@dataclass
class Cause:
    """One mutant: its mistakes (one or two names), the explained share at full size (``explained``, None when
    it was only ranked small), the small-render share (``small``), the :class:`Evidence`."""

    mistakes: tuple[str, ...]
    explained: float | None
    small: float | None = None
    evidence: Evidence | None = None
    #: where ``explained`` was measured: ``pixels`` or ``blocks`` (4x4 means,
    #: :func:`a5mi.diagnose.measure.explained_at`)
    scale: str = "pixels"
    #: ``Λ``, the log-likelihood ratio against the reference with the jitter noise counted (nats per value;
    #: :func:`closest`), set for the causes of an image no cause explains and for a name block means alone earn
    likelihood: float | None = None
    #: for a pair listed as a named single plus a partner: the partner's name and the paired CRPS test's ``z`` for
    #: the pair against the single alone (:func:`a5mi.diagnose.measure.paired_z`; docs/MISTAKES.md "Partners: the
    #: paired score")
    partner: str | None = None
    partner_z: float | None = None

    @property
    def catalogue(self) -> list[Mistake]:
        return [BY_NAME[m] for m in self.mistakes]


@dataclass
class Diagnosis:
    """What :func:`a5mi.diagnose.rank.diagnose` found: ``verdict`` (``match``, ``diagnosis`` or ``unexplained``),
    ``psnr`` and ``mse`` of the image against the reference, ``noise`` (σ², the seed noise; 0 without ``-jitter``),
    ``causes`` (best first, at most :data:`a5mi.diagnose.rank.SHOWN`), ``remaining`` (mse left by the best cause, or
    by the reference when none), ``considered`` (mistakes rendered), ``renders`` (small, full) and ``seconds`` by
    stage."""

    verdict: str
    psnr: float
    mse: float
    noise: float
    causes: list[Cause] = field(default_factory=list)
    remaining: float = 0.0
    considered: list[str] = field(default_factory=list)
    renders: dict[str, int] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def best(self) -> Cause | None:
        return self.causes[0] if self.verdict == "diagnosis" and self.causes else None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready data (``a5mi diagnose --json``, the grade report, the view page)."""
        out = dataclasses.asdict(self)
        for c, cause in zip(out["causes"], self.causes, strict=True):
            c["catalogue"] = [{"name": m.name, "section": m.section, "change": m.change, "symptom": m.symptom}
                              for m in cause.catalogue]
        return out


#: The sampling mistakes (jitter, supersampling, blur, downsampling): ``no_supersampling`` leaves the others without
#: effect (:func:`combinable`); beside a named single their effect is mostly the jitter noise, so the diagnosis
#: always tries them as its partners by the paired CRPS test (docs/MISTAKES.md "Partners: the paired score").
SAMPLING: tuple[str, ...] = (*JITTER_MISTAKES, "no_supersampling", *FILTER_MISTAKES)


def combinable(a: str, b: str) -> bool:
    """Whether two mistakes can be made together (the marble texture takes one mistake; two jitter mistakes or
    ``no_supersampling`` with a sampling mistake leave one of them without effect)."""
    layer = {n: m.layer for n, m in BY_NAME.items()}
    if layer[a] == layer[b] == "marble":
        return False
    return not ({a, b} <= set(SAMPLING) and "no_supersampling" in (a, b))


def closest(causes: list[Cause], ref: Image, images: dict[tuple[str, ...], Image],
            ratio: Callable[[tuple[str, ...]], float], shown: int, share: float) -> list[Cause]:
    """The closest causes of an image no cause explains (docs/MISTAKES.md "Closest causes: the likelihood with the
    noise"), at most ``shown`` of ``causes`` (ranked by the explained share): those removing at least ``share`` of
    the squared difference, then as many more of those under which the image is more probable than under the
    correct renderer, ``Λ(M) = ℓ(I | M) - ℓ(I | R) > 0`` (``ratio(key)``:
    :func:`a5mi.diagnose.measure.log_likelihood`, nats per value, each hypothesis with its own jitter noise);
    listed most probable first. Sets their :attr:`Cause.likelihood`; a mutant equal to the reference (its mistake
    does not show here) has ``Λ = 0`` and is not rendered again."""
    out = [c for c in causes if (c.explained or 0.0) >= share][:shown]
    more = []
    for c in causes:
        if np.array_equal(images[c.mistakes], ref):
            c.likelihood = 0.0
        elif c.likelihood is None and (c in out or len(out) < shown):
            c.likelihood = ratio(c.mistakes)
        if c not in out and (c.likelihood or 0.0) > 0.0:
            more.append(c)
    out += sorted(more, key=lambda c: -(c.likelihood or 0.0))[: shown - len(out)]
    return sorted(out, key=lambda c: (-(c.likelihood or 0.0), len(c.mistakes)))

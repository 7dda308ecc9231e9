"""The confusion matrix of ``a5mi diagnose`` (docs/MISTAKES.md "How well it works", BENCHMARKS.md): images made by
a5mi with ``-mistake`` and jitter seeds other than the diagnosis uses, diagnosed with every applicable candidate.

:func:`run_matrix` renders, for every mistake, the three scenes of :func:`scenes` where it shows most (a5mi's
mutant against the correct render, glibc's seed), diagnoses each, and counts top-1 (the first cause is exactly
that mistake, with verdict ``diagnosis``) and top-3 (it is among the mistakes of the first three causes); pairs:
both mistakes among the first three causes' mistakes (a pair is left out, and counted as masked, when its image
equals one of its singles' images at glibc's seed: one mistake hides the other, as a blur that saturates the image
hides a refraction mistake); correct renders with other seeds: verdict ``match``."""

from __future__ import annotations

import itertools
import random
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from a5mi.diagnose.probes import PROBES, describe_probe
from a5mi.diagnose.rank import Diagnosis, as_levels, diagnose
from a5mi.imageio import quantize
from a5mi.options import RenderOptions

SEEDS = (7, 31, 101)


@dataclass
class Figures:
    singles: list[tuple[str, str, bool, bool]] = field(default_factory=list)   # mistake, scene, top1, top3
    pairs: list[tuple[tuple[str, str], str, bool]] = field(default_factory=list)
    correct: list[tuple[str, int, str]] = field(default_factory=list)   # scene, seed, verdict
    masked: list[tuple[str, str]] = field(default_factory=list)   # pairs left out: one hides the other
    cpu: float = 0.0

    def rate(self, k: int) -> float:
        return float(np.mean([s[k] for s in self.singles])) if self.singles else 0.0

    def summary(self) -> str:
        pair = float(np.mean([p[2] for p in self.pairs])) if self.pairs else 0.0
        named = sum(v != "match" for _, _, v in self.correct)
        misses = [f"{m}@{s}" for m, s, t1, _ in self.singles if not t1]
        return (f"{len(self.masked)} pairs masked; singles: {len(self.singles)} images, "
                f"top-1 {100 * self.rate(2):.1f}%, "
                f"top-3 {100 * self.rate(3):.1f}%; pairs: {len(self.pairs)} images, both in the top 3 "
                f"{100 * pair:.1f}%; correct renders: "
                f"{len(self.correct)}, a mistake named {named} times; CPU {self.cpu:.0f} s; top-1 misses: "
                f"{', '.join(misses) or 'none'}; pairs missed: "
                f"{', '.join('+'.join(p) + '@' + s for p, s, ok in self.pairs if not ok) or 'none'}")


def scenes(tmp: Path, size: int = 30) -> dict[str, tuple[object, RenderOptions]]:
    """The matrix's scenes: the four probes (a5mi/diagnose/probes.py), each at ``size``."""
    out = {}
    for probe in PROBES:
        folder = tmp / probe.name
        folder.mkdir(exist_ok=True)
        opts = probe.options()
        out[probe.name] = (describe_probe(probe, folder), RenderOptions(**{**opts.__dict__, "width": size,
                                                                          "height": size}))
    return out


def _image(session, desc, opts: RenderOptions, mistakes: tuple[str, ...], seed: int | None) -> np.ndarray:  # noqa: ANN001
    return quantize(session.render(desc, RenderOptions(**{**opts.__dict__, "seed": seed,
                                                          "mistakes": mistakes})).image)


def _names(d: Diagnosis) -> list[str]:
    return [m for c in d.causes[:3] for m in c.mistakes]


def run_matrix(tmp: Path, mistakes: list[str], n_pairs: int = 30, n_scenes: int = 3, seed: int = 5,
               pairs: list[tuple[str, str]] | None = None) -> Figures:
    """The figures (module docstring) for ``mistakes``, ``n_pairs`` random pairs of them (or the given ``pairs``)
    and the correct renders."""
    from a5mi.diagnose.catalogue import BY_NAME, applicable, option_traits, scene_traits
    from a5mi.diagnose.rank import combinable
    from a5mi.session import RenderSession

    t0 = time.process_time()
    session = RenderSession()
    sc = scenes(tmp)
    fig = Figures()
    where: dict[str, list[str]] = {}
    for name, (desc, opts) in sc.items():
        ok = {m.name for m in applicable(scene_traits(desc) | option_traits(opts))}
        ref = as_levels(session.render(desc, opts).image)
        for m in mistakes:
            if m in ok:
                shown = float(np.mean((as_levels(session.render(desc, RenderOptions(
                    **{**opts.__dict__, "mistakes": (m,)})).image) - ref) ** 2))
                if shown > 5e-6:
                    where.setdefault(m, []).append((shown, name))
    rng = random.Random(seed)
    for k, m in enumerate(mistakes):
        for _, name in sorted(where.get(m, []), reverse=True)[:n_scenes]:
            desc, opts = sc[name]
            d = diagnose(_image(session, desc, opts, (m,), SEEDS[k % len(SEEDS)]), desc, opts, session=session)
            top1 = d.verdict == "diagnosis" and bool(d.causes) and d.causes[0].mistakes == (m,)
            fig.singles.append((m, name, top1, m in _names(d)))
    pool = [(a, b) for a, b in itertools.combinations(mistakes, 2) if combinable(a, b)
            and set(s for _, s in where.get(a, [])) & set(s for _, s in where.get(b, []))
            and BY_NAME[a].layer != BY_NAME[b].layer]
    chosen = pairs if pairs is not None else rng.sample(pool, len(pool))
    for a, b in chosen:
        if len(fig.pairs) >= (len(chosen) if pairs is not None else n_pairs):
            break
        common = sorted(set(s for _, s in where[a]) & set(s for _, s in where[b]))
        name = rng.choice(common)
        desc, opts = sc[name]
        both = _image(session, desc, opts, (a, b), None).astype(float)
        if min(float(np.mean((both - _image(session, desc, opts, (m,), None)) ** 2)) for m in (a, b)) <= 5e-6 * 65025:
            fig.masked.append((a, b))   # one mistake hides the other on this scene: nobody can name both
            continue
        d = diagnose(_image(session, desc, opts, (a, b), rng.choice(SEEDS)), desc, opts, session=session)
        fig.pairs.append(((a, b), name, {a, b} <= set(_names(d))))
    for name, (desc, opts) in sc.items():
        for s in SEEDS:
            d = diagnose(_image(session, desc, opts, (), s), desc, opts, session=session)
            fig.correct.append((name, s, d.verdict))
    fig.cpu = time.process_time() - t0
    return fig

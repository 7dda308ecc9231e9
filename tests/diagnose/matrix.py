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

from a5mi.diagnose.probes import PROBES, Probe, describe_probe
from a5mi.diagnose.rank import Diagnosis, as_levels, diagnose
from a5mi.platform.imageio import quantize
from a5mi.render.options import RenderOptions

SEEDS = (7, 31, 101)


@dataclass
class Figures:
    #: mistake, scene, top1, top3, verdict, first cause's mistakes
    singles: list[tuple[str, str, bool, bool, str, tuple[str, ...]]] = field(default_factory=list)
    pairs: list[tuple[tuple[str, str], str, bool]] = field(default_factory=list)
    correct: list[tuple[str, int, str]] = field(default_factory=list)   # scene, seed, verdict
    masked: list[tuple[str, str]] = field(default_factory=list)   # pairs left out: one hides the other
    cpu: float = 0.0

    def rate(self, k: int, above_noise: bool = False) -> float:
        """Share of single-mistake images right at top-1 (``k = 2``) or top-3 (``k = 3``); ``above_noise``: of
        those the diagnosis did not find within the jitter noise (verdict other than ``match``)."""
        rows = [s for s in self.singles if not above_noise or s[4] != "match"]
        return float(np.mean([s[k] for s in rows])) if rows else 0.0

    def wrong(self) -> list[str]:
        """Single-mistake images given a diagnosis that does not name the mistake first."""
        return [f"{m}@{s}->{'+'.join(first)}" for m, s, t1, _, v, first in self.singles if v == "diagnosis" and not t1]

    def summary(self) -> str:
        pair = float(np.mean([p[2] for p in self.pairs])) if self.pairs else 0.0
        named = sum(v != "match" for _, _, v in self.correct)
        misses = [f"{m}@{s}({v})" for m, s, t1, _, v, _ in self.singles if not t1]
        quiet = sum(s[4] == "match" for s in self.singles)
        return (f"{len(self.masked)} pairs masked; singles: {len(self.singles)} images, "
                f"top-1 {100 * self.rate(2):.1f}%, "
                f"top-3 {100 * self.rate(3):.1f}%; above the jitter noise ({len(self.singles) - quiet} images): "
                f"top-1 {100 * self.rate(2, True):.1f}%, "
                f"top-3 {100 * self.rate(3, True):.1f}%; within it ({quiet}): verdict match; wrong names: "
                f"{', '.join(self.wrong()) or 'none'}; "
                f"top-3 {100 * self.rate(3):.1f}%; pairs: {len(self.pairs)} images, both in the top 3 "
                f"{100 * pair:.1f}%; correct renders: "
                f"{len(self.correct)}, a mistake named {named} times; CPU {self.cpu:.0f} s; top-1 misses: "
                f"{', '.join(misses) or 'none'}; pairs missed: "
                f"{', '.join('+'.join(p) + '@' + s for p, s, ok in self.pairs if not ok) or 'none'}")


#: More scenes: the probes seen from other places (so that every mistake shows on three scenes at least).
VARIANTS: tuple[Probe, ...] = (
    Probe("spheres_side", PROBES[3].text.replace("center 0 1.2 6 direction 0 -0.2 -1",
                                                 "center 4 3 4 direction -0.65 -0.5 -0.6"), bounces=3),
    Probe("lit_left", PROBES[0].text.replace("center 0 0 5 direction 0 0 -1", "center -1 -0.5 5 direction 0.15 0.1 -1"),
          bounces=0),
    Probe("lit_right", PROBES[0].text.replace("center 0 0 5 direction 0 0 -1", "center 1 0.6 5 direction -0.2 -0.1 -1"),
          bounces=0),
    Probe("glass_left", PROBES[2].text.replace("center 0 0 5 direction 0 0 -1", "center -1 0.5 5 direction 0.1 0 -1"),
          shadows=False, bounces=4),
    Probe("glass_steep", PROBES[2].text.replace("normal 0.6 0 -0.8 offset 0.8", "normal 0.8 0 -0.6 offset 0.6"),
          shadows=False, bounces=4),
    Probe("corridor_up", PROBES[1].text.replace("direction 0.2 0.1 -1", "direction -0.1 0.3 -1"), shadows=False,
          bounces=3),
    Probe("placed_left", PROBES[4].text.replace("center 0 0 5 direction 0 0 -1",
                                                "center -2 1 4.5 direction 0.35 -0.2 -1"), bounces=2),
    Probe("placed_low", PROBES[4].text.replace("center 0 0 5 direction 0 0 -1",
                                               "center 1 -0.8 5 direction -0.2 0.1 -1"), bounces=2),
)


def scenes(tmp: Path, size: int = 30, course: Path | None = None) -> dict[str, tuple[object, RenderOptions]]:
    """The matrix's scenes: the five probes (a5mi/diagnose/probes.py) and :data:`VARIANTS`, each at ``size``, and with
    ``course`` (the course's ``scenes/`` folder) scene10_sphere."""
    out = {}
    if course is not None:
        from a5mi.render.session import describe_file

        out["scene10"] = (describe_file(str(course / "scene10_sphere.txt"))[0],
                          RenderOptions(width=size, height=size, shadows=True, jitter=True, filter=True))
    for probe in (*PROBES, *VARIANTS):
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
               pairs: list[tuple[str, str]] | None = None, course: Path | None = None) -> Figures:
    """The figures (module docstring) for ``mistakes``, ``n_pairs`` random pairs of them (or the given ``pairs``)
    and the correct renders."""
    from a5mi.diagnose.catalogue import BY_NAME, applicable, option_traits, scene_traits
    from a5mi.diagnose.rank import combinable
    from a5mi.render.session import RenderSession

    t0 = time.process_time()
    session = RenderSession()
    sc = scenes(tmp, course=course)
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
            fig.singles.append((m, name, top1, m in _names(d), d.verdict, d.causes[0].mistakes if d.causes else ()))
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
        for s in SEEDS if name in [p.name for p in PROBES] else ():
            d = diagnose(_image(session, desc, opts, (), s), desc, opts, session=session)
            fig.correct.append((name, s, d.verdict))
    fig.cpu = time.process_time() - t0
    return fig

"""Shrink a failing scene to a smallest reproducer (greedy delta debugging on the scene's parts).

A scene *fails* when its comparison's PSNR is below the threshold (or a side fails the same way). The
minimiser repeats, until nothing changes or the evaluation budget is spent, trying each of these edits and
keeping it whenever the edited scene still fails:

1. drop one top-level object (there must stay at least one);
2. drop one light (a scene without lights is a different scene: the binary forces ambient to 1);
3. drop one material no object uses, renumbering ``MaterialIndex`` (only at the top level of objects);
4. flags: ``-jitter`` off, ``-filter`` off, ``-shadows`` off, ``-bounces`` down to 0, then one less;
5. replace the cube-map background by its colour.

Every candidate is compared with the same :func:`~.runner.compare_scene` (both renderers), so the final
scene is one the two really disagree on.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

from a5mi.difftest.generate import GenScene, Obj
from a5mi.difftest.runner import Outcome

Check = Callable[[GenScene], Outcome]


@dataclass(frozen=True)
class Minimised:
    """The smallest failing scene found, its outcome, and how many comparisons it took."""

    scene: GenScene
    outcome: Outcome
    evaluations: int


def _renumber(obj: Obj, mapping: dict[int, int]) -> Obj:
    return replace(obj, material=mapping[obj.material])


def _nested_materials(obj: Obj) -> set[int]:
    return {int(m) for m in re.findall(r"MaterialIndex (\d+)", obj.text)}


def candidates(s: GenScene) -> Iterator[GenScene]:
    """Every one-step simplification of ``s`` (module docstring), simplest kinds first."""
    if len(s.objects) > 1:
        for i in range(len(s.objects)):
            yield replace(s, objects=s.objects[:i] + s.objects[i + 1:])
    if len(s.lights) > 1:
        for i in range(len(s.lights)):
            yield replace(s, lights=s.lights[:i] + s.lights[i + 1:])
    used = {o.material for o in s.objects} | {m for o in s.objects for m in _nested_materials(o)}
    nested = any(_nested_materials(o) for o in s.objects)
    if len(s.materials) > 1 and not nested:
        for i in range(len(s.materials)):
            if i not in used:
                mapping = {k: k - (k > i) for k in range(len(s.materials)) if k != i}
                yield replace(s, materials=s.materials[:i] + s.materials[i + 1:],
                              objects=tuple(_renumber(o, mapping) for o in s.objects))
    f = s.flags
    if f.jitter:
        yield s.with_flags(jitter=False)
    if f.filter:
        yield s.with_flags(filter=False)
    if f.shadows:
        yield s.with_flags(shadows=False)
    if f.bounces > 0:
        yield s.with_flags(bounces=0)
        if f.bounces > 1:
            yield s.with_flags(bounces=f.bounces - 1)
    if s.background_files:
        plain = "\n".join(line for line in s.background.splitlines() if "cubeMap" not in line)
        yield replace(s, background=plain, background_files=())


def minimise(scene: GenScene, check: Check, threshold: float, first: Outcome | None = None,
             budget: int = 80) -> Minimised:
    """The smallest variant of ``scene`` that still fails (``check(scene).worst < threshold``: the lowest PSNR
    of its images), within ``budget`` comparisons (module docstring)."""
    best, outcome = scene, first if first is not None else check(scene)
    n = 0 if first is not None else 1
    changed = True
    while changed and n < budget:
        changed = False
        for cand in candidates(best):
            if n >= budget:
                break
            n += 1
            out = check(cand)
            if out.status == outcome.status and out.worst < threshold:
                best, outcome, changed = cand, out, True
                break
    return Minimised(best, outcome, n)

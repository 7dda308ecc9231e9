"""The catalogue of the assignment's mistakes (docs/MISTAKES.md): each an exact change to SPEC's computation.

A :class:`Mistake` names the SPEC section it changes, the change (``change``, the formula as the student computes
it), the symptom a student sees, the layer that makes it on request (:data:`a5mi.render.options.MISTAKES` by layer) and
what a render needs for it to show (:data:`NEEDS`): ``-shadows``, a bounce budget, ``-jitter -filter``, or a scene
with mirrors, glass, marble, textures, a cube map, two lights, an ambient light. :func:`applicable` is the
cheap static test ``a5mi diagnose`` uses before it renders a mutant. The entries are data (:data:`SOURCE`,
``mistakes.tsv`` beside this module, read by :func:`read_catalogue`), in docs/MISTAKES.md's order.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from a5mi.render.options import (
    CAMERA_MISTAKES,
    FILTER_MISTAKES,
    IMAGE_MISTAKES,
    JITTER_MISTAKES,
    KERNEL_MISTAKES,
    MARBLE_MISTAKES,
    RenderOptions,
)

if TYPE_CHECKING:
    from a5mi.converters.describe import SceneDescription

#: What a render must have for a mistake to show: flags (``shadows``, ``bounces``, ``supersampling`` = -jitter
#: -filter) and scene content (``mirror``: a material with |specularColor| > 0.001, ``glass``: refractionIndex > 0,
#: ``marble``, ``texture``, ``pattern``: marble or texture, ``cubemap``, ``lights2``: two lights or more,
#: ``ambient``: a non-zero ambient light, ``narrow``: a field of view under 90 degrees, ``scaled``: some object's
#: placing matrix M is not orthonormal, ``nonuniform``: some object's M Mᵀ is not a multiple of I).
NEEDS: tuple[str, ...] = ("shadows", "bounces", "supersampling", "mirror", "glass", "marble", "texture", "pattern",
                          "cubemap", "lights2", "ambient", "narrow", "scaled", "nonuniform")


@dataclass(frozen=True)
class Mistake:
    """One catalogued mistake: ``name`` (the ``-mistake`` name), ``section`` (SPEC section changed), ``change`` (the
    student's computation, exactly), ``symptom`` (what the image shows), ``needs`` (:data:`NEEDS`)."""

    name: str
    section: str
    change: str
    symptom: str
    needs: tuple[str, ...] = ()

    @property
    def layer(self) -> str:
        """Which part of a5mi makes it: ``kernel``, ``marble``, ``camera``, ``jitter``, ``filter`` or ``image``."""
        for layer, names in LAYERS.items():
            if self.name in names:
                return layer
        raise KeyError(self.name)


LAYERS: dict[str, tuple[str, ...]] = {"kernel": KERNEL_MISTAKES, "marble": MARBLE_MISTAKES, "camera": CAMERA_MISTAKES,
                                      "jitter": JITTER_MISTAKES, "filter": FILTER_MISTAKES, "image": IMAGE_MISTAKES}

#: The catalogue's data (one mistake a line, tab-separated: name, section, change, symptom, needs), package data
#: beside this module, in docs/MISTAKES.md's order.
SOURCE = Path(__file__).with_name("mistakes.tsv")


def read_catalogue(text: str) -> tuple[Mistake, ...]:
    """The :class:`Mistake` of each data line of ``text`` (the format of :data:`SOURCE`: ``#`` lines are comments,
    the first other line names the columns ``name section change symptom needs``; ``needs`` is comma-separated,
    empty for any scene). ``ValueError`` on a line without five fields, a duplicate name, or a need not in
    :data:`NEEDS`."""
    rows = [ln.split("\t") for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    header, *data = rows
    if header != ["name", "section", "change", "symptom", "needs"]:
        raise ValueError(f"catalogue header {header}")
    out: dict[str, Mistake] = {}
    for row in data:
        if len(row) != 5 or row[0] in out:
            raise ValueError(f"catalogue line {row}: five tab-separated fields and a new name expected")
        name, section, change, symptom, needs = row
        wants = tuple(n for n in needs.split(",") if n)
        if not set(wants) <= set(NEEDS):
            raise ValueError(f"catalogue line {name}: needs {wants}, known {NEEDS}")
        out[name] = Mistake(name, section, change, symptom, wants)
    return tuple(out.values())


CATALOGUE: tuple[Mistake, ...] = read_catalogue(SOURCE.read_text(encoding="utf-8"))

#: The catalogue by name.
BY_NAME: dict[str, Mistake] = {m.name: m for m in CATALOGUE}


def scene_traits(desc: SceneDescription) -> set[str]:
    """The scene-content :data:`NEEDS` that ``desc`` has (``mirror``, ``glass``, ``marble``, ``texture``,
    ``cubemap``, ``lights2``, ``ambient``, ``narrow``, and by :func:`placing_traits` ``scaled``, ``nonuniform``)."""
    from a5mi.converters.describe import CubeMapBackground
    from a5mi.converters.files import Image
    from a5mi.converters.model import Noise

    traits: set[str] = set()
    for mat in desc.materials:
        if sum(float(c) ** 2 for c in mat.specular_color) ** 0.5 > 0.001:
            traits.add("mirror")
        if mat.refraction_index > 0.0:
            traits.add("glass")
        if isinstance(mat.kd, Noise):
            traits.update(("marble", "pattern"))
        elif isinstance(mat.kd, Image):
            traits.update(("texture", "pattern"))
    if isinstance(desc.background, CubeMapBackground):
        traits.add("cubemap")
    if len(desc.lights) >= 2:
        traits.add("lights2")
    if any(float(c) > 0.0 for c in desc.ambient):
        traits.add("ambient")
    if 0.0 < float(desc.camera.angle) < 90.0:
        traits.add("narrow")
    return traits | placing_traits(desc)


#: Relative tolerance of :func:`placing_traits` (the matrices are float32: a rotation's Gram matrix is I to ~1e-7).
PLACING_RTOL = 1e-5


def placing_traits(desc: SceneDescription) -> set[str]:
    """``scaled`` when some primitive's placing matrix ``M`` (SPEC A.6 Transform, upper 3x3) is not orthonormal,
    ``nonuniform`` when some ``M Mᵀ`` is not a multiple of I (docs/MISTAKES.md ``normal_not_normalised`` and
    ``normal_by_m`` change nothing otherwise). ``M`` as the a5 render holds it: a sphere's or plane's ``binary``
    matrix (inside a ``Transform``), a mesh's world-to-object ``A = M⁻¹`` (its octree rows; ``A Aᵀ = s⁻² I`` exactly
    when ``Mᵀ M = s² I``); a primitive without one is unplaced (``M = I``)."""
    from a5mi.converters.describe import MeshShape

    traits: set[str] = set()
    for shape in desc.shapes:
        if isinstance(shape, MeshShape):
            rows = shape.mesh.octree
            a = None if rows is None else np.asarray(rows[0, :9], dtype=np.float64).reshape(3, 3)
        else:
            a = None if shape.binary is None else np.asarray(shape.binary[0], dtype=np.float64)[:3, :3]
        if a is None:
            continue
        gram = a @ a.T
        s2 = float(np.trace(gram)) / 3.0
        if not np.allclose(gram, s2 * np.eye(3), rtol=0.0, atol=PLACING_RTOL * s2):
            traits.update(("scaled", "nonuniform"))
        elif abs(s2 - 1.0) > PLACING_RTOL:
            traits.add("scaled")
    return traits


def option_traits(options: RenderOptions) -> set[str]:
    """The flag :data:`NEEDS` that ``options`` has (``shadows``, ``bounces``, ``supersampling``)."""
    traits = set()
    if options.shadows:
        traits.add("shadows")
    if options.bounces > 0:
        traits.add("bounces")
    if options.jitter and options.filter:
        traits.add("supersampling")
    return traits


def applicable(traits: set[str]) -> list[Mistake]:
    """The mistakes whose :attr:`Mistake.needs` are all in ``traits`` (:func:`scene_traits` |
    :func:`option_traits`), in catalogue order. ``glass`` counts as ``mirror`` too (refraction needs a non-zero
    specularColor, SPEC B.3 notes)."""
    have = set(traits)
    if "glass" in have:
        have.add("mirror")
    return [m for m in CATALOGUE if set(m.needs) <= have]

"""Text and JSON of a :class:`~a5mi.trace.core.PixelTrace`, and the term that explains a student's pixel.

The text prints each node of the SPEC B.3 ray tree as the kernel computed it::

    #k KIND ray  o (...)  d (...)  tmin T  medium n  weight w  bounces left b
       hit t ..  p (...)  OBJECT at line L (material M, line L'), outside|inside, N (...)
       ambient ⊙ diffuseColor = a ⊙ dc = (...)
       light K (KIND at line L): L (...)  N·L ..  colour (...)  lit|blocked by OBJECT at line L (t ..)  -> (...)
       local (...)  contribution = weight ⊙ local = (...)
       Fresnel R ...; children: reflection weight (...), refraction weight (...)

then ``Σ contributions`` against the rendered sample (float and 8-bit). :func:`explain` ranks the terms of a
tree by how much of ``student - reference`` each one accounts for (a blocked light term the student adds, or
a term / child subtree of the reference the student lacks).

Noise: a pixel whose largest channel difference is at most :data:`DIFF_NOISE` levels (of 255) does not differ
(:func:`differs`): a correct renderer drawing other jitter samples or rounding floats otherwise lands there,
and nothing is named for it. A term is named only if it explains part of the difference: its residual must be
below the residual of the reference pixel itself, ``|student - reference|`` (an identical pixel has no
culprit).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from a5mi.platform.imageio import quantize
from a5mi.trace.core import PixelTrace
from a5mi.trace.tree import RayNode, RayTree, fresnel_text


def v3(v: Any, digits: int = 6) -> str:
    return "(" + ", ".join(f"{float(x):.{digits}g}" for x in v) + ")"


def _byte(v: Any) -> tuple[int, ...]:
    return tuple(int(b) for b in quantize(np.array(v, np.float32)).ravel()[:3])


def node_lines(tree: RayTree, node: RayNode, fresnel: str, ambient: Any) -> list[str]:
    """The lines of one node (module docstring), indented by its depth."""
    pad = "  " * node.depth
    lines = [f"{pad}#{node.index} {node.kind} ray  o {v3(node.o)}  d {v3(node.d)}  tmin {node.tmin:g}  "
             f"medium {node.n_medium:g}  weight {v3(node.weight)}  bounces left {int(node.bounces)}"]
    pad += "   "
    if not node.is_hit:
        lines.append(f"{pad}miss: background {v3(node.background)}  contribution = weight ⊙ background = "
                     f"{v3(node.contribution)}")
        return lines
    obj = node.obj
    where = f"{obj} (material {obj.material}, line {obj.material_line})" if obj else "an object outside the scene file"
    lines.append(f"{pad}hit t {node.t:.7g}  p {v3(node.p)}  {where}, {'inside' if node.inside else 'outside'}, "
                 f"N {v3(node.n)}" + (f", uv {v3(node.uv)}" if obj and obj.kind == "TriangleMesh" else ""))
    lines.append(f"{pad}ambient ⊙ diffuseColor = {v3(ambient)} ⊙ {v3(node.diffuse_color)} = {v3(node.ambient_term)}"
                 + (f"  (kd {v3(node.kd)})" if node.kd != node.diffuse_color else ""))
    for lt in node.lights:
        if not lt.tested:
            shadow = "no shadow rays"
        elif lt.visible:
            shadow = "lit"
        else:
            occ = f"{lt.occluder} (t {lt.occluder_t:.6g})" if lt.occluder else "an object"
            shadow = f"blocked by {occ}"
        extra = f"  highlight {lt.highlight:.6g}" if lt.highlight else ""
        lines.append(f"{pad}light {lt.index} ({lt.name}): L {v3(lt.L)}  N·L {lt.n_dot_l:.6g}  colour "
                     f"{v3(lt.light_color)}  {shadow}{extra}  -> max(N·L,0) colour ⊙ kd = {v3(lt.term)}"
                     + ("" if lt.visible else " (not added)"))
    lines.append(f"{pad}local {v3(node.local)}  contribution = weight ⊙ local = {v3(node.contribution)}")
    kids = []
    if node.push_refl > 0.5:
        kids.append(f"reflection weight ⊙ specular ⊙ R = {v3(node.w_refl)}")
    if node.push_refr > 0.5:
        kids.append(f"refraction weight ⊙ specular ⊙ (1-R) = {v3(node.w_refr)}")
    if node.refractive > 0.5 or node.push_refr > 0.5:
        lines.append(f"{pad}Fresnel: {fresnel_text(node, fresnel)}")
    if kids:
        lines.append(f"{pad}children: " + "; ".join(kids) + f"  (subtree total {v3(tree.subtree(node.index))})")
    elif int(node.bounces) == 0 and np.linalg.norm(node.specular) > 0.001:
        lines.append(f"{pad}no children: no bounces left")
    return lines


def tree_lines(tree: RayTree, fresnel: str, ambient: Any) -> list[str]:
    out: list[str] = []
    for node in tree.nodes:
        out.extend(node_lines(tree, node, fresnel, ambient))
    if tree.cut:
        out.append(f"(tree cut after {len(tree.nodes)} nodes)")
    return out


def format_trace(pt: PixelTrace, ambient: Any, sample: int | None = None) -> str:
    """The whole report of one pixel (``sample``: only that sub-sample's tree)."""
    o = pt.options
    gw, gh = pt.grid
    rw, rh = o.render_size
    lines = [f"pixel ({pt.x}, {pt.y}) from the top-left = ({pt.x}, {gh - 1 - pt.y}) from the bottom-left of the "
             f"{gw}x{gh} image; render buffer {rw}x{rh}"]
    n_block = len(pt.block)
    shown = range(n_block) if sample is None else [sample]
    for k in shown:
        (i, j), tree = pt.samples[k], pt.trees[k]
        head = f"sample {k}: " if n_block > 1 else ""
        lines.append("")
        lines.append(f"{head}render-buffer sample (i {i}, j {j}) (j from the bottom), camera ray through x_pix "
                     f"{pt.x_pix[k]:.9g}, y_pix {pt.y_pix[k]:.9g}" + ("  (glibc jitter)" if o.jitter else ""))
        lines.extend(tree_lines(tree, o.fresnel, ambient))
        s = tree.contribution_sum()
        r = np.array(pt.rendered[k], np.float32)
        ok = "equal" if np.array_equal(s, r) else f"DIFFER by {float(np.max(np.abs(s - r))):.3g}"
        lines.append(f"sum of contributions {v3(s, 9)} = rendered sample {v3(r, 9)}, 8-bit {_byte(s)} vs "
                     f"{_byte(r)}: {ok}")
    if pt.weights:
        lines.append("")
        lines.append(f"-filter (SPEC B.5): {len(pt.weights)} samples feed this pixel; w = (1/9) Σ_block K[a]K[b]:")
        for (i, j), w in sorted(pt.weights.items(), key=lambda kv: (-kv[1], kv[0])):
            k = pt.samples.index((i, j))
            lines.append(f"  (i {i}, j {j}) w {w:.6f}  value {v3(pt.rendered[k])}")
        lines.append(f"blurred, downsampled value Σ w c = {v3(pt.value, 9)}; image pixel {v3(pt.image_value, 9)} "
                     f"(|diff| {pt.value_error:.2g}), 8-bit {pt.value_byte} vs {pt.image_byte}")
    elif n_block > 1:
        lines.append(f"-jitter alone saves the {rw}x{rh} buffer: each sample above is one saved pixel")
    else:
        ok = "equal" if pt.max_error == 0.0 and pt.value_byte == pt.image_byte else "DIFFER"
        lines.append(f"image pixel {v3(pt.image_value, 9)}, 8-bit {pt.image_byte}: {ok}")
    return "\n".join(lines)


def _node_json(tree: RayTree, node: RayNode) -> dict[str, Any]:
    out = {"index": node.index, "kind": node.kind, "parent": node.parent, "depth": node.depth,
           "object": None if node.obj is None else vars(node.obj), "inside": node.inside,
           "ambient_term": node.ambient_term, "children": node.children,
           "subtree": [float(x) for x in tree.subtree(node.index)], **node.values}
    out["lights"] = [{**{k: v for k, v in vars(lt).items() if k != "occluder"},
                      "occluder": None if lt.occluder is None else vars(lt.occluder)} for lt in node.lights]
    return out


def trace_json(pt: PixelTrace) -> dict[str, Any]:
    """A JSON-ready dict of the whole trace (every recorded field of every node)."""
    return {
        "pixel": [pt.x, pt.y], "pixel_bottom_left": [pt.x, pt.grid[1] - 1 - pt.y], "grid": list(pt.grid),
        "render_size": list(pt.options.render_size), "fresnel": pt.options.fresnel,
        "samples": [{"i": i, "j": j, "x_pix": xp, "y_pix": yp, "rendered": list(r),
                     "sum": [float(x) for x in t.contribution_sum()], "cut": t.cut,
                     "weight": pt.weights.get((i, j)),
                     "nodes": [_node_json(t, n) for n in t.nodes]}
                    for (i, j), xp, yp, t, r in zip(pt.samples, pt.x_pix, pt.y_pix, pt.trees, pt.rendered,
                                                    strict=True)],
        "value": list(pt.value), "image_value": list(pt.image_value), "image_byte": list(pt.image_byte),
        "max_error": pt.max_error,
    }


def dumps(obj: Any) -> str:
    def default(x: Any) -> Any:
        if isinstance(x, (np.floating, np.integer)):
            return x.item()
        raise TypeError(type(x).__name__)

    return json.dumps(obj, default=default, allow_nan=True)


# ------------------------------------------------------------------------------------------------ --diff
#: Largest per-channel difference, in levels of 255, that ``trace --diff`` takes as noise (module docstring).
DIFF_NOISE = 2


def differs(error_levels: float) -> bool:
    """A pixel differs when its largest channel difference exceeds :data:`DIFF_NOISE` levels."""
    return float(error_levels) > DIFF_NOISE

@dataclass(frozen=True)
class Term:
    """A candidate explanation: ``value`` (RGB, already times the path weight) enters the student's pixel
    with ``sign`` (+1: the reference blocked or dropped it and the student has it; -1: the reference has it
    and the student lacks it)."""

    label: str
    kind: str          # shadow, light, ambient, reflection, refraction, background
    value: tuple[float, float, float]
    sign: int
    node: int


def candidate_terms(tree: RayTree) -> list[Term]:
    """Every term of a tree a wrong implementation could drop or add (SPEC B.3)."""
    out: list[Term] = []
    for node in tree.nodes:
        w = np.array(node.weight)
        at = f"node #{node.index} ({node.kind} ray)"
        if not node.is_hit:
            out.append(Term(f"background of {at}", "background", tuple(w * node.background), -1, node.index))
            continue
        out.append(Term(f"ambient term of {at}", "ambient", tuple(w * np.array(node.ambient_term)), -1, node.index))
        for lt in node.lights:
            val = tuple(w * np.array(lt.term))
            if lt.tested and not lt.visible:
                occ = f"{lt.occluder}" if lt.occluder else "an object"
                out.append(Term(f"shadow term of light {lt.index} at {at}: reference blocked by {occ}",
                                "shadow", val, +1, node.index))
            else:
                out.append(Term(f"light {lt.index} term at {at} (reference: lit, N·L {lt.n_dot_l:.3g})",
                                "light", val, -1, node.index))
        for child in node.children:
            kid = tree.nodes[child]
            out.append(Term(f"{kid.kind} term of {at} (child #{child}, weight {v3(kid.weight, 3)})", kid.kind,
                            tuple(tree.subtree(child)), -1, node.index))
    return out


def pixel_terms(pt: PixelTrace) -> list[Term]:
    """The candidate terms of a pixel: one tree's, or with ``-filter`` every feeding sample's terms times its
    filter weight, equal labels summed (neighbouring samples usually share their tree's shape)."""
    if not pt.weights:
        return candidate_terms(pt.trees[0])
    acc: dict[tuple[str, int], Term] = {}
    for (i, j), tree in zip(pt.samples, pt.trees, strict=True):
        w = pt.weights.get((i, j), 0.0)
        for t in candidate_terms(tree):
            key = (t.label, t.sign)
            v = np.array(t.value) * w
            if key in acc:
                v = v + np.array(acc[key].value)
            acc[key] = Term(t.label, t.kind, tuple(v), t.sign, t.node)
    return list(acc.values())


def _aggregates(terms: list[Term]) -> list[Term]:
    """One extra candidate per kind of light term with several members: all of them together (a student who
    skips every shadow test adds every blocked term at once), labelled by its largest member. Child subtrees
    need no aggregate: the camera ray's children already hold everything below them."""
    out = []
    for kind in ("shadow", "light"):
        members = [t for t in terms if t.kind == kind]
        if len(members) < 2:
            continue
        total = np.sum([np.array(t.value) for t in members], axis=0)
        big = max(members, key=lambda t: float(np.linalg.norm(t.value)))
        out.append(Term(f"all {len(members)} {kind} terms together, the largest: {big.label}", kind, tuple(total),
                        members[0].sign, big.node))
    return out


def explain(pt: PixelTrace, student: Any) -> list[tuple[Term, float]]:
    """Terms ranked by how well the reference with that term changed, ``clamp(reference + sign · value, 0,
    1)``, matches the student's pixel (float, /255, so saturated pixels compare fairly): the residual
    ``|student - clamp(...)|`` (smallest first; ties: the larger term). Only terms whose residual is below
    ``|student - reference|`` are listed (module docstring): empty for an identical pixel."""
    student = np.asarray(student, np.float64)
    ref = np.asarray(pt.value, np.float64)
    base = float(np.linalg.norm(student - np.clip(ref, 0.0, 1.0)))
    terms = pixel_terms(pt)
    scored = []
    for term in terms + _aggregates(terms):
        v = np.array(term.value)
        if not np.any(v):
            continue
        predicted = np.clip(ref + term.sign * v, 0.0, 1.0)
        residual = float(np.linalg.norm(student - predicted))
        if residual < base:
            scored.append((term, residual, -float(np.linalg.norm(v))))
    scored.sort(key=lambda s: (s[1], s[2]))
    return [(t, r) for t, r, _ in scored]

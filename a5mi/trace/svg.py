"""``a5mi trace --svg``: a diagram of one ray tree (SPEC B.3) as a standalone SVG, standard library only.

Layout: depth downwards, leaves left to right in the kernel's depth-first order, each parent centred over its
children. A node box shows its number and ray kind, what it hit (object and scene line, or "miss"), its local
colour and its contribution (with a swatch of the contribution, clamped to [0, 1]); an edge is labelled with
the child's ray kind and the weight handed to it (``w ⊙ specularColor ⊙ R`` or ``⊙ (1 - R)``).
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from a5mi.platform.imageio import atomic_file
from a5mi.trace.tree import RayTree

BOX_W, BOX_H, GAP_X, GAP_Y, MARGIN = 250, 84, 20, 70, 20


def _v(v: object) -> str:
    return "(" + ", ".join(f"{float(x):.4g}" for x in v) + ")"  # type: ignore[union-attr]


def _rgb(v: object) -> str:
    c = np.clip(np.array(v, np.float64), 0.0, 1.0)
    return "#" + "".join(f"{int(round(x * 255)):02x}" for x in c)


def layout(tree: RayTree) -> dict[int, tuple[float, float]]:
    """Top-left corner of each node's box."""
    pos: dict[int, tuple[float, float]] = {}
    next_x = [0.0]

    def place(k: int) -> float:
        node = tree.nodes[k]
        if not node.children:
            x = next_x[0]
            next_x[0] += BOX_W + GAP_X
        else:
            xs = [place(c) for c in node.children]
            x = (min(xs) + max(xs)) / 2.0
        pos[k] = (MARGIN + x, MARGIN + node.depth * (BOX_H + GAP_Y))
        return x

    if tree.nodes:
        place(0)
    return pos


def tree_svg(tree: RayTree, title: str) -> str:
    """The SVG document of ``tree`` (module docstring)."""
    pos = layout(tree)
    width = max((x for x, _ in pos.values()), default=0) + BOX_W + MARGIN
    height = max((y for _, y in pos.values()), default=0) + BOX_H + MARGIN + 30
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
           f'font-family="monospace" font-size="11">',
           f'<title>{escape(title)}</title>',
           f'<text x="{MARGIN}" y="{height - 12:.0f}">{escape(title)}; sum of contributions '
           f'{_v(tree.contribution_sum())}</text>']
    for node in tree.nodes:
        if node.parent is None:
            continue
        px, py = pos[node.parent]
        cx, cy = pos[node.index]
        x1, y1, x2, y2 = px + BOX_W / 2, py + BOX_H, cx + BOX_W / 2, cy
        weight = node.weight
        out.append(f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" stroke="#555"/>')
        out.append(f'<text x="{(x1 + x2) / 2 + 4:.1f}" y="{(y1 + y2) / 2:.1f}" fill="#225">'
                   f'{escape(node.kind)} w {_v(weight)}</text>')
    for node in tree.nodes:
        x, y = pos[node.index]
        hit = f"{node.obj}" if node.is_hit and node.obj else ("hit" if node.is_hit else "miss (background)")
        side = (" inside" if node.inside else " outside") if node.is_hit else ""
        lines = [f"#{node.index} {node.kind} ray, t {node.t:.5g}" if node.is_hit else f"#{node.index} {node.kind} ray",
                 hit + side,
                 f"local {_v(node.local if node.is_hit else node.background)}",
                 f"contribution {_v(node.contribution)}"]
        if node.refractive > 0.5:
            lines.append(f"R {node.r_fresnel:.5g}")
        out.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{BOX_W}" height="{BOX_H}" rx="6" fill="#f8f8f8" '
                   f'stroke="#333"/>')
        out.append(f'<rect x="{x + BOX_W - 22:.1f}" y="{y + 6:.1f}" width="16" height="16" '
                   f'fill="{_rgb(node.contribution)}" stroke="#333"/>')
        for k, text in enumerate(lines):
            out.append(f'<text x="{x + 6:.1f}" y="{y + 16 + 15 * k:.1f}">{escape(text)}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def write_svg(path: str | Path, tree: RayTree, title: str) -> None:
    """Write :func:`tree_svg` atomically (never a half-written file)."""
    with atomic_file(path, "w") as fh:
        fh.write(tree_svg(tree, title))

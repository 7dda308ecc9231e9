"""Write ``scenes/meshes/tube.obj``: an open metal cylinder for the ring caustic (docs/EXTENSIONS.md E.16).

    python scenes/make_tube.py

Radius 1 about the y axis, y in [0, 0.6], no caps, 64 segments: 128 vertices (> 120, so SPEC A.6's smooth,
area-weighted vertex normals), 128 triangles, wound outward.
"""

from __future__ import annotations

import math
from pathlib import Path

SEGMENTS, RADIUS, HEIGHT = 64, 1.0, 0.6


def tube_obj() -> str:
    lines = ["# open cylinder, scenes/make_tube.py"]
    for y in (0.0, HEIGHT):
        for i in range(SEGMENTS):
            a = 2.0 * math.pi * i / SEGMENTS
            lines.append(f"v {RADIUS * math.cos(a):.6f} {y:.6f} {RADIUS * math.sin(a):.6f}")
    for i in range(SEGMENTS):
        j = (i + 1) % SEGMENTS
        b0, b1, t0, t1 = i + 1, j + 1, i + 1 + SEGMENTS, j + 1 + SEGMENTS
        lines.append(f"f {b0} {t0} {b1}")
        lines.append(f"f {b1} {t0} {t1}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    Path(__file__).with_name("meshes").joinpath("tube.obj").write_text(tube_obj())

"""Write the meshes of the photon-mapping demos (docs/EXTENSIONS.md E.16).

    python scenes/make_tube.py

* ``scenes/meshes/tube.obj``: an open metal cylinder for the ring caustic: radius 1 about the y axis, y in
  [0, 0.6], no caps, 64 segments: 128 vertices (> 120, so SPEC A.6's smooth, area-weighted vertex normals),
  128 triangles, wound outward.
* ``scenes/meshes/column.obj``: a closed cylinder, the water of a glass of water: radius 1, y in [0, 1], 64
  segments; the caps have their own rim vertices (so the smooth normals of the side and the flat ones of the
  caps do not mix): 258 vertices, 256 triangles, wound outward.
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


def column_obj() -> str:
    lines = ["# closed cylinder, scenes/make_tube.py"]
    ring = [(math.cos(2.0 * math.pi * i / SEGMENTS), math.sin(2.0 * math.pi * i / SEGMENTS)) for i in range(SEGMENTS)]
    for y in (0.0, 1.0, 0.0, 1.0):          # side bottom, side top, cap bottom, cap top
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, z in ring]
    lines += ["v 0 0 0", "v 0 1 0"]
    n = SEGMENTS
    centre_bottom, centre_top = 4 * n + 1, 4 * n + 2
    for i in range(n):
        j = (i + 1) % n
        lines.append(f"f {i + 1} {i + 1 + n} {j + 1}")
        lines.append(f"f {j + 1} {i + 1 + n} {j + 1 + n}")
        lines.append(f"f {centre_bottom} {i + 1 + 2 * n} {j + 1 + 2 * n}")
        lines.append(f"f {centre_top} {j + 1 + 3 * n} {i + 1 + 3 * n}")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    meshes = Path(__file__).with_name("meshes")
    meshes.joinpath("tube.obj").write_text(tube_obj())
    meshes.joinpath("column.obj").write_text(column_obj())

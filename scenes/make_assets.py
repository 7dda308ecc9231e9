"""Generate the meshes, textures and cube map of the project's own scenes (ours, no third-party data).

    python scenes/make_assets.py        # rewrites scenes/meshes/*.obj, scenes/tex/*.bmp, scenes/sky/*.bmp

* ``box.obj``: the unit cube [-1, 1]^3, 8 vertices, 12 triangles, outward winding (flat-shaded: <= 120
  vertices, SPEC A.6).
* ``icosphere.obj``: an icosahedron subdivided twice and projected on the unit sphere, 162 vertices
  (> 120, so smooth area-weighted normals per SPEC A.6), with ``vt`` longitude/latitude coordinates.
* ``prism.obj``: an equilateral triangular prism (apex angles 60°), edges parallel to y, height 2 (y in
  [-1, 1]), cross-section vertices at unit distance from the y axis, one at +x; 6 vertices, 8 triangles, outward
  winding (flat-shaded). The Newton prism of ``scenes/prism.txt`` (docs/EXTENSIONS.md E.10).
* ``tex/checker.bmp``: 64 x 64 24-bit BMP, 8 x 8 checks of two colours with a red/green gradient border, so
  orientation mistakes (flipped rows, swapped u/v) show.
* ``tile.obj``: the square [-1, 1]² in the plane y = 0, facing +y, uv (0, 0)..(1, 1) along +x and −z
  (docs/EXTENSIONS.md E.7 demo, ``scenes/bumps.txt``).
* ``tex/bumps.bmp``: 64 x 64 grey height field, a 4 x 4 grid of round domes (height 1 − (r/R)², R = 6 texels);
  ``tex/ripples.bmp``: 64 x 64 tangent-space normal map of the ripples h = sin(2π·3 (u + v)) / 12, encoded
  ``128 + 127 t`` (the E.7 decoding).
* ``volumes/cloud.vol``: a 24 x 24 x 24 Mitsuba ``.vol`` density grid (docs/EXTENSIONS.md E.9: ``VOL`` 3,
  float32, x fastest), three overlapping Gaussian puffs ``exp(-|x - c|²/(2 s²))``, summed and clamped to 1, so
  the ``Volume`` of ``scenes/volume.txt`` shows a varying density.
* ``tex/btf/silk_I_J.bmp``: a 16 x 16 view-dependent "shot silk" (docs/EXTENSIONS.md E.19, ``scenes/btf.txt``),
  one image per view elevation ``BTF_ELEVATIONS[I]`` and azimuth ``BTF_AZIMUTHS[J]``: a 4 x 4 weave of red warp
  (along u) and blue weft threads whose visible share follows the view, ``w = 0.5 + 0.45 sin θ cos φ`` of the
  warp's colour, the other threads darkened by ``1 − 0.5 sin θ``.
* ``sky/{left,right,up,down,front,back}.bmp``: a 32 x 32 cube map, each face its own hue with a vertical
  gradient and a dark mark in its top-left corner (SPEC A.4's face/uv table is visible in a render).
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

ROOT = Path(__file__).resolve().parent
HERE = ROOT / "meshes"


def box() -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int]]]:
    v = [(x, y, z) for z in (-1.0, 1.0) for y in (-1.0, 1.0) for x in (-1.0, 1.0)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = []
    for a, b, c, d in quads:
        faces += [(a, b, c), (a, c, d)]
    return v, faces


def icosphere(levels: int = 2) -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int]]]:
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [_unit(p) for p in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        cache: dict[tuple[int, int], int] = {}
        new = []
        for a, b, c in faces:
            ab, bc, ca = (_midpoint(verts, cache, i, j) for i, j in ((a, b), (b, c), (c, a)))
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return verts, faces


def prism() -> tuple[list[tuple[float, float, float]], list[tuple[int, int, int]]]:
    ring = [(math.cos(a), math.sin(a)) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]   # (x, z)
    verts = [(x, y, z) for y in (-1.0, 1.0) for x, z in ring]
    faces = [(0, 2, 1), (3, 4, 5)]                                  # caps
    for i in range(3):
        j = (i + 1) % 3
        faces += [(i, i + 3, j + 3), (i, j + 3, j)]                 # side quad i -> j
    return verts, [_outward(verts, f) for f in faces]


def _outward(verts: list, face: tuple[int, int, int]) -> tuple[int, int, int]:
    """``face`` wound so that ``(v1 - v0) x (v2 - v0)`` points away from the origin (the solid's centre)."""
    a, b, c = (verts[i] for i in face)
    e1 = [b[k] - a[k] for k in range(3)]
    e2 = [c[k] - a[k] for k in range(3)]
    n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
    centroid = [(a[k] + b[k] + c[k]) / 3 for k in range(3)]
    return face if sum(n[k] * centroid[k] for k in range(3)) > 0 else (face[0], face[2], face[1])


def _midpoint(verts: list, cache: dict[tuple[int, int], int], a: int, b: int) -> int:
    """Index of the unit-sphere midpoint of edge (a, b), created once per edge."""
    key = (min(a, b), max(a, b))
    if key not in cache:
        pa, pb = verts[a], verts[b]
        verts.append(_unit(tuple((x + y) / 2 for x, y in zip(pa, pb, strict=True))))
        cache[key] = len(verts) - 1
    return cache[key]


def _unit(p: tuple[float, ...]) -> tuple[float, float, float]:
    n = math.sqrt(sum(x * x for x in p))
    return (p[0] / n, p[1] / n, p[2] / n)


def write_obj(path: Path, verts, faces, with_uv: bool = False) -> None:
    lines = [f"# {path.name}: generated by scenes/make_meshes.py for the a5mi demo scenes"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    if with_uv:
        for x, y, z in verts:
            u = 0.5 + math.atan2(x, z) / (2 * math.pi)
            v = 0.5 + math.asin(max(-1.0, min(1.0, y))) / math.pi
            lines.append(f"vt {u:.6f} {v:.6f}")
        lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in faces]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def write_bmp(path: Path, rows: list[list[tuple[int, int, int]]]) -> None:
    """A 24-bit uncompressed BMP; ``rows[0]`` is the top row of the image (BMP stores bottom-up)."""
    import struct

    h, w = len(rows), len(rows[0])
    stride = (3 * w + 3) & ~3
    data = bytearray()
    for row in reversed(rows):
        line = bytearray()
        for r, g, b in row:
            line += bytes((b, g, r))
        data += line + bytes(stride - len(line))
    header = struct.pack("<2sIHHI", b"BM", 54 + len(data), 0, 0, 54)
    info = struct.pack("<IiiHHIIiiII", 40, w, h, 1, 24, 0, len(data), 2835, 2835, 0, 0)
    path.write_bytes(header + info + bytes(data))


def checker(n: int = 64, checks: int = 8) -> list[list[tuple[int, int, int]]]:
    rows = []
    for y in range(n):
        row = []
        for x in range(n):
            if x < 2 or y < 2 or x >= n - 2 or y >= n - 2:
                row.append((255 * x // (n - 1), 255 * y // (n - 1), 40))
            elif ((x * checks // n) + (y * checks // n)) % 2:
                row.append((235, 225, 200))
            else:
                row.append((40, 60, 110))
        rows.append(row)
    return rows


SKY_HUES = {"right": (230, 120, 90), "left": (90, 200, 120), "up": (150, 190, 255),
            "down": (120, 100, 80), "front": (200, 180, 240), "back": (240, 220, 120)}


def sky_face(colour: tuple[int, int, int], n: int = 32) -> list[list[tuple[int, int, int]]]:
    rows = []
    for y in range(n):
        k = 0.55 + 0.45 * (1 - y / (n - 1))
        row = [tuple(int(c * k) for c in colour) for _ in range(n)]
        rows.append(row)
    for y in range(4):
        for x in range(4):
            rows[y][x] = (20, 20, 20)
    return rows  # type: ignore[return-value]


def tile() -> tuple[str, ...]:
    """The uv-mapped square of the module docstring, as OBJ lines (v, vt, two faces)."""
    return ("# tile.obj: generated by scenes/make_assets.py for the a5mi demo scenes",
            "v -1 0 1", "v 1 0 1", "v 1 0 -1", "v -1 0 -1",
            "vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1",
            "f 1/1 2/2 3/3", "f 1/1 3/3 4/4")


def domes(n: int = 64, cells: int = 4, radius: float = 6.0) -> list[list[tuple[int, int, int]]]:
    """Grey height field of round domes, rows top to bottom (module docstring)."""
    size = n / cells
    rows = []
    for j in range(n):
        row = []
        for i in range(n):
            dx = (i + 0.5) % size - size / 2
            dy = (j + 0.5) % size - size / 2
            h = max(0.0, 1.0 - (dx * dx + dy * dy) / (radius * radius))
            g = round(255 * h)
            row.append((g, g, g))
        rows.append(row)
    return rows


def ripples(n: int = 64, waves: int = 3, amp: float = 1.0 / 12.0) -> list[list[tuple[int, int, int]]]:
    """Tangent-space normal map of h = amp sin(2π waves (u + v)): t ∝ (−h_u, −h_v, 1), bytes 128 + 127 t."""
    rows = []
    for j in range(n):
        v = 1.0 - (j + 0.5) / n
        row = []
        for i in range(n):
            u = (i + 0.5) / n
            d = amp * 2 * math.pi * waves * math.cos(2 * math.pi * waves * (u + v))
            t = (-d, -d, 1.0)
            norm = math.sqrt(sum(c * c for c in t))
            row.append(tuple(max(0, min(255, round(128 + 127 * c / norm))) for c in t))
        rows.append(row)
    return rows  # type: ignore[return-value]


#: The puffs of ``cloud.vol``: centre (unit cube) and standard deviation.
PUFFS = (((0.35, 0.45, 0.5), 0.16), ((0.62, 0.55, 0.45), 0.14), ((0.5, 0.35, 0.6), 0.12))


def cloud(n: int = 24) -> list[float]:
    """Density of ``cloud.vol`` at the cell centres ``((i + ½)/n, ...)``, x fastest (E.9 order)."""
    values = []
    for z in range(n):
        for y in range(n):
            for x in range(n):
                p = ((x + 0.5) / n, (y + 0.5) / n, (z + 0.5) / n)
                d = sum(math.exp(-sum((a - b) ** 2 for a, b in zip(p, c, strict=True)) / (2 * s * s))
                        for c, s in PUFFS)
                values.append(min(1.0, d))
    return values


BTF_ELEVATIONS = (0.0, 30.0, 60.0)
BTF_AZIMUTHS = (0.0, 90.0, 180.0, 270.0)


def silk(theta: float, phi: float, n: int = 16) -> list[list[tuple[int, int, int]]]:
    """The shot-silk image seen from ``theta``, ``phi`` (degrees; module docstring)."""
    st, cp = math.sin(math.radians(theta)), math.cos(math.radians(phi))
    w = 0.5 + 0.45 * st * cp
    warp, weft = (220, 40, 70), (40, 80, 230)
    mix = tuple(round(w * a + (1 - w) * b) for a, b in zip(warp, weft, strict=True))
    dark = 1.0 - 0.5 * st
    rows = []
    for y in range(n):
        row = []
        for x in range(n):
            over = ((x // 4) + (y // 4)) % 2 == 0           # the weave: warp over weft on half the cells
            base = mix if over else tuple(round(c * dark) for c in mix)
            row.append(base if (x % 4 and y % 4) else tuple(round(0.6 * c) for c in base))
        rows.append(row)
    return rows


def write_vol(path: Path, n: int, values: list[float]) -> None:
    """A Mitsuba ``.vol`` file (docs/EXTENSIONS.md E.9): ``VOL`` 3, encoding 1, n³ cells, 1 channel, the unit
    bounding box, float32 values."""
    head = b"VOL" + bytes([3]) + struct.pack("<iiiii6f", 1, n, n, n, 1, 0, 0, 0, 1, 1, 1)
    path.write_bytes(head + struct.pack(f"<{len(values)}f", *values))


if __name__ == "__main__":
    HERE.mkdir(exist_ok=True)
    write_obj(HERE / "box.obj", *box())
    write_obj(HERE / "icosphere.obj", *icosphere(2), with_uv=True)
    write_obj(HERE / "prism.obj", *prism())
    (ROOT / "tex").mkdir(exist_ok=True)
    write_bmp(ROOT / "tex" / "checker.bmp", checker())
    (HERE / "tile.obj").write_text("\n".join(tile()) + "\n")
    write_bmp(ROOT / "tex" / "bumps.bmp", domes())
    write_bmp(ROOT / "tex" / "ripples.bmp", ripples())
    (ROOT / "volumes").mkdir(exist_ok=True)
    write_vol(ROOT / "volumes" / "cloud.vol", 24, cloud(24))
    (ROOT / "tex" / "btf").mkdir(exist_ok=True)
    for i, theta in enumerate(BTF_ELEVATIONS):
        for j, phi in enumerate(BTF_AZIMUTHS):
            write_bmp(ROOT / "tex" / "btf" / f"silk_{i}_{j}.bmp", silk(theta, phi))
    (ROOT / "sky").mkdir(exist_ok=True)
    for face, colour in SKY_HUES.items():
        write_bmp(ROOT / "sky" / f"{face}.bmp", sky_face(colour))
    print("wrote meshes/ (box, icosphere, prism, tile), tex/*.bmp, tex/btf/, volumes/cloud.vol, sky/*.bmp under", ROOT)

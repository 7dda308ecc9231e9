"""Seeded random a5 scenes from the whole SPEC A grammar, as editable parts (for the minimiser).

:func:`random_scene` ``(seed, index)`` is reproducible: the same pair always gives the same text (Python's
``random.Random`` seeded with the string ``"seed:index"``). A scene draws, within bounds that keep a render
at ~100 x 100 pixels to about a second:

* a ``PerspectiveCamera`` 6-12 units from the origin looking near it (up not perpendicular, angle 25-50°);
* 1-3 lights: ``DirectionalLight`` (a quarter of them along an axis or with a zero component, the case of
  the binary's octree rule) and ``PointLight`` with and without ``falloff``;
* a ``Background`` with colour, ambient light (or none) and, one time in four, a course cube map;
* 1-4 materials (``Material`` or ``PhongMaterial``) with mirror ``specularColor``, glass
  (``refractionIndex`` 1.1-2.4), ``Noise`` marble or a ``texture`` (with the course's textured meshes);
* 1-4 objects: spheres, planes at any orientation, triangles, the course meshes (cube, diamond, bunny_200,
  bunny_1k, vase, the last two a third as often; the textured c1-c3; each placed by a random ``Translate``),
  a nested ``Group``, each possibly inside a ``Transform`` of
  ``Translate``, ``Scale``, ``UniformScale``, ``X/Y/ZRotate``, ``Rotate`` and ``Matrix4f`` (shears);
* flags: ``-shadows`` (70%), ``-bounces 0..8``, ``-jitter`` (20%), ``-filter`` (30%).

The binary asserts on non-square images, so sizes are square.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field, replace

MESHES = ("cube.obj", "diamond.obj", "bunny_200.obj", "bunny_1k.obj", "vase.obj")
UV_MESHES = ("tex/c1.obj", "tex/c2.obj", "tex/c3.obj")
#: A uniform scale and a translation that bring each course mesh to about 2 units around the origin.
MESH_FIT = {"cube.obj": (0.7, (0, 0, 0)), "diamond.obj": (0.5, (0, 0, 0)), "bunny_200.obj": (7, (0, -1.5, 0)),
            "bunny_1k.obj": (7, (0, -1.5, 0)), "vase.obj": (0.25, (0, -1, 0)), "tex/c1.obj": (2, (0, -1.5, 0)),
            "tex/c2.obj": (2, (0, -2.7, 0)), "tex/c3.obj": (2, (0, -0.3, 0))}
TEXTURES = ("tex/head.bmp", "tex/body.bmp", "tex/feet.bmp", "tex/char.bmp", "tex/chicken.bmp")
CUBE_MAPS = ("tex/church", "tex/church2")


def fmt(x: float) -> str:
    """A number as the scene text writes it: at most 3 decimals, no exponent, never ``-0``."""
    s = f"{x:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def v3(v: tuple[float, ...] | list[float]) -> str:
    return " ".join(fmt(x) for x in v)


@dataclass(frozen=True)
class Flags:
    """The render flags of a scene (SPEC B.1)."""

    size: int = 100
    shadows: bool = False
    bounces: int = 4
    jitter: bool = False
    filter: bool = False

    def argv(self) -> list[str]:
        """The a5 command-line flags (without ``-input`` / ``-output``)."""
        out = ["-size", str(self.size), str(self.size), "-bounces", str(self.bounces)]
        out += ["-shadows"] * self.shadows + ["-jitter"] * self.jitter + ["-filter"] * self.filter
        return out


@dataclass(frozen=True)
class Obj:
    """One top-level object: its material index and its text (which may be a Transform or Group)."""

    material: int
    text: str
    files: tuple[str, ...] = ()


@dataclass(frozen=True)
class GenScene:
    """A scene as parts; :meth:`text` writes it, :attr:`files` are the course files it names."""

    camera: str
    lights: tuple[str, ...]
    background: str
    materials: tuple[tuple[str, tuple[str, ...]], ...]  # (text, files)
    objects: tuple[Obj, ...]
    flags: Flags = field(default_factory=Flags)
    background_files: tuple[str, ...] = ()

    @property
    def files(self) -> tuple[str, ...]:
        out = list(self.background_files)
        for _, f in self.materials:
            out += f
        for o in self.objects:
            out += o.files
        return tuple(dict.fromkeys(out))

    def text(self) -> str:
        lights = "\n".join(self.lights)
        mats = "\n".join(m for m, _ in self.materials)
        objs = "\n".join(f"  MaterialIndex {o.material}\n{o.text}" for o in self.objects)
        return (f"{self.camera}\n\nLights {{\n  numLights {len(self.lights)}\n{lights}\n}}\n\n{self.background}\n\n"
                f"Materials {{\n  numMaterials {len(self.materials)}\n{mats}\n}}\n\n"
                f"Group {{\n  numObjects {len(self.objects)}\n{objs}\n}}\n")

    def with_flags(self, **kw: object) -> GenScene:
        return replace(self, flags=replace(self.flags, **kw))  # type: ignore[arg-type]


class _Gen:
    def __init__(self, rng: random.Random) -> None:
        self.r = rng

    def u(self, a: float, b: float) -> float:
        return self.r.uniform(a, b)

    def color(self, lo: float = 0.0, hi: float = 1.0) -> list[float]:
        return [self.u(lo, hi) for _ in range(3)]

    def direction(self) -> list[float]:
        r = self.r.random()
        if r < 0.12:  # along an axis
            d = [0.0, 0.0, 0.0]
            d[self.r.randrange(3)] = self.r.choice((-1.0, 1.0))
            return d
        d = [self.u(-1, 1), self.u(-1, -0.2), self.u(-1, 1)]
        if r < 0.25:  # one zero component
            d[self.r.choice((0, 2))] = 0.0
        return d

    def camera(self) -> str:
        dist = self.u(6, 12)
        az, el = self.u(-0.8, 0.8), self.u(-0.1, 0.6)
        import math

        c = [dist * math.sin(az) * math.cos(el), dist * math.sin(el), dist * math.cos(az) * math.cos(el)]
        target = [self.u(-0.5, 0.5) for _ in range(3)]
        d = [t - x for t, x in zip(target, c, strict=True)]
        up = [self.u(-0.2, 0.2), 1.0, self.u(-0.2, 0.2)]
        return (f"PerspectiveCamera {{\n  center {v3(c)}\n  direction {v3(d)}\n  up {v3(up)}\n"
                f"  angle {fmt(self.u(25, 50))}\n}}")

    def light(self) -> str:
        if self.r.random() < 0.5:
            return (f"  DirectionalLight {{\n    direction {v3(self.direction())}\n"
                    f"    color {v3(self.color(0.2, 0.9))}\n  }}")
        pos = [self.u(-5, 5), self.u(1, 6), self.u(-5, 5)]
        fall = self.r.choice(("", "", "    falloff 0\n", f"    falloff {fmt(self.u(0.01, 0.2))}\n"))
        return f"  PointLight {{\n    position {v3(pos)}\n    color {v3(self.color(0.3, 1.0))}\n{fall}  }}"

    def background(self) -> tuple[str, tuple[str, ...]]:
        parts = [f"  color {v3(self.color())}"]
        if self.r.random() < 0.7:
            parts.append(f"  ambientLight {v3(self.color(0, 0.3))}")
        files: tuple[str, ...] = ()
        if self.r.random() < 0.25:
            cm = self.r.choice(CUBE_MAPS)
            parts.append(f"  cubeMap {cm}")
            files = (cm,)
        self.r.shuffle(parts)
        return "Background {\n" + "\n".join(parts) + "\n}", files

    def material(self) -> tuple[str, tuple[str, ...], bool]:
        lines = [f"    diffuseColor {v3(self.color(0.05, 1))}"]
        files: tuple[str, ...] = ()
        if self.r.random() < 0.5:
            lines.append(f"    specularColor {v3(self.color(0, 0.9))}")
        if self.r.random() < 0.3:
            lines.append(f"    shininess {fmt(self.u(1, 60))}")
        glass = self.r.random() < 0.25
        if glass:
            lines.append(f"    refractionIndex {fmt(self.u(1.1, 2.4))}")
            if not any(x.strip().startswith("specularColor") for x in lines):
                lines.append(f"    specularColor {v3(self.color(0.3, 0.9))}")
        r = self.r.random()
        if r < 0.2:
            lines.append(f"    Noise {{\n      color {v3(self.color())}\n      color {v3(self.color())}\n"
                         f"      octaves {self.r.randrange(0, 5)}\n      frequency {fmt(self.u(0.5, 4))}\n"
                         f"      amplitude {fmt(self.u(0.5, 6))}\n    }}")
        elif r < 0.35:
            tex = self.r.choice(TEXTURES)
            lines.append(f"    texture {tex}")
            files = (tex,)
        self.r.shuffle(lines)
        kw = self.r.choice(("Material", "PhongMaterial"))
        return f"  {kw} {{\n" + "\n".join(lines) + "\n  }", files, glass

    def transform_ops(self) -> list[str]:
        ops = []
        for _ in range(self.r.randrange(1, 4)):
            k = self.r.randrange(8)
            if k == 0:
                ops.append(f"Translate {v3([self.u(-1.5, 1.5) for _ in range(3)])}")
            elif k == 1:
                ops.append(f"Scale {v3([self.u(0.4, 1.6) for _ in range(3)])}")
            elif k == 2:
                ops.append(f"UniformScale {fmt(self.u(0.4, 1.6))}")
            elif k in (3, 4, 5):
                ops.append(f"{'XYZ'[k - 3]}Rotate {fmt(self.r.choice((90.0, -90.0, self.u(-180, 180))))}")
            elif k == 6:
                ops.append(f"Rotate {{ {v3([self.u(-1, 1) for _ in range(3)])} {fmt(self.u(-180, 180))} }}")
            else:  # a shear (or general affine map); Matrix4f reads columns
                m = [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]]
                i, j = self.r.sample(range(3), 2)
                m[i][j] = self.u(-0.8, 0.8)
                m[0][3], m[1][3], m[2][3] = (self.u(-1, 1) for _ in range(3))
                cols = [m[r][c] for c in range(4) for r in range(4)]
                ops.append("Matrix4f {\n" + "\n".join(v3(cols[4 * c:4 * c + 4]) for c in range(4)) + "\n}")
        return ops

    def primitive(self, uv_ok: bool) -> tuple[str, tuple[str, ...]]:
        k = self.r.random()
        if k < 0.35:
            c = [self.u(-1.5, 1.5), self.u(-1, 1.5), self.u(-1.5, 1.5)]
            return f"Sphere {{\n  center {v3(c)}\n  radius {fmt(self.u(0.3, 1.3))}\n}}", ()
        if k < 0.5:
            n = self.r.choice(([0, 1, 0], [0, 2, 0], [self.u(-0.3, 0.3), 1, self.u(-0.3, 0.3)],
                               [self.u(-1, 1), self.u(-1, 1), self.u(-1, 1)]))
            return f"Plane {{\n  normal {v3(n)}\n  offset {fmt(self.u(-2.5, -0.5))}\n}}", ()
        if k < 0.62:
            vs = [[self.u(-2, 2), self.u(-1, 2), self.u(-2, 2)] for _ in range(3)]
            return f"Triangle {{\n  vertex0 {v3(vs[0])}\n  vertex1 {v3(vs[1])}\n  vertex2 {v3(vs[2])}\n}}", ()
        # Heavier meshes are drawn less often (the binary traces a 100 x 100 -jitter vase scene in ~15 s).
        mesh = self.r.choice(UV_MESHES) if uv_ok and self.r.random() < 0.6 else \
            self.r.choices(MESHES, weights=(3, 3, 3, 1, 1))[0]
        scale, shift = MESH_FIT[mesh]
        fit = f"Translate {v3(shift)}\nUniformScale {fmt(scale)}\n" if shift != (0, 0, 0) else \
            f"UniformScale {fmt(scale)}\n"
        return f"{fit}TriangleMesh {{\n  obj_file {mesh}\n}}", (mesh,)

    def obj(self, n_materials: int, textured: set[int], depth: int = 0) -> Obj:
        m = self.r.randrange(n_materials)
        if depth == 0 and self.r.random() < 0.08:  # a nested Group with its own MaterialIndex
            kids = [self.obj(n_materials, textured, 1) for _ in range(2)]
            body = "\n".join(f"  MaterialIndex {o.material}\n{o.text}" for o in kids)
            files = tuple(f for o in kids for f in o.files)
            return Obj(m, f"Group {{\n  numObjects 2\n{body}\n}}", files)
        text, files = self.primitive(m in textured)
        if files:  # a mesh: its fitting transform after a random placement (so copies never coincide)
            place = f"Translate {v3([self.u(-1.5, 1.5) for _ in range(3)])}\n"
            ops = "\n".join(self.transform_ops()) + "\n" if self.r.random() < 0.5 else ""
            text = f"Transform {{\n{place}{ops}{text}\n}}"
        elif self.r.random() < 0.5:
            ops = "\n".join(self.transform_ops())
            text = f"Transform {{\n{ops}\n{text}\n}}"
        return Obj(m, text, files)


def random_scene(seed: int, index: int, size: int = 100) -> GenScene:
    """Scene number ``index`` of the seeded series ``seed`` (module docstring), rendered at ``size``²."""
    g = _Gen(random.Random(f"{seed}:{index}"))
    camera = g.camera()
    lights = tuple(g.light() for _ in range(g.r.randrange(1, 4)))
    background, bg_files = g.background()
    mats = [g.material() for _ in range(g.r.randrange(1, 5))]
    textured = {i for i, (_, f, _) in enumerate(mats) if f}
    objects = tuple(g.obj(len(mats), textured) for _ in range(g.r.randrange(1, 5)))
    flags = Flags(size=size, shadows=g.r.random() < 0.7, bounces=g.r.randrange(0, 9),
                  jitter=g.r.random() < 0.2, filter=g.r.random() < 0.3)
    return GenScene(camera, lights, background, tuple((t, f) for t, f, _ in mats), objects, flags, bg_files)

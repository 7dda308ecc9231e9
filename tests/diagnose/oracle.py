"""A float64 numpy ray tracer for scenes of planes and triangles, and spheres, planes and triangles inside a
``Transform`` (SPEC A.6: the ray mapped by M⁻¹, the normal by (M⁻¹)ᵀ and normalised): SPEC B.2 camera rays, SPEC
B.3 ``traceRay`` with
directional and point lights, a constant background, marble with ``octaves 0`` (SPEC B.4: ``N = 0``, so the colour
is ``t c1 + (1 - t) c2`` with ``t = (sin(frequency p.x) + 1)/2``), and each docs/MISTAKES.md kernel and marble
mistake as the change the catalogue defines. The per-mistake tests compare a5mi's ``-mistake`` renders with it:
an independent statement of every formula change (test helper, not part of a5mi)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

V = np.ndarray


def unit(v: V) -> V:
    return v / np.linalg.norm(v)


@dataclass
class Mat:
    diffuse: tuple[float, float, float] = (1.0, 1.0, 1.0)
    specular: tuple[float, float, float] = (0.0, 0.0, 0.0)
    shininess: float = 0.0
    ior: float = 0.0
    marble: tuple[tuple[float, float, float], tuple[float, float, float], float, float] | None = None  # c1 c2 f a

    def text(self) -> str:
        s = (f"Material {{ diffuseColor {' '.join(map(str, self.diffuse))} specularColor "
             f"{' '.join(map(str, self.specular))} shininess {self.shininess} refractionIndex {self.ior}")
        if self.marble is not None:
            c1, c2, f, a = self.marble
            s += (f" Noise {{ color {' '.join(map(str, c1))} color {' '.join(map(str, c2))} octaves 0 frequency {f}"
                  f" amplitude {a} }}")
        return s + " }"


@dataclass
class Scene:
    camera: tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...], float]
    materials: list[Mat]
    planes: list[tuple[tuple[float, float, float], float, int]] = field(default_factory=list)
    triangles: list[tuple[tuple[tuple[float, float, float], ...], int]] = field(default_factory=list)
    directional: list[tuple[tuple[float, float, float], tuple[float, float, float]]] = field(default_factory=list)
    point: list[tuple[tuple[float, float, float], tuple[float, float, float]]] = field(default_factory=list)
    ambient: tuple[float, float, float] = (0.0, 0.0, 0.0)
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: objects inside a ``Transform``: kind (``sphere``: (centre, radius), ``plane``: (normal, offset),
    #: ``triangle``: three vertices), its values, the transforms as written (``("Scale", (2, 1, 1))``,
    #: ``("ZRotate", 30)``, ...), material
    placed: list[tuple[str, tuple, list[tuple[str, object]], int]] = field(default_factory=list)

    def text(self) -> str:
        c, d, u, a = self.camera
        out = [f"PerspectiveCamera {{ center {' '.join(map(str, c))} direction {' '.join(map(str, d))} "
               f"up {' '.join(map(str, u))} angle {a} }}"]
        lights = [f"DirectionalLight {{ direction {' '.join(map(str, dd))} color {' '.join(map(str, cc))} }}"
                  for dd, cc in self.directional]
        lights += [f"PointLight {{ position {' '.join(map(str, p))} color {' '.join(map(str, cc))} }}"
                   for p, cc in self.point]
        out.append(f"Lights {{ numLights {len(lights)} {' '.join(lights)} }}")
        out.append(f"Background {{ color {' '.join(map(str, self.background))} "
                   f"ambientLight {' '.join(map(str, self.ambient))} }}")
        out.append(f"Materials {{ numMaterials {len(self.materials)} {' '.join(m.text() for m in self.materials)} }}")
        objs = []
        for n, off, m in self.planes:
            objs.append(f"MaterialIndex {m} Plane {{ normal {' '.join(map(str, n))} offset {off} }}")
        for vs, m in self.triangles:
            objs.append(f"MaterialIndex {m} Triangle {{ vertex0 {' '.join(map(str, vs[0]))} "
                        f"vertex1 {' '.join(map(str, vs[1]))} vertex2 {' '.join(map(str, vs[2]))} }}")
        for kind, values, transforms, m in self.placed:
            steps = " ".join(f"{name} {_words(arg)}" for name, arg in transforms)
            if kind == "sphere":
                obj = f"Sphere {{ center {_words(values[0])} radius {values[1]} }}"
            elif kind == "plane":
                obj = f"Plane {{ normal {_words(values[0])} offset {values[1]} }}"
            else:
                obj = "Triangle { " + " ".join(f"vertex{k} {_words(v)}" for k, v in enumerate(values)) + " }"
            objs.append(f"MaterialIndex {m} Transform {{ {steps} {obj} }}")
        out.append(f"Group {{ numObjects {len(self.planes) + len(self.triangles) + len(self.placed)} "
                   f"{' '.join(objs)} }}")
        return "\n".join(out) + "\n"


def _words(v: object) -> str:
    return " ".join(map(str, v)) if isinstance(v, tuple) else str(v)


def placing(transforms: list[tuple[str, object]]) -> V:
    """SPEC A.6's M (4x4) of a ``Transform``'s steps: M = I, then ``M = M T`` for each step in order (degrees)."""
    m = np.eye(4)
    for name, arg in transforms:
        t = np.eye(4)
        if name == "Translate":
            t[:3, 3] = arg
        elif name == "Scale":
            t[:3, :3] = np.diag(arg)
        elif name == "UniformScale":
            t[:3, :3] *= arg
        else:   # XRotate, YRotate, ZRotate: right-handed, about that axis
            a = math.radians(float(arg))
            i, j = {"XRotate": (1, 2), "YRotate": (2, 0), "ZRotate": (0, 1)}[name]
            t[i, i], t[i, j], t[j, i], t[j, j] = math.cos(a), -math.sin(a), math.sin(a), math.cos(a)
        m = m @ t
    return m


def _object_hit(kind: str, values: tuple, o: V, d: V) -> list[tuple[float, V]]:
    """Every ``(t, unit object-space normal)`` where the object-space ray ``o + t d`` (d not unit) meets it."""
    if kind == "sphere":
        q = o - np.array(values[0], float)
        a, b, c = d @ d, 2 * (d @ q), q @ q - values[1] ** 2
        disc = b * b - 4 * a * c
        if disc < 0:
            return []
        return [(t, unit(q + t * d)) for t in ((-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a))]
    if kind == "plane":
        n = np.array(values[0], float)
        return [] if n @ d == 0 else [((values[1] - n @ o) / (n @ d), unit(n))]
    v0, v1, v2 = (np.array(v, float) for v in values)
    e1, e2 = v1 - v0, v2 - v0
    mat = np.column_stack([e1, e2, -d])
    if abs(np.linalg.det(mat)) < 1e-12:
        return []
    b, g, t = np.linalg.solve(mat, o - v0)
    return [(t, unit(np.cross(e1, e2)))] if b >= 0 and g >= 0 and b + g <= 1 else []


def schlick(c: float, r0: float) -> float:
    return r0 + (1.0 - r0) * (1.0 - c) ** 5


class Oracle:
    """SPEC B.3 over :class:`Scene` with the set ``mistakes`` made; :meth:`image` gives rows top first."""

    def __init__(self, scene: Scene, bounces: int, shadows: bool, mistakes: tuple[str, ...] = ()) -> None:
        self.s, self.m = scene, set(mistakes)
        self.shadows = shadows and "no_shadows" not in self.m
        if "no_recursion" in self.m:
            bounces = 0
        bounces += ("bounces_plus_one" in self.m) - ("bounces_minus_one" in self.m)
        self.bounces = max(bounces, 0)

    def hit(self, o: V, d: V, tmin: float, tmax: float = math.inf) -> tuple[float, V, int] | None:
        best: tuple[float, V, int] | None = None
        for n, off, mat in self.s.planes:
            n = np.array(n, float)
            nd = n @ d
            if nd == 0.0:
                continue
            t = (off - n @ o) / nd
            if tmin < t < (tmax if best is None else best[0]):
                best = (t, unit(n), mat)
        for vs, mat in self.s.triangles:
            v0, v1, v2 = (np.array(v, float) for v in vs)
            e1, e2 = v1 - v0, v2 - v0
            pv = np.cross(d, e2)
            det = e1 @ pv
            if abs(det) < 1e-12:
                continue
            tv = o - v0
            uu = (tv @ pv) / det
            qv = np.cross(tv, e1)
            vv = (d @ qv) / det
            t = (e2 @ qv) / det
            if uu < 0 or vv < 0 or uu + vv > 1:
                continue
            if tmin < t < (tmax if best is None else best[0]):
                best = (t, unit(np.cross(e1, e2)), mat)
        for kind, values, transforms, mat in self.s.placed:
            m = placing(transforms)
            inv = np.linalg.inv(m)
            for t, n_o in _object_hit(kind, values, inv[:3, :3] @ o + inv[:3, 3], inv[:3, :3] @ d):
                if tmin < t < (tmax if best is None else best[0]):
                    best = (t, self.placed_normal(m[:3, :3], n_o), mat)
        return best

    def placed_normal(self, m: V, n_o: V) -> V:
        """SPEC B.3 notes: ``normalize((M⁻¹)ᵀ n_o)``; docs/MISTAKES.md ``normal_by_m``: ``M`` in place of
        ``(M⁻¹)ᵀ``, ``normal_not_normalised``: not normalised."""
        n = m @ n_o if "normal_by_m" in self.m else np.linalg.inv(m).T @ n_o
        return n if "normal_not_normalised" in self.m else unit(n)

    def kd(self, mat: Mat, p: V) -> V:
        if mat.marble is None:
            return np.array(mat.diffuse)
        c1, c2, f, a = mat.marble
        arg = a * p[0] if "marble_freq_amp_swapped" in self.m else f * p[0]   # N = 0 (octaves 0)
        t = min(max(math.sin(arg), 0.0), 1.0) if "marble_sine_unmapped" in self.m else (math.sin(arg) + 1) / 2
        return t * np.array(c1) + (1 - t) * np.array(c2)

    def trace(self, o: V, d: V, tmin: float, bounces: int, n_medium: float) -> V:
        h = self.hit(o, d, tmin)
        if h is None:
            return np.array(self.s.background)
        t, n, mi = h
        mat = self.s.materials[mi]
        p = o + t * d
        diffuse, ks = np.array(mat.diffuse), np.array(mat.specular)
        kd = self.kd(mat, p)
        color = np.zeros(3) if "no_ambient" in self.m else np.array(self.s.ambient) * (
            kd if "ambient_uses_kd" in self.m else diffuse)
        n_l = -n if ("normal_faces_viewer" in self.m and d @ n > 0) else n
        kd_l = diffuse if "kd_ignores_texture" in self.m else kd
        r = d - 2 * (d @ n) * n
        if "mirror_sign" in self.m:
            r = -r
        lights = [(-unit(np.array(dd, float)), np.array(cc), math.inf) for dd, cc in self.s.directional]
        lights += [(unit(np.array(pp) - p), np.array(cc), float(np.linalg.norm(np.array(pp) - p)))
                   for pp, cc in self.s.point]
        for k, (L, lc, dist) in enumerate(lights):
            if "light_dir_flipped" in self.m:
                L = -L
            cos = L @ n_l if "ndotl_unclamped" in self.m else max(L @ n_l, 0.0)
            term = cos * kd_l if "light_color_ignored" in self.m else cos * lc * kd_l
            if "phong_highlight" in self.m:
                ldr = max(L @ unit(r), 0.0)
                term = term + (1.0 if mat.shininess == 0 else ldr ** mat.shininess) * lc * ks
            if self.shadows and np.any(term != 0) and not ("shadow_first_light_only" in self.m and k > 0):
                far = math.inf if "shadow_beyond_light" in self.m else dist
                if self.hit(p, L, 0.001, far) is not None:
                    term = 0 * term
            color = color + term
        if bounces > 0:
            refl, refr, R = np.zeros(3), np.zeros(3), 1.0
            if np.linalg.norm(ks) > 0.001:
                refl = self.trace(p, r, 0.001, bounces - 1, n_medium)
            w_refl, w_refr = ks * 1.0, ks * 1.0
            if mat.ior > 0:
                leaving = d @ n > 0
                m, nt = (-n, 1.0) if leaving else (n, mat.ior)
                n_in, n_out, m_s = n_medium, nt, m
                if "eta_inverted" in self.m:
                    n_in, n_out = nt, n_medium
                if "eta_inside_inverted" in self.m and leaving:
                    n_in, n_out = nt, n_medium
                if "normal_not_flipped_inside" in self.m:
                    m_s = n
                eta = n_in / n_out
                dn = d @ m_s
                rad = 1 - eta * eta * (1 - dn * dn)
                r0 = ((nt - 1) / (nt + 1)) ** 2
                if rad >= 0:
                    T = unit(eta * (d - m_s * dn) - m_s * math.sqrt(rad))
                    refr = self.trace(p, T, 0.001, bounces - 1, nt)
                    c_d, c_t = abs(d @ m), abs(T @ m)
                    if "schlick_wrong_c" in self.m:
                        c_d, c_t = c_t, c_d
                    R = schlick(c_d if nt > n_medium else c_t, r0)
                elif "tir_ignored" in self.m:
                    R = schlick(abs(d @ m), r0)
            if "reflection_unweighted" in self.m:
                w_refl = np.ones(3)
            if "refraction_unweighted" in self.m:
                w_refr = np.ones(3)
            if "refl_refr_added" in self.m:
                color = color + w_refl * refl + w_refr * refr
            else:
                color = color + w_refl * R * refl + w_refr * (1 - R) * refr
        return color

    def image(self, size: int) -> V:
        c, dirn, up, angle = self.s.camera
        w = unit(np.array(dirn, float))
        u = unit(np.cross(w, np.array(up, float)))
        v = unit(np.cross(u, w))
        f = 1 / math.tan(math.radians(angle) / 2)
        img = np.zeros((size, size, 3))
        for j in range(size):
            for i in range(size):
                x, y = 2 * i / (size - 1) - 1, 2 * j / (size - 1) - 1
                img[size - 1 - j, i] = self.trace(np.array(c, float), unit(f * w + x * u + y * v), 0.0,
                                                  self.bounces, 1.0)
        return img

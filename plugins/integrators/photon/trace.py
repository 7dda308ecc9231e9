"""Photon tracing (Jensen 1996; docs/EXTENSIONS.md E.16): emitted photons followed through the a5 materials.

Each bounce is one Dr.Jit launch over the photons still alive (compacted between bounces on the host):
the nearest hit (plugins/kernel/intersect.py: meshes by the binary's rules, spheres, exact planes), the material
(plugins/kernel/surfaces.py), then :func:`.photon_walk.scatter`. At the first hit the power of an a5 light's
photon is multiplied by ``r²/(1 + f r²)`` (plugins/integrators/photon/emit.py). A photon is *stored* at every hit on a
material with ``max kd > 0``, with its position, direction and power and the kind of path that brought it:

* ``DIRECT`` (``L D``: the light loop computes this part; kept for the full map of the final gather),
* ``CAUSTIC`` (``L S+ D``: one or more mirror / dielectric bounces, no diffuse one: the caustic map),
* ``INDIRECT`` (``L (S|D)* D (S|D)* D``: after a diffuse bounce: the global map).

Photons are followed inside the ball of radius ``4 R`` about the bounding sphere ``(c, R)`` of the scene's
shapes, lights and camera (plugins/integrators/photon/emit.py ``scene_ball``): a hit farther out (an exact plane far
away)
absorbs the photon. An a5 light over an infinite plane otherwise sends photons of unbounded power (``∝ r²``)
from arbitrarily far back into the scene; the direct light there is next-event estimation's, only the indirect
light from beyond ``4 R`` is left out.

Depth: a photon ends by Russian roulette alone (plugins/integrators/photon/walk.py), unbiased; from bounce
:data:`ROULETTE_CAP_DEPTH` on its survival is at most :data:`ROULETTE_CAP` (power × ``w/q`` as before), so that
lossless bounces end too. ``max_depth > 0`` (``-photon_depth N``) cuts every path after ``N`` hits instead: the
light of the longer paths is lost: in an integrating sphere of albedo ``a`` the irradiance is
``Σ_(m=1..N) a^(m−1) = (1 − a^N)/(1 − a)`` times the direct one instead of ``1/(1 − a)``, a share ``a^N`` low
(E.16).

Random numbers: a PCG32 per photon, stream = the photon's index, state from ``(seed, pass, bounce)``, so a map
depends only on its seed and pass, never on how the photons were split or compacted.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from a5mi.plugins.integrators.photon.emit import PhotonRays, first_hit_factor, scene_ball, to_np3
from a5mi.plugins.integrators.photon.walk import photon_step
from a5mi.plugins.kernel.intersect import intersect, mirror_normal
from a5mi.plugins.kernel.surfaces import surface_at

if TYPE_CHECKING:
    from a5mi.plugins.kernel.features import Features, SceneData

DIRECT, CAUSTIC, INDIRECT = 0, 1, 2

#: From this bounce on, Russian roulette keeps a photon with probability at most ``ROULETTE_CAP`` (module
#: docstring): lossless paths end with probability 1 (after ``1/(1 − 0.95) = 20`` more bounces on average).
ROULETTE_CAP_DEPTH, ROULETTE_CAP = 32, 0.95


class PhotonSet(NamedTuple):
    """Stored photons (numpy): ``pos``, ``dir`` (travel direction) and ``power`` ``(n, 3)``, ``kind`` ``(n,)``
    (``DIRECT`` / ``CAUSTIC`` / ``INDIRECT``), ``shape`` ``(n,)`` (the hit shape's index in ``scene.shapes()``,
    ``-1 - k`` for exact plane ``k``) and ``emitted``: photons emitted per map (the caller's ``N``)."""

    pos: np.ndarray
    dir: np.ndarray
    power: np.ndarray
    kind: np.ndarray
    shape: np.ndarray
    emitted: int

    def select(self, mask: np.ndarray) -> PhotonSet:
        """The photons where ``mask``."""
        return PhotonSet(self.pos[mask], self.dir[mask], self.power[mask], self.kind[mask], self.shape[mask],
                         self.emitted)


def _np3(v: object) -> np.ndarray:
    return to_np3(v)


def _dr3(cls: type, a: np.ndarray) -> object:
    return cls(*(mi.Float(np.ascontiguousarray(a[:, i], dtype=np.float32)) for i in range(3)))


def shape_index(scene: mi.Scene, hit_shape: object, on_plane: object, plane: object) -> np.ndarray:
    """Per lane the index of the hit shape in ``scene.shapes()``, ``-1 - k`` on exact plane ``k``."""
    ids = np.asarray([s.id() for s in scene.shapes()])
    ptrs = mi.ShapePtr(scene.shapes_dr())
    out = np.full(dr.width(on_plane), -10**6, dtype=np.int64)
    for i in range(len(ids)):
        one = dr.gather(mi.ShapePtr, ptrs, mi.UInt32(i))
        out[np.asarray(hit_shape == one, dtype=bool)] = i
    pl = np.asarray(on_plane, dtype=bool)
    out[pl] = -1 - np.asarray(plane, dtype=np.int64)[pl]
    return out


def _bounce(scene: mi.Scene, data: SceneData, f: Features, o: np.ndarray, d: np.ndarray, n_medium: np.ndarray,
            index: np.ndarray, state: int, shapes: bool, q_max: float) -> dict[str, np.ndarray]:
    """One bounce of the photons ``(o, d)`` (numpy): hit, material, scatter (survival at most ``q_max``);
    numpy results."""
    n = len(o)
    od, dd = _dr3(mi.Point3f, o), _dr3(mi.Vector3f, d)
    h = intersect(scene, data.planes, data.rules, od, dd, data.tmin + dr.zeros(mi.Float, n), dr.zeros(mi.UInt32, n))
    s = surface_at(h.bsdf, h.si, h.hit, h.n, f, None, mi.UInt32(1))
    rng = mi.PCG32(n, dr.opaque(mi.UInt64, state), mi.UInt64(index.astype(np.uint64) * 2 + 1))
    u_lobe, u_rr = rng.next_float32(), rng.next_float32()
    u_dir = mi.Point2f(rng.next_float32(), rng.next_float32())
    n_mirror = mirror_normal(data.planes, h.on_plane, h.plane, s.n)
    st = photon_step(f.fresnel, dd, s.n, n_mirror, s.kd, s.specular, s.ior, mi.Float(n_medium.astype(np.float32)),
                     h.hit, u_lobe, u_dir, u_rr, f.refraction, f.reflection, q_max)
    out = {"t": h.t, "p": h.p, "kd": s.kd, "hit": h.hit, "d": st.d, "factor": st.factor, "alive": st.alive & h.hit,
           "diffuse": st.diffuse, "n_medium": st.n_medium}
    dr.eval(*out.values())
    res = {k: np.asarray(v) for k, v in out.items()}
    for k in ("p", "kd", "d", "factor"):
        res[k] = _np3(out[k])
    res["shape"] = shape_index(scene, h.si.shape, h.on_plane, h.plane) if shapes else None
    return res


def trace_photons(scene: mi.Scene, data: SceneData, f: Features, rays: PhotonRays, max_depth: int, seed: int,
                  pass_index: int, emitted: int, keep: tuple[int, ...] = (DIRECT, CAUSTIC, INDIRECT),
                  shapes: bool = False) -> PhotonSet:
    """Trace ``rays`` until Russian roulette ends them, or for at most ``max_depth`` hits when it is > 0
    (module docstring), and return the photons stored whose kind is in ``keep``; ``emitted``: the ``N`` the
    powers were divided by; ``shapes``: fill ``PhotonSet.shape`` (``a5mi photons``), else -1."""
    o, d, power = rays.o.copy(), rays.d.copy(), rays.power.copy()
    falloff = rays.falloff.copy()
    n_medium = np.ones(len(o), dtype=np.float64)           # photons leave the lights in air
    centre, radius = scene_ball(scene)
    bound = 4.0 * radius                                    # the photons' world (module docstring)
    index = np.arange(len(o), dtype=np.int64)
    kind = np.full(len(o), DIRECT, dtype=np.int8)
    stored: list[tuple[np.ndarray, ...]] = []
    depth = -1
    while len(o) and (max_depth <= 0 or depth + 1 < max_depth):
        depth += 1
        q_max = 1.0 if depth < ROULETTE_CAP_DEPTH else ROULETTE_CAP
        state = (seed * 0x9E3779B97F4A7C15 + (pass_index << 20) + depth * 0x632BE59BD9B4E019 + 1) % (1 << 64)
        b = _bounce(scene, data, f, o, d, n_medium, index, state, shapes, q_max)
        if depth == 0:
            r = np.where(b["hit"], b["t"].astype(np.float64), np.inf)
            power = power * first_hit_factor(falloff, r)[:, None]
        inside = np.linalg.norm(b["p"] - centre, axis=1) <= bound
        store = b["hit"] & inside & (b["kd"].max(axis=1) > 0.0) & np.isin(kind, keep)
        if store.any():
            sh = b["shape"][store] if shapes else np.full(int(store.sum()), -1)
            stored.append((b["p"][store], d[store], power[store], kind[store], sh))
        alive = b["alive"] & inside
        kind = np.where(b["diffuse"], INDIRECT, np.where(kind == DIRECT, CAUSTIC, kind)).astype(np.int8)
        if not any(k in keep for k in (CAUSTIC, INDIRECT)):
            break
        if keep == (CAUSTIC,):   # a caustic map follows specular paths only
            alive &= ~b["diffuse"]
        o, d = b["p"][alive], b["d"][alive]
        power = power[alive] * b["factor"][alive]
        kind, index, falloff, n_medium = kind[alive], index[alive], falloff[alive], b["n_medium"][alive]
        live = power.max(axis=1) > 0.0
        o, d, power, kind, index = o[live], d[live], power[live], kind[live], index[live]
        falloff, n_medium = falloff[live], n_medium[live]
    if not stored:
        z = np.zeros((0, 3))
        return PhotonSet(z, z, z, np.zeros(0, dtype=np.int8), np.zeros(0, dtype=np.int64), emitted)
    cols = [np.concatenate(c) for c in zip(*stored, strict=True)]
    return PhotonSet(cols[0], cols[1], cols[2], cols[3], cols[4].astype(np.int64), emitted)


def first_distance(scene: mi.Scene, data: SceneData) -> object:
    """``(o, d) -> distance to the first hit`` (numpy; inf on a miss), for the light powers of
    plugins/integrators/photon/emit.py."""
    def dist(o: np.ndarray, d: np.ndarray) -> np.ndarray:
        n = len(o)
        h = intersect(scene, data.planes, data.rules, _dr3(mi.Point3f, o), _dr3(mi.Vector3f, d),
                      data.tmin + dr.zeros(mi.Float, n), dr.zeros(mi.UInt32, n))
        t = dr.select(h.hit, h.t, dr.inf)
        dr.eval(t)
        return np.asarray(t, dtype=np.float64)
    return dist

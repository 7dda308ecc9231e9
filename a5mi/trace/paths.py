"""``a5mi trace`` of a path-traced (``-integrator path``, docs/EXTENSIONS.md E.14) or distribution-traced
(``-indirect N``, E.15) pixel: its ``-spp`` samples and what each contributes, checked against the render.

A render-buffer sample ``(i, j)`` is traced ``spp`` times, pass ``k`` with the keys the driver gives it
(:class:`a5mi.plugins.sampling.SamplePass` ``(j·RW + i, k, spp, seed)``, lane 0), so sample ``k`` here is exactly
the render's pass ``k`` of that pixel and their mean is the rendered value (up to float32 summation order).
For ``-integrator path`` every sample is a path, recorded vertex by vertex by the render kernel
(:class:`a5mi.plugins.kernel.pbr_record.PathRecorder`): the surface it hits (object and line), ``β``, the
MIS-weighted emission its ray found, the next-event estimate, the lobe sampled, its pdf and weight, the
roulette; the sample's value is the sum of the emission and next-event columns. For ``-indirect`` the sample
is the whole ray tree of one pass (its gathered rays included); its value is reported.
Pixels are addressed as :mod:`a5mi.trace.core` does (top-left; no ``-jitter`` / ``-filter``: one sample per
pixel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from a5mi.render.options import RenderOptions
from a5mi.trace.core import TraceError, Tracer
from a5mi.trace.tree import SceneObject, object_names


@dataclass
class Vertex:
    """One vertex of a recorded path: ``depth`` (0 = the camera ray's hit), ``hit`` (False: the ray escaped),
    ``obj`` (None: a light's shape or nothing), ``t``, ``p``, ``beta`` (β before the scatter), ``emitted``
    (β w_e Le its ray found), ``nee`` (β NEE at the vertex), ``lobe``, ``pdf``, ``weight`` (f cos/pdf), ``q``
    (the roulette's survival probability, 1 before ``rr_depth``) and ``survived``."""

    depth: int
    hit: bool
    obj: SceneObject | None
    t: float
    p: tuple[float, float, float]
    beta: tuple[float, float, float]
    emitted: tuple[float, float, float]
    nee: tuple[float, float, float]
    lobe: str
    pdf: float
    weight: tuple[float, float, float]
    q: float
    survived: bool

    def to_dict(self) -> dict[str, Any]:
        out = dict(self.__dict__)
        out["obj"] = None if self.obj is None else {"kind": self.obj.kind, "index": self.obj.index,
                                                    "line": self.obj.line}
        out["t"] = None if math.isinf(self.t) else self.t
        return out


@dataclass
class Sample:
    """Pass ``index`` of the pixel: its value and (``-integrator path``) its vertices."""

    index: int
    value: tuple[float, float, float]
    vertices: list[Vertex] = field(default_factory=list)


@dataclass
class PathPixel:
    """What ``a5mi trace`` found for one pixel of a stochastic mode: ``mode`` (``path`` / ``indirect``), the
    samples, their ``mean`` and standard error ``stderr`` per channel, and the ``rendered`` pixel of the real
    render (float32)."""

    x: int
    y: int
    mode: str
    spp: int
    seed: int
    samples: list[Sample]
    mean: tuple[float, float, float]
    stderr: tuple[float, float, float]
    rendered: tuple[float, float, float]

    @property
    def error(self) -> float:
        """|mean of the samples − rendered pixel| (float32 sums in a different order: about 1e-7)."""
        return float(np.max(np.abs(np.array(self.mean) - np.array(self.rendered))))

    def to_json(self) -> dict[str, Any]:
        return {"pixel": [self.x, self.y], "mode": self.mode, "spp": self.spp, "seed": self.seed,
                "mean": list(self.mean), "stderr": list(self.stderr), "rendered": list(self.rendered),
                "error": self.error,
                "samples": [{"index": s.index, "value": list(s.value),
                             "vertices": [v.to_dict() for v in s.vertices]} for s in self.samples]}


def stochastic_mode(options: RenderOptions) -> str | None:
    """``path`` / ``indirect`` when the options render one of the stochastic modes this module traces."""
    if options.integrator == "path":
        return "path"
    if options.indirect > 0:
        return "indirect"
    return None


def _t3(row: np.ndarray, name: str) -> tuple[float, float, float]:
    from a5mi.plugins.kernel.pbr_record import LAYOUT

    off, _ = LAYOUT[name]
    return (float(row[off]), float(row[off + 1]), float(row[off + 2]))


def _f1(row: np.ndarray, name: str) -> float:
    from a5mi.plugins.kernel.pbr_record import LAYOUT

    return float(row[LAYOUT[name][0]])


def _vertices(rows: np.ndarray, shapes: dict[int, SceneObject], planes: list[SceneObject]) -> list[Vertex]:
    from a5mi.plugins.kernel.pbr_record import LOBES

    out = []
    for depth, row in enumerate(rows):
        if _f1(row, "valid") < 0.5:
            break
        on_plane = _f1(row, "on_plane") > 0.5
        obj = (planes[int(_f1(row, "plane"))] if planes else None) if on_plane else shapes.get(int(_f1(row, "shape")))
        hit = _f1(row, "hit") > 0.5
        out.append(Vertex(depth, hit, obj if hit else None, _f1(row, "t"), _t3(row, "p"), _t3(row, "beta"),
                          _t3(row, "emitted"), _t3(row, "nee"), LOBES[int(_f1(row, "lobe"))], _f1(row, "pdf"),
                          _t3(row, "weight"), _f1(row, "q") if _f1(row, "q") > 0.0 else 1.0,
                          _f1(row, "survived") > 0.5 or _f1(row, "q") == 0.0))
    return out


def trace_pixel(tracer: Tracer, x: int, y: int) -> PathPixel:
    """The :class:`PathPixel` of pixel ``(x, y)`` (top-left) of ``tracer``'s scene and options."""
    import drjit as dr
    import mitsuba as mi

    from a5mi.platform.arrays import aligned_float32
    from a5mi.plugins.kernel.pbr_record import PathRecorder
    from a5mi.plugins.sampling import SamplePass
    from a5mi.plugins.sensors.camera import camera_rays

    opts = tracer.options
    mode = stochastic_mode(opts)
    if mode is None:
        raise TraceError("trace_pixel traces -integrator path or -indirect N pixels")
    if opts.jitter or opts.filter:
        raise TraceError(f"a5mi trace of -{'integrator path' if mode == 'path' else 'indirect'}: without -jitter "
                         "and -filter (one render-buffer sample per pixel)")
    if not (0 <= x < opts.width and 0 <= y < opts.height):
        raise TraceError(f"pixel ({x}, {y}) is outside the {opts.width}x{opts.height} image")
    i, j = x, opts.height - 1 - y
    cam = tracer.desc.camera
    ray = camera_rays(cam.center, cam.direction, cam.up, cam.angle, mi.Float(aligned_float32(np.array([i], float))),
                      mi.Float(aligned_float32(np.array([j], float))), opts.width, opts.height)
    seed = opts.seed or 0
    integ = tracer.integrator
    samples: list[Sample] = []
    shapes: dict[int, SceneObject] = {}
    planes: list[SceneObject] = []
    max_vertices = opts.bounces + 2
    for k in range(opts.spp):
        sp = SamplePass(j * opts.width + i, k, opts.spp, seed)
        if mode == "path":
            rec = PathRecorder(1, max_vertices)
            color = integ.trace(tracer.scene, ray, mi.Bool(True), None, sp, record=rec)[0]
            dr.eval(color)
            rows = rec.read()[0]  # type: ignore[index]
            if not shapes:
                from a5mi.plugins.kernel.pbr_record import LAYOUT

                rids = {int(r[LAYOUT["shape"][0]]) for r in rows}
                shapes, planes = object_names(tracer.desc, tracer.scene, integ, rids)
            else:
                from a5mi.plugins.kernel.pbr_record import LAYOUT

                rids = {int(r[LAYOUT["shape"][0]]) for r in rows} - set(shapes)
                if rids:
                    more, _ = object_names(tracer.desc, tracer.scene, integ, rids)
                    shapes.update(more)
            vertices = _vertices(rows, shapes, planes)
        else:
            color = integ.trace(tracer.scene, ray, mi.Bool(True), None, sample_pass=sp)[0]
            dr.eval(color)
            vertices = []
        value = tuple(float(c) for c in np.asarray(color).ravel()[:3])
        samples.append(Sample(k, value, vertices))  # type: ignore[arg-type]
    values = np.array([s.value for s in samples], np.float64)
    mean = values.mean(axis=0)
    se = values.std(axis=0, ddof=1) / math.sqrt(len(samples)) if len(samples) > 1 else np.zeros(3)
    rendered = tracer.image()[y, x].astype(np.float64)
    return PathPixel(x, y, mode, opts.spp, seed, samples, tuple(float(v) for v in mean),  # type: ignore[arg-type]
                     tuple(float(v) for v in se), tuple(float(v) for v in rendered))  # type: ignore[arg-type]


def _v3(v: tuple[float, float, float]) -> str:
    return "(" + ", ".join(f"{c:.4f}" for c in v) + ")"


def format_pixel(pp: PathPixel, show: int | None = None) -> str:
    """The text report: the pixel's mean, standard error and rendered value, then each sample (``show``: the
    first ``show`` samples only) with its vertices."""
    what = "-integrator path" if pp.mode == "path" else "-indirect"
    lines = [f"pixel ({pp.x}, {pp.y}) (top-left), {what}: {pp.spp} samples (-spp), seed {pp.seed}",
             f"  mean {_v3(pp.mean)} ± {_v3(pp.stderr)} (standard error); rendered {_v3(pp.rendered)} "
             f"(|mean − rendered| = {pp.error:.2g})"]
    for s in pp.samples[:show]:
        lines.append(f"  sample {s.index}: {_v3(s.value)}")
        for v in s.vertices:
            where = (str(v.obj) if v.obj is not None else "a light's shape") if v.hit else "escapes"
            head = f"    v{v.depth} {where}" + (f", t = {v.t:.4g}" if v.hit else "")
            parts = [head, f"β {_v3(v.beta)}"]
            if any(v.emitted):
                parts.append(f"emission {_v3(v.emitted)}")
            if any(v.nee):
                parts.append(f"NEE {_v3(v.nee)}")
            if v.lobe != "end":
                scatter = f"-> {v.lobe}"
                if v.lobe == "diffuse":
                    scatter += f" (pdf {v.pdf:.4g})"
                if v.lobe != "absorbed":
                    scatter += f" weight {_v3(v.weight)}"
                if v.q < 1.0:
                    scatter += f", roulette q = {v.q:.3f}: {'survives' if v.survived else 'ends'}"
                parts.append(scatter)
            lines.append("; ".join(parts))
    if show is not None and len(pp.samples) > show:
        lines.append(f"  ... {len(pp.samples) - show} more samples (--json lists all)")
    return "\n".join(lines)

"""Record mode of ``a5_path`` (docs/EXTENSIONS.md E.14): the vertices of a few paths, from the render kernel.

:class:`PathRecorder` is handed to :func:`plugins.path.trace_paths` only by ``a5mi trace``; a render passes none
and its :class:`~.features.Features` have ``record = False``, so its kernel holds none of these calls. At each
iteration of the path loop (vertex ``i``, the ray that arrives there) the kernel scatters what it computed:
the hit (shape registry id or plane), ``β_i``, the emission that ray added (``β_i w_e Le``), the next-event
estimate (``β_i NEE_i``), the lobe sampled, its pdf and weight, and the roulette's survival probability; the
sample's value is the sum of the ``emitted`` and ``nee`` columns.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

#: lobe codes of the ``lobe`` field: none sampled (the path ends here), Lambert, mirror, refraction, absorbed
LOBES: tuple[str, ...] = ("end", "diffuse", "mirror", "refraction", "absorbed")
#: per-vertex fields and widths, in buffer order
VERTEX_FIELDS: tuple[tuple[str, int], ...] = (
    ("valid", 1), ("hit", 1), ("on_plane", 1), ("plane", 1), ("shape", 1), ("t", 1), ("p", 3), ("beta", 3),
    ("emitted", 3), ("nee", 3), ("lobe", 1), ("pdf", 1), ("weight", 3), ("q", 1), ("survived", 1),
)
LAYOUT: dict[str, tuple[int, int]] = {}
_k = 0
for _name, _w in VERTEX_FIELDS:
    LAYOUT[_name] = (_k, _w)
    _k += _w
STRIDE = _k


def _f(v: object) -> mi.Float:
    if isinstance(v, mi.Bool):
        return dr.select(v, mi.Float(1.0), mi.Float(0.0))
    return mi.Float(v)


class PathRecorder:
    """Per-lane buffers for at most ``max_vertices`` vertices of ``width`` paths; :meth:`read` gives
    ``(W, V, STRIDE)`` laid out by :data:`LAYOUT`."""

    def __init__(self, width: int, max_vertices: int) -> None:
        self.width, self.max_vertices = width, max_vertices
        self.lane = dr.arange(mi.UInt32, width)
        self.buf = dr.zeros(mi.Float, width * max_vertices * STRIDE)
        dr.make_opaque(self.buf)

    def vertex(self, depth: mi.UInt32, active: mi.Bool, **values: object) -> None:
        """Store fields (names of :data:`VERTEX_FIELDS`) of vertex ``depth`` on the lanes ``active``."""
        ok = active & (depth < self.max_vertices)
        base = (self.lane * self.max_vertices + depth) * STRIDE
        for name, value in values.items():
            off, w = LAYOUT[name]
            if w == 1:
                dr.scatter(self.buf, _f(value), base + off, ok)
            else:
                for c in range(w):
                    dr.scatter(self.buf, _f(value[c]), base + off + c, ok)  # type: ignore[index]

    def read(self) -> object:
        import numpy as np

        dr.eval(self.buf)
        return np.asarray(self.buf).reshape(self.width, self.max_vertices, STRIDE)


def lobe_code(valid: mi.Bool, delta: mi.Bool, through: mi.Bool, alive: mi.Bool) -> mi.Float:
    """The :data:`LOBES` code of a vertex's scatter: ``end`` where the path was not continued from it."""
    code = dr.select(delta, dr.select(through, 3.0, 2.0), 1.0)
    return dr.select(alive, dr.select(valid, code, 4.0), 0.0)

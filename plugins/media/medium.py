"""The participating media of ``a5_whitted``: homogeneous ``Fog`` and gridded ``Volume`` (docs/EXTENSIONS.md
E.8, E.9): :class:`MediumParams` and its reading from the integrator's properties. How a ray segment is
attenuated and lit in a medium is the integrator's (plugins/integrators/whitted/medium_segment.py); the
transmittance towards a light is plugins/media/light.py.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from a5mi.plugins.params import read_choice, read_int, read_number

#: Sampling dimensions of the medium: ``MEDIUM_DIM + node·256 + k`` for light k, ``+ 255`` for the jitter ξ.
MEDIUM_DIM = 0x80000000
KINDS = ("fog", "volume")
#: the plugin that reads these parameters (the first word of their errors)
PLUGIN = "a5_whitted"


class MediumParams:
    """The medium of a render: ``kind`` (``fog`` | ``volume``, baked into the kernel), the extinction
    ``density``, the ``albedo`` and ``steps`` (opaque), and for a volume its grid (a Mitsuba ``gridvolume``
    placed on the box) and the box corners (opaque)."""

    def __init__(self, kind: str, density: float, albedo: list[float], steps: int,
                 grid: mi.Volume | None = None, bounces: int = 0, g: float = 0.0) -> None:
        self.kind = kind
        self.density_value, self.albedo_value, self.steps_value = float(density), list(albedo), int(steps)
        self.density = dr.opaque(mi.Float, self.density_value)
        self.albedo = dr.opaque(mi.Color3f, self.albedo_value)
        self.steps = dr.opaque(mi.UInt32, self.steps_value)
        #: ``medium_bounces`` (``-media_bounces``): 0 the course-era E.8 (light unattenuated on its way), >= 1
        #: shadow rays carry the medium's transmittance (plugins/media/light.py)
        self.bounces = int(bounces)
        self.bounces_opaque = dr.opaque(mi.UInt32, self.bounces)
        #: Henyey-Greenstein asymmetry (plugins/integrators/whitted/medium_walk.py); 0: the isotropic phase of E.8,
        #: no phase factor
        self.g_value = float(g)
        self.g = dr.opaque(mi.Float, self.g_value)
        self.grid = grid
        self.grid_max = dr.opaque(mi.Float, float(grid.max()) if grid is not None else 0.0)
        if grid is not None:
            box = grid.bbox()
            self.box_min = dr.opaque(mi.Point3f, [float(box.min[i]) for i in range(3)])
            self.box_max = dr.opaque(mi.Point3f, [float(box.max[i]) for i in range(3)])


def params_from_props(props: mi.Properties) -> MediumParams | None:
    """``medium`` (``none`` | ``fog`` | ``volume``), ``medium_density`` (>= 0), ``medium_albedo`` (rgb),
    ``medium_steps`` (>= 1) and, for a volume, ``medium_grid`` (a ``gridvolume``); None for ``none``."""
    kind = read_choice(PLUGIN, props, "medium", "none", ("none", *KINDS))
    bounces = read_int(PLUGIN, props, "medium_bounces", 0, 0)
    if kind == "none":
        return None
    density = read_number(PLUGIN, props, "medium_density", 0.0)
    steps = read_int(PLUGIN, props, "medium_steps", 16, 1)
    albedo = props.get("medium_albedo", mi.ScalarColor3d(1.0))
    grid = None
    if kind == "volume":
        grid = props.get("medium_grid", None)
        if not isinstance(grid, mi.Volume):
            raise ValueError(f"{PLUGIN}: medium 'volume' needs a 'medium_grid' volume (gridvolume)")
    g = read_number(PLUGIN, props, "medium_g", 0.0, -1.0, 1.0, open_low=True)
    return MediumParams(kind, density, [float(albedo[i]) for i in range(3)], steps, grid, bounces, g)

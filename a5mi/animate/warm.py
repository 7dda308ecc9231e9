"""One warm scene per process, updated per frame (docs/EXTENSIONS.md E.11, E.12).

:class:`WarmScene` loads the Mitsuba scene of an animated model once (the still scene, as ``a5`` renders it)
and, for a time ``t``, writes the values of :func:`converters.keyframes.scene_at` into it through
``mi.traverse`` / ``SceneParameters.update()``, without recompiling the render kernel (every value that
changes enters the kernel as an opaque variable or a device array):

* camera: the a5 camera is not a Mitsuba sensor; the driver takes the camera of the frame (its basis, focal
  factor, lens radius and focus distance are opaque, :mod:`a5mi.plugins.sensors.camera`, :mod:`a5mi.render.passes`);
* ``PointLight`` / ``SpotLight``: ``position``, ``color`` and the spot's unit ``axis = d/|d|``;
  ``AreaLight`` / ``SphereLight``: the ``color`` of the ``a5_area`` emitter on the light's shape (opaque);
  ``DirectionalLight``: ``irradiance.value`` and the ``to_world`` Mitsuba's ``directional`` builds from
  ``direction`` (copied from a stand-alone one, so it is the same to the bit);
* media (E.8, E.9): the ``Fog`` / ``Volume`` ``density`` and albedo ``color`` (opaque values of ``a5_whitted``'s
  medium) and a Volume's grid per frame (``grid "smoke_%03d.vol"``: the ``gridvolume``'s ``data``, read once per
  frame);
* materials: ``diffuse_color``, ``specular_color`` of each ``a5_material`` of the material (and its uniform
  ``kd.value``); a keyframed specular colour keeps the still material's kind (mirror or not, SPEC B.3);
* shapes under a keyframed ``Transform`` get the world-space data of :func:`converters.describe.describe`
  for the frame's matrices: meshes and triangles ``vertex_positions`` / ``vertex_normals`` / ``faces`` (and the
  octree-rule face attributes), spheres ``to_world`` (``translate(M c)·scale(s r)`` for a similarity, else
  the instance's ``M``: a sphere must keep one of the two kinds for the whole animation), planes the
  integrator's device arrays (:func:`a5mi.plugins.emulation.planes.replace_planes`).

Every tracked value is written at every frame, computed from ``t`` alone: a frame does not depend on the
frames the process rendered before (so it is the same on every worker).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from a5mi.converters import keyframes, volgrid
from a5mi.converters import transforms as tf
from a5mi.converters.describe import describe, describe_volume
from a5mi.converters.errors import SceneSemanticError
from a5mi.converters.geometry import mesh_from_obj, mesh_from_triangle, world_plane
from a5mi.converters.model import (
    AreaLight,
    DirectionalLight,
    Group,
    Node,
    Plane,
    PointLight,
    Scene,
    Sphere,
    SphereLight,
    SpotLight,
    Transform,
    Triangle,
    TriangleMesh,
    Volume,
)
from a5mi.converters.names import binary_spheres, object_bsdf, scene_ids
from a5mi.converters.to_mitsuba import OCTREE_ATTRIBUTES, TRIANGLE_ATTRIBUTES, to_dict
from a5mi.platform.arrays import aligned_float32
from a5mi.platform.loading import load_dict
from a5mi.render.driver import RenderResult, render_scene
from a5mi.render.options import RenderOptions


def enclosing_transforms(root: Group) -> list[frozenset[int]]:
    """Per placed primitive (file order, as :attr:`Scene.objects`), the numbers of the ``Transform`` blocks
    around it (numbered as :func:`converters.keyframes.transform_blocks`)."""
    out: list[frozenset[int]] = []
    counter = [0]

    def walk(node: Node, around: frozenset[int]) -> None:
        if isinstance(node, Group):
            for c in node.children:
                walk(c, around)
        elif isinstance(node, Transform):
            index = counter[0]
            counter[0] += 1
            walk(node.child, around | {index})
        else:
            out.append(around)

    walk(root, frozenset())
    return out


@dataclass
class FrameTiming:
    """Seconds spent updating the scene and rendering, and the kernels compiled, per frame."""

    update: float = 0.0
    render: float = 0.0
    kernels: dict[str, int] = field(default_factory=dict)


class WarmScene:
    """The Mitsuba scene of ``model`` (which has an ``animation``) loaded once; :meth:`render` renders the
    scene at any time (module docstring). Needs an active JIT variant with the a5mi plugins registered."""

    def __init__(self, model: Scene, options: RenderOptions) -> None:
        import mitsuba as mi

        from a5mi.converters import files, octree

        self.model, self.options = model, options
        self.animation = model.animation
        self.desc = describe(model, bump=options.bump)  # -bump: the maps of docs/EXTENSIONS.md E.7
        d = to_dict(self.desc, options)
        self.ids = scene_ids(self.desc, binary_spheres=binary_spheres(options.integrator, options.subsurface))
        self.bsdfs: dict[int, list[Any]] = {}  # material -> its a5_material objects
        for shape, ids in zip(self.desc.shapes, self.ids.objects, strict=True):
            obj = object_bsdf(d, ids)
            if all(obj is not b for b in self.bsdfs.setdefault(shape.material, [])):
                self.bsdfs[shape.material].append(obj)
        self.scene = load_dict(d)
        self.params = mi.traverse(self.scene)
        self.integrator = self.scene.integrator()
        tracks = self.animation.tracks if self.animation is not None else ()
        moving = {tr.index for tr in tracks if tr.target == "Transform"}
        self.moving = [i for i, around in enumerate(enclosing_transforms(model.root)) if around & moving]
        self.lights = sorted({tr.index for tr in tracks if tr.target == "Light"})
        # E.8, E.9: a keyframed medium, or a Volume with a grid per frame (volgrid.frame_name)
        medium = model.medium
        self.grid_frames = isinstance(medium, Volume) and volgrid.is_pattern(medium.grid)
        self.medium_tracked = self.grid_frames or any(tr.target in ("Fog", "Volume") for tr in tracks)
        self._grid_name = volgrid.frame_name(medium.grid, 0) if isinstance(medium, Volume) else None
        self.materials = sorted({tr.index for tr in tracks if tr.target == "Material"})
        self.meshes: dict[str, tuple[Any, np.ndarray]] = {}  # OBJ name -> (ObjMesh, reach masks)
        placed = model.objects
        for i in self.moving:
            prim = placed[i].primitive
            if isinstance(prim, TriangleMesh) and prim.obj_file not in self.meshes:
                obj = files.load_mesh(model, prim.obj_file, prim.obj_file_loc)[1]
                self.meshes[prim.obj_file] = (obj, octree.reach_masks(obj.vertices, obj.faces))
        self._sphere_kind = {i: tf.similarity_scale(placed[i].to_world) is not None for i in self.moving
                             if isinstance(placed[i].primitive, Sphere)}

    # ----------------------------------------------------------------------------------------------- update
    def update(self, t: float) -> Any:
        """Write the scene at time ``t`` into the loaded scene (module docstring); returns its camera."""
        import drjit as dr
        import mitsuba as mi

        model_t = keyframes.scene_at(self.model, t)
        p = self.params
        for i in self.lights:
            light, key = model_t.lights[i], self.ids.lights[i].key
            if isinstance(light, PointLight | SpotLight):
                p[f"{key}.position"] = mi.Point3f(*light.position)
                p[f"{key}.color"] = mi.Color3f(*light.color)
            if isinstance(light, SpotLight):
                norm = math.sqrt(sum(c * c for c in light.direction))
                p[f"{key}.axis"] = mi.Vector3f(*(c / norm for c in light.direction))
            elif isinstance(light, DirectionalLight):
                p[f"{key}.irradiance.value"] = mi.Color3f(*light.color)
                # the matrix Mitsuba's directional builds from a direction, taken from one it builds
                probe = load_dict({"type": "directional", "direction": list(light.direction)})
                p[f"{key}.to_world"] = mi.traverse(probe)["to_world"]
            elif isinstance(light, AreaLight | SphereLight):  # the a5_area emitter of the light's shape (E.2)
                p[f"{key}.emitter.color"] = dr.opaque(mi.Color3f, list(light.color))
        for m in self.materials:
            mat = model_t.materials[m]
            for obj in self.bsdfs.get(m, ()):
                bp = mi.traverse(obj)
                bp["diffuse_color"] = mi.Color3f(*mat.diffuse_color)
                bp["specular_color"] = mi.Color3f(*mat.specular_color)
                if "kd.value" in bp.keys():
                    bp["kd.value"] = mi.Color3f(*mat.diffuse_color)
                bp.update()
        if self.moving:
            self._move_shapes(model_t)
        if self.medium_tracked:
            self._update_medium(model_t)
        p.update()
        return model_t.camera

    def _update_medium(self, model_t: Scene) -> None:
        """The medium's opaque ``density`` and ``albedo`` (plugins/media/medium.py ``MediumParams``, read by the kernel
        at trace time) and, for a grid per frame, the ``gridvolume``'s ``data`` (same resolution every frame)."""
        import drjit as dr
        import mitsuba as mi

        med, m = self.integrator._medium, model_t.medium  # the a5_whitted medium (E.8, E.9)
        med.density = dr.opaque(mi.Float, float(m.density))
        med.albedo = dr.opaque(mi.Color3f, [float(c) for c in m.color])
        if self.grid_frames and m.grid != self._grid_name:
            grid = describe_volume(model_t, m).grid
            gp = mi.traverse(med.grid)
            if tuple(gp["data"].shape) != grid.shape:
                raise SceneSemanticError(f"Volume grid '{m.grid}' is {grid.shape[2]} x {grid.shape[1]} x "
                                         f"{grid.shape[0]}; every frame's grid must have the size of frame 0's "
                                         f"({' x '.join(str(n) for n in tuple(gp['data'].shape)[2::-1])})",
                                         m.grid_loc)
            gp["data"] = mi.TensorXf(np.ascontiguousarray(grid, dtype=np.float32))
            gp.update()
            self._grid_name = m.grid

    def _move_shapes(self, model_t: Scene) -> None:
        import mitsuba as mi

        from a5mi.plugins.emulation.planes import replace_planes

        p = self.params
        placed = model_t.objects
        planes: dict[str, Any] = {}
        for i in self.moving:
            pl = placed[i]
            prim, m = pl.primitive, pl.to_world
            ids = self.ids.objects[i]
            if isinstance(prim, TriangleMesh | Triangle):
                if isinstance(prim, TriangleMesh):
                    obj, reach = self.meshes[prim.obj_file]
                    data = mesh_from_obj(obj, m, "auto", reach, pl.transformed)
                else:
                    data = mesh_from_triangle(prim, m)
                name = ids.entry
                # 64-byte aligned copies: Dr.Jit maps numpy memory and bakes its alignment into kernels (driver)
                p[f"{name}.vertex_positions"] = mi.Float(aligned_float32(data.positions))
                p[f"{name}.faces"] = mi.UInt32(aligned_float32(data.faces.astype(np.uint32).view(np.float32))
                                               .view(np.uint32))
                if data.normals is not None:
                    p[f"{name}.vertex_normals"] = mi.Float(aligned_float32(data.normals))
                if data.octree is not None:
                    for attr, cols in OCTREE_ATTRIBUTES.items():
                        p[f"{name}.{attr}"] = mi.Float(aligned_float32(data.octree[:, cols]))
                if data.triangles is not None:  # the binary's triangle test (plugins/emulation/triangle_rule.py)
                    for attr, cols in TRIANGLE_ATTRIBUTES.items():
                        p[f"{name}.{attr}"] = mi.Float(aligned_float32(data.triangles[:, cols]))
            elif isinstance(prim, Sphere):
                scale = tf.similarity_scale(m)
                if (scale is not None) != self._sphere_kind[i]:
                    raise SceneSemanticError("a keyframed Transform must keep this Sphere's scale uniform (or "
                                             "non-uniform) for the whole animation", prim.loc)
                if ids.plane is not None:       # a5_whitted's sphere test (plugins/emulation/planes.py): the binary's M
                    planes[ids.plane] = tf.binary_chain(pl.levels)
                elif scale is not None:
                    c = tf.transform_points(m, np.asarray(prim.center))
                    p[f"{ids.entry}.to_world"] = (mi.ScalarTransform4f().translate(mi.ScalarPoint3f(*c))
                                                  @ mi.ScalarTransform4f().scale(float(prim.radius * scale)))
                else:
                    p[f"{ids.entry}.to_world"] = mi.ScalarTransform4f(m.tolist())
            elif isinstance(prim, Plane) and ids.plane is not None:  # an exact plane: a5_whitted's parameters
                chain = tf.binary_chain(pl.levels)
                if chain is not None:           # intersected in object space (plugins/emulation/planes.py)
                    planes[ids.plane] = chain
                    continue
                n_w, off_w = world_plane(prim, m)
                mirror = n_w / np.linalg.norm(n_w) if pl.transformed else n_w
                planes[ids.plane] = (tuple(float(x) for x in n_w), float(off_w), tuple(float(x) for x in mirror))
        if planes:
            replace_planes(self.integrator, planes)

    # ----------------------------------------------------------------------------------------------- render
    def render(self, frame: int, timing: FrameTiming | None = None) -> RenderResult:
        """Frame ``frame``. With ``shutter s`` and ``spp = N`` passes, pass ``i`` sees the scene at
        :func:`pass_time` (E.12: ``N`` stratified slices of the shutter interval centred on the frame's time,
        each at its centre); with one pass (or ``s = 0``) that is the frame's time ``frame / fps``."""
        import time

        anim = self.animation
        fps = anim.fps if anim is not None else 1.0
        shutter = anim.shutter if anim is not None else 0.0
        spp = self.options.spp
        t0 = time.perf_counter()
        update_time = [0.0]

        def hook(k: int) -> Any:
            u0 = time.perf_counter()
            camera = self.update(pass_time(frame, fps, shutter, k, spp))
            update_time[0] += time.perf_counter() - u0
            return camera

        if shutter > 0.0 and spp > 1:
            result = render_scene(self.scene, self.desc.camera, self.options, integrator=self.integrator,
                                  pass_hook=hook)
        else:
            result = render_scene(self.scene, hook(0), self.options, integrator=self.integrator)
        if timing is not None:
            timing.update += update_time[0]
            timing.render += time.perf_counter() - t0 - update_time[0]
            for k, v in result.kernels.items():
                timing.kernels[k] = timing.kernels.get(k, 0) + v
        return result


def pass_time(frame: int, fps: float, shutter: float, k: int, passes: int) -> float:
    """E.12: ``t_k = (frame + shutter·((k + ½)/N − ½)) / fps`` for pass ``k`` of ``N``: the centre of the
    ``k``-th of ``N`` equal slices of the open shutter ``[frame − s/2, frame + s/2] / fps``."""
    return (frame + shutter * ((k + 0.5) / passes - 0.5)) / fps

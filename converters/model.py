"""The typed scene model of the 6.837 scene language (SPEC A.1-A.6).

Frozen dataclasses, one per block of the grammar, with the keyword names in snake_case
(``diffuseColor`` -> ``diffuse_color``) and the SPEC defaults. Every entity keeps the :class:`FileLoc` of
the keyword that opened it (``loc``), so later stages (the Mitsuba converter) report errors at the entity,
as pbrt's ``SceneEntity`` does. File names (``obj_file``, ``texture``, ``cubeMap``) are stored as written,
with their own ``*_loc``; the describe step turns them into files (:func:`a5mi.converters.files.resolve_path`:
scene folder first, then the working directory; the sample solution used only the working directory, SPEC A.0).

Typed data and pure helpers only: no file-system access, no Mitsuba import (pure Python plus numpy).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from a5mi.converters.errors import FileLoc

if TYPE_CHECKING:
    from a5mi.converters.subsurface import Subsurface
    from a5mi.converters.surface_model import Btf, Milled

Vec3 = tuple[float, float, float]
#: A 4x4 matrix as hashable row-major tuples (``m[row][col]``); :func:`.transforms.as_array` gives numpy.
Matrix4 = tuple[tuple[float, float, float, float], ...]


# ---------------------------------------------------------------------------------------------- camera, lights
@dataclass(frozen=True)
class Camera:
    """``PerspectiveCamera { center V3 direction V3 up V3 angle F }`` (SPEC A.2); ``angle`` in degrees, full fov."""

    center: Vec3
    direction: Vec3
    up: Vec3
    angle: float
    loc: FileLoc
    #: thin lens (docs/EXTENSIONS.md E.3): lens diameter (0 = the pinhole of B.2) and the focus-plane distance
    aperture: float = 0.0
    focus_distance: float = 1.0


@dataclass(frozen=True)
class DirectionalLight:
    """``DirectionalLight { direction V3 color V3 }`` (SPEC A.3); ``direction`` is where the light travels."""

    direction: Vec3
    color: Vec3
    loc: FileLoc


@dataclass(frozen=True)
class PointLight:
    """``PointLight { position V3 color V3 [falloff F] }`` (SPEC A.3): arriving colour ``color / (1 + f d²)``."""

    position: Vec3
    color: Vec3
    falloff: float
    loc: FileLoc


@dataclass(frozen=True)
class SpotLight:
    """``SpotLight { position V3 direction V3 color V3 [falloff F] angle F [beamWidth F] }``
    (docs/EXTENSIONS.md E.1): a PointLight times the cone profile; angles in degrees from the axis."""

    position: Vec3
    direction: Vec3
    color: Vec3
    falloff: float
    angle: float
    beam_width: float
    loc: FileLoc


@dataclass(frozen=True)
class AreaLight:
    """``AreaLight { corner V3 edge1 V3 edge2 V3 color V3 [falloff F] [samples I] }`` (EXTENSIONS E.2):
    the parallelogram ``corner + s·edge1 + t·edge2``, ``s, t`` in [0, 1]."""

    corner: Vec3
    edge1: Vec3
    edge2: Vec3
    color: Vec3
    falloff: float
    samples: int
    loc: FileLoc


@dataclass(frozen=True)
class SphereLight:
    """``SphereLight { center V3 radius F color V3 [falloff F] [samples I] }`` (EXTENSIONS E.2)."""

    center: Vec3
    radius: float
    color: Vec3
    falloff: float
    samples: int
    loc: FileLoc


Light = DirectionalLight | PointLight | SpotLight | AreaLight | SphereLight


@dataclass(frozen=True)
class Background:
    """``Background { color V3 | ambientLight V3 | cubeMap NAME }`` (SPEC A.4), with the SPEC defaults."""

    color: Vec3 = (0.5, 0.5, 0.5)
    ambient_light: Vec3 = (0.0, 0.0, 0.0)
    cube_map: str | None = None
    cube_map_loc: FileLoc | None = None
    loc: FileLoc | None = None


# ------------------------------------------------------------------------------------------------------- media
@dataclass(frozen=True)
class Fog:
    """``Fog { color V3 density F [steps I] }`` (docs/EXTENSIONS.md E.8): a homogeneous medium filling the
    scene, extinction ``density`` per unit length, single-scattering albedo ``color``, ``steps`` light
    samples along each ray segment."""

    color: Vec3
    density: float
    steps: int
    loc: FileLoc
    #: Henyey-Greenstein asymmetry of the phase function (docs/EXTENSIONS.md E.8; 0: isotropic)
    g: float = 0.0


@dataclass(frozen=True, eq=False)
class VolumeBox:
    """What a ``Volume`` (EXTENSIONS E.9) and its description (:class:`.describe.VolumeDescription`) share:
    extinction ``density · grid(x)`` inside the box ``[box_min, box_max]``, albedo ``color``, ``steps``
    ray-marching steps across the box, the block's ``loc``."""

    density: float
    box_min: Vec3
    box_max: Vec3
    color: Vec3
    steps: int
    loc: FileLoc


@dataclass(frozen=True)
class Volume(VolumeBox):
    """``Volume { grid NAME density F min V3 max V3 [color V3] [steps I] }`` (EXTENSIONS E.9): a
    :class:`VolumeBox` with the Mitsuba ``.vol`` grid file ``grid`` (as written, at ``grid_loc``) stretched
    over it."""

    grid: str
    grid_loc: FileLoc
    #: Henyey-Greenstein asymmetry (docs/EXTENSIONS.md E.8, E.9; 0: isotropic)
    g: float = 0.0


Medium = Fog | Volume


# ---------------------------------------------------------------------------------------------------- materials
@dataclass(frozen=True)
class Noise:
    """``Noise { color V3 (twice) octaves I frequency F amplitude F }`` (SPEC A.5, B.4)."""

    color1: Vec3 = (0.0, 0.0, 0.0)
    color2: Vec3 = (0.0, 0.0, 0.0)
    octaves: int = 0
    frequency: float = 1.0
    amplitude: float = 1.0
    loc: FileLoc | None = None


#: docs/EXTENSIONS.md E.7: default ``bumpScale``, the height (world units) of grey 1 in a bump height field
BUMP_SCALE = 0.2


@dataclass(frozen=True)
class Solid:
    """``Wood`` / ``Turbulence`` / ``Veins { color V3 color V3 ... }`` (docs/EXTENSIONS.md E.6): a procedural solid
    texture on the marble's noise; ``kind`` is ``wood``, ``turbulence`` or ``veins``."""

    kind: str
    color1: Vec3
    color2: Vec3
    octaves: int = 4
    frequency: float = 1.0
    amplitude: float = 1.0
    scale: float = 1.0
    axis: Vec3 = (0.0, 1.0, 0.0)
    center: Vec3 = (0.0, 0.0, 0.0)
    loc: FileLoc | None = None


@dataclass(frozen=True)
class Material:
    """``Material`` / ``PhongMaterial`` (SPEC A.5). ``shininess`` is parsed but unused by a5soln (SPEC B.3)."""

    diffuse_color: Vec3 = (1.0, 1.0, 1.0)
    specular_color: Vec3 = (0.0, 0.0, 0.0)
    shininess: float = 0.0
    refraction_index: float = 0.0
    texture: str | None = None
    texture_loc: FileLoc | None = None
    bump: str | None = None
    noise: Noise | None = None
    loc: FileLoc | None = None
    #: glossy lobe (docs/EXTENSIONS.md E.4): GGX roughness alpha (0 = the mirror of B.3) and the children per hit
    roughness: float = 0.0
    glossy_samples: int = 1
    #: dispersion (docs/EXTENSIONS.md E.10): Cauchy's B in µm² of ``refractionIndex dispersion A B`` (then
    #: ``refraction_index`` is A); None when the index is a plain number
    dispersion: float | None = None
    #: docs/EXTENSIONS.md E.6: a procedural solid (Wood, Turbulence, Veins) as kd, in place of Noise
    solid: Solid | None = None
    #: docs/EXTENSIONS.md E.7 (used with -bump only): where ``bump`` was given, the height of grey 1 in world
    #: units (``bumpScale``), and the tangent-space ``normalMap``
    bump_loc: FileLoc | None = None
    bump_scale: float = BUMP_SCALE
    normal_map: str | None = None
    normal_map_loc: FileLoc | None = None
    #: docs/EXTENSIONS.md E.19, E.20: view-dependent images (the uv colour source) and the milled lobe
    btf: Btf | None = None
    milled: Milled | None = None
    #: docs/EXTENSIONS.md E.18 (used with -subsurface only): the ``subsurface`` block (converters/subsurface.py)
    subsurface: Subsurface | None = None


# ------------------------------------------------------------------------------------------------------ objects
@dataclass(frozen=True)
class Sphere:
    """``Sphere { center V3 radius F }``; ``material`` is the current ``MaterialIndex`` at parse time (A.6)."""

    center: Vec3
    radius: float
    material: int
    loc: FileLoc


@dataclass(frozen=True)
class Plane:
    """``Plane { normal V3 offset F }``: the points with ``P·normal = offset``, normal NOT normalised (A.6)."""

    normal: Vec3
    offset: float
    material: int
    loc: FileLoc


@dataclass(frozen=True)
class Triangle:
    """``Triangle { vertex0 V3 vertex1 V3 vertex2 V3 }`` (SPEC A.6), shaded with its face normal."""

    vertex0: Vec3
    vertex1: Vec3
    vertex2: Vec3
    material: int
    loc: FileLoc


@dataclass(frozen=True)
class TriangleMesh:
    """``TriangleMesh { obj_file NAME }`` (SPEC A.6); ``obj_file`` as written, resolved by
    :func:`.files.resolve_path`."""

    obj_file: str
    material: int
    loc: FileLoc
    obj_file_loc: FileLoc


Primitive = Sphere | Plane | Triangle | TriangleMesh


@dataclass(frozen=True)
class TransformOp:
    """One entry of a ``Transform`` block: ``kind`` is the keyword (``Translate``, ``Scale``, ``UniformScale``,
    ``XRotate``, ``YRotate``, ``ZRotate``, ``Rotate``, ``Matrix4f``) and ``values`` its numbers as written
    (``Rotate``: axis x y z then degrees; ``Matrix4f``: 16 numbers, column by column)."""

    kind: str
    values: tuple[float, ...]
    loc: FileLoc


@dataclass(frozen=True)
class Transform:
    """``Transform { <transform>* <object> }`` (SPEC A.6). ``matrix`` is the composed object-to-parent map
    ``M`` (post-multiplied keywords, ``Matrix4f`` pre-multiplied; see :mod:`.transforms`), kept with the
    ``ops`` it came from."""

    ops: tuple[TransformOp, ...]
    matrix: Matrix4
    child: Node
    loc: FileLoc

    @property
    def matrix_array(self) -> np.ndarray:
        """``matrix`` as a float64 (4, 4) array."""
        return np.array(self.matrix, dtype=np.float64)


@dataclass(frozen=True)
class Group:
    """``Group { numObjects I (MaterialIndex I | <object>)* }`` (SPEC A.6); ``children`` in file order."""

    num_objects: int
    children: tuple[Node, ...]
    loc: FileLoc


Node = Group | Transform | Sphere | Plane | Triangle | TriangleMesh


@dataclass(frozen=True, eq=False)
class Placed:
    """A primitive with its object-to-world matrix (the product of the enclosing ``Transform`` matrices);
    ``transformed``: some ``Transform`` encloses it (even one whose matrix is the identity: the binary then
    still maps its rays, which matters for signed zeros, :mod:`.octree`)."""

    primitive: Primitive
    to_world: np.ndarray
    transformed: bool = False
    #: The enclosing ``Transform`` blocks' keywords, outermost first, as ``(kind, values)`` pairs (for the
    #: binary's float32 matrices, :func:`.transforms.binary_chain`).
    levels: tuple[tuple[tuple[str, tuple[float, ...]], ...], ...] = ()


def iter_placed(obj: Node, to_world: np.ndarray | None = None, transformed: bool = False,
                levels: tuple = ()) -> Iterator[Placed]:
    """Depth-first, file-order walk: ``to_world = M_outer @ ... @ M_inner`` (SPEC A.6)."""
    m = np.eye(4) if to_world is None else to_world
    if isinstance(obj, Group):
        for child in obj.children:
            yield from iter_placed(child, m, transformed, levels)
    elif isinstance(obj, Transform):
        ops = tuple((op.kind, op.values) for op in obj.ops)
        yield from iter_placed(obj.child, m @ obj.matrix_array, True, (*levels, ops))
    else:
        yield Placed(obj, m, transformed, levels)


# ---------------------------------------------------------------------------------------------------- animation
@dataclass(frozen=True)
class Track:
    """One keyframed value (docs/EXTENSIONS.md E.11): ``target`` (``"Camera"``, ``"Light"``, ``"Material"``,
    ``"Transform"``), ``index`` (the light / material / Transform number; 0 for the camera), ``field`` (the
    keyword as written, or the Transform's keyword number as a string), ``interpolation``, ``times`` (seconds,
    increasing) and ``values`` (one tuple per key); evaluated by :func:`.keyframes.evaluate`."""

    target: str
    index: int
    field: str
    interpolation: str
    times: tuple[float, ...]
    values: tuple[tuple[float, ...], ...]
    loc: FileLoc


@dataclass(frozen=True)
class Animation:
    """``Animation { frames I fps F [shutter F] Track* }`` (EXTENSIONS E.11, E.12): frame ``f``
    (0 <= f < frames) shows time ``f / fps``; ``shutter`` (0..1) is the fraction of the frame interval the
    shutter stays open (E.12)."""

    frames: int
    fps: float
    shutter: float
    tracks: tuple[Track, ...]
    loc: FileLoc

    def frame_time(self, frame: int) -> float:
        """``frame / fps`` (seconds)."""
        return frame / self.fps


# -------------------------------------------------------------------------------------------------------- scene
@dataclass(frozen=True)
class Scene:
    """A parsed scene file (SPEC A.1). ``warnings`` lists ``(loc, message)`` for input the sample solution
    accepted silently but that probably does not mean what it says (repeated blocks, no lights, ...)."""

    path: str
    camera: Camera
    lights: tuple[Light, ...] = ()
    background: Background = field(default_factory=Background)
    materials: tuple[Material, ...] = ()
    root: Group = field(default_factory=lambda: Group(0, (), FileLoc("<none>", 1, 1)))
    warnings: tuple[tuple[FileLoc, str], ...] = ()
    #: the participating medium (docs/EXTENSIONS.md E.8, E.9); None in course scenes
    medium: Medium | None = None
    #: ``Animation { ... }`` (docs/EXTENSIONS.md E.11; :mod:`.keyframes`), None for a still scene
    animation: Animation | None = None

    @property
    def base_dir(self) -> Path:
        """The scene file's folder (relative names resolve here first), or the cwd for ``<string>``."""
        return Path.cwd() if self.path.startswith("<") else Path(self.path).parent

    @property
    def ambient(self) -> Vec3:
        """The ambient light the renderer uses: (1, 1, 1) when there are no lights (SPEC A.1), else the Background's."""
        return (1.0, 1.0, 1.0) if not self.lights else self.background.ambient_light

    @property
    def objects(self) -> tuple[Placed, ...]:
        """Every primitive with its object-to-world matrix, in file order (groups flattened)."""
        return tuple(iter_placed(self.root))

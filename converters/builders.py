"""Typed builders: the mutable state the grammar's rules fill while a block is read (SPEC A.1-A.6, EXTENSIONS).

Each builder has the fields of one frozen entity of :mod:`.model`, with the same defaults (SPEC A's; the
material's builder takes them from the model), and ``build(loc)`` (``build()``) returns that entity; a rule
(:data:`.tokens.Rule`) sets fields. Where a block has required fields (``Animation``'s ``frames`` and ``fps``,
A.1's camera and ``Group``) the builder keeps None until they are read and the parser, which reports their
absence at a position, builds the entity. :class:`GroupState` is the parser's "current material" of A.6;
:class:`SceneBuilder` collects the top-level blocks of A.1.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from a5mi.converters.errors import FileLoc
from a5mi.converters.lexer import Token
from a5mi.converters.model import (
    Animation,
    Background,
    Camera,
    Group,
    Light,
    Material,
    Medium,
    Noise,
    PointLight,
    Solid,
    Track,
    Vec3,
)

_ZERO: Vec3 = (0.0, 0.0, 0.0)


@dataclass
class PointLightBuilder:
    """``PointLight`` (A.3): ``position`` and ``color`` None until given (then 0 0 0, with a warning)."""

    position: Vec3 | None = None
    color: Vec3 | None = None
    falloff: float = 0.0

    def build(self, loc: FileLoc) -> PointLight:
        return PointLight(self.position or _ZERO, self.color or _ZERO, self.falloff, loc)


@dataclass
class BackgroundBuilder:
    """``Background`` (A.4) with the SPEC defaults."""

    color: Vec3 = (0.5, 0.5, 0.5)
    ambient_light: Vec3 = _ZERO
    cube_map: str | None = None
    cube_map_loc: FileLoc | None = None

    def build(self, loc: FileLoc) -> Background:
        return Background(self.color, self.ambient_light, self.cube_map, self.cube_map_loc, loc)


@dataclass
class NoiseBuilder:
    """``Noise`` (A.5, B.4): up to two colours, the missing ones 0 0 0."""

    colors: list[Vec3] = field(default_factory=list)
    octaves: int = 0
    frequency: float = 1.0
    amplitude: float = 1.0

    def build(self, loc: FileLoc) -> Noise:
        c = self.colors + [_ZERO] * (2 - len(self.colors))
        return Noise(c[0], c[1], self.octaves, self.frequency, self.amplitude, loc)


@dataclass
class SolidBuilder:
    """``Wood`` / ``Turbulence`` / ``Veins`` (EXTENSIONS E.6): ``block`` as written (for messages), ``kind`` the
    ``a5_solid`` kind; ``given``: the keywords read besides ``color`` (each at most once)."""

    block: str
    kind: str
    colors: list[Vec3] = field(default_factory=list)
    given: set[str] = field(default_factory=set)
    octaves: int = 4
    frequency: float = 1.0
    amplitude: float = 1.0
    scale: float = 1.0
    axis: Vec3 = (0.0, 1.0, 0.0)
    center: Vec3 = _ZERO

    def build(self, loc: FileLoc) -> Solid:
        return Solid(self.kind, self.colors[0], self.colors[1], self.octaves, self.frequency, self.amplitude,
                     self.scale, self.axis, self.center, loc)


class MaterialBuilder:
    """``Material`` / ``PhongMaterial`` (A.5; EXTENSIONS E.4, E.6, E.7, E.10, E.18-E.20) while it is read: an
    attribute per field of :class:`.model.Material` (the one declaration of the fields and their defaults),
    set by the rules of :mod:`.a5_parser` (the course's keywords), :mod:`.ext_parser` and :mod:`.surface_ext`
    (the extensions'); a name the model lacks is an ``AttributeError``."""

    __slots__ = tuple(f.name for f in fields(Material))

    def __init__(self, loc: FileLoc) -> None:
        for f in fields(Material):
            setattr(self, f.name, f.default)
        self.loc = loc

    def build(self) -> Material:
        return Material(**{name: getattr(self, name) for name in self.__slots__})


@dataclass
class AnimationBuilder:
    """``Animation`` (EXTENSIONS E.11): ``frames`` and ``fps`` None until given (both required)."""

    frames: int | None = None
    fps: float | None = None
    shutter: float = 0.0
    tracks: list[Track] = field(default_factory=list)


@dataclass
class GroupState:
    """The parser's global "current material" (A.6: sequential, survives nested groups and later ``Group``
    blocks), the material count it is checked against and the nesting depth of the object being parsed."""

    num_materials: int | None = None
    current: int | None = None
    materials_line: int | None = None  # line of the Materials block in effect
    depth: int = 0  # Group / Transform nesting


@dataclass
class SceneBuilder:
    """The top-level blocks of A.1 read so far; ``blocks``: the keyword token of each kind's last block;
    ``group_materials``: the ``Materials`` list the last ``Group`` was parsed with."""

    camera: Camera | None = None
    lights: tuple[Light, ...] = ()
    background: Background = field(default_factory=Background)
    materials: tuple[Material, ...] | None = None
    root: Group | None = None
    medium: Medium | None = None
    animation: Animation | None = None
    group_materials: tuple[Material, ...] | None = None
    blocks: dict[str, Token] = field(default_factory=dict)
    group: GroupState = field(default_factory=GroupState)

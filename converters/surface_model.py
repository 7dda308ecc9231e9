"""The model of ``btf`` and ``milled`` in ``Material`` (docs/EXTENSIONS.md E.19, E.20): frozen values, no rules.

Kept apart from :mod:`.surface_ext` (their rules, description and dicts) so that :mod:`.model` and
:mod:`.builders` can name them without importing the grammar.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from a5mi.converters.errors import FileLoc

Vec3 = tuple[float, float, float]
PATTERNS: Final = ("straight", "circular")


@dataclass(frozen=True)
class Btf:
    """``btf { images NAME elevations F+ azimuths F+ }`` (E.19): the image of ``(i, j)`` is ``images % (i, j)``."""

    images: str
    images_loc: FileLoc
    elevations: tuple[float, ...]
    azimuths: tuple[float, ...]
    loc: FileLoc

    def file_name(self, i: int, j: int) -> str:
        return self.images % (i, j)


@dataclass(frozen=True)
class Milled:
    """``milled { alphaU F alphaV F [color V3] pattern P axis V3 [center V3] }`` (E.20): Ward's anisotropic lobe
    of reflectance ``color`` on the tangent field ``pattern``."""

    alpha_u: float
    alpha_v: float
    color: Vec3
    pattern: str
    axis: Vec3
    center: Vec3
    loc: FileLoc

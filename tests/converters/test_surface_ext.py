"""The grammar of a ``Material``'s ``btf`` and ``milled`` blocks (docs/EXTENSIONS.md E.19, E.20;
converters/surface_ext.py): each error at the offending keyword or value, as the course grammar's errors are."""

from __future__ import annotations

from conftest import positioned_error_test
from helpers import SCENES

SCENE = """PerspectiveCamera {{ center 0 3 3 direction 0 -1 -1 up 0 1 0 angle 40 }}
Lights {{ numLights 1 DirectionalLight {{ direction 0 -1 0 color 1 1 1 }} }}
Background {{ color 0 0 0 ambientLight 0 0 0 }}
Materials {{ numMaterials 1 Material {{ diffuseColor 1 1 1 {block} }} }}
Group {{ numObjects 1 MaterialIndex 0 TriangleMesh {{ obj_file {tile} }} }}
"""


def _material(block: str) -> str:
    """A scene whose one material (on a tile with uv) ends with ``block``."""
    return SCENE.format(block=block, tile=SCENES / "meshes" / "tile.obj")


test_surface_errors_are_positioned = positioned_error_test(_material, [
    # E.19
    ("btf { images ^tex/btf/silk_%d.bmp elevations 0 azimuths 0 }", "needs two integer conversions"),
    ("btf { images a_%d_%d elevations ^azimuths 0 }", "expected a number after 'elevations'"),
    ("btf { images a_%d_%d ^elevations 0 30 20 azimuths 0 }", "btf elevations must increase strictly"),
    ("btf { images a_%d_%d elevations 0 ^azimuths 0 360 }", "btf azimuths must increase strictly within [0, 360)"),
    ("btf { images a_%d_%d elevations 0 azimuths 0 } ^btf", "a Material takes one 'btf'"),
    # E.20
    ("milled { alphaU ^0 alphaV 0.3 pattern straight axis 1 0 0 }", "milled alphaU must be in (0, 1]"),
    ("milled { alphaU 0.1 alphaV 0.3 pattern ^zigzag axis 1 0 0 }", "pattern must be straight or circular"),
    ("milled { alphaU 0.1 alphaV 0.3 pattern straight ^axis 0 0 0 }", "axis must not be the zero vector"),
    ("milled { alphaU 0.1 alphaV 0.3 pattern straight axis 1 0 0 ^center 0 0 0 }", "only used by pattern circular"),
    ("milled { alphaU 0.1 ^alphaU 0.3 }", "milled gives 'alphaU' twice"),
])

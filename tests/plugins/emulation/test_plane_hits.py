"""The plane set tested unrolled and in a loop (plugins/emulation/plane_hits.py): the same bits.

A set of at most ``UNROLL`` entries is tested entry by entry with kernel scalars and each entry's own kind's code;
a larger one in a loop over the device arrays with a per-lane ``if`` on the kind. Both read the same arithmetic,
so a scene of every kind (a plane, a plane inside a ``Transform``, a sphere, a non-similarity sphere; glass, a
texture, three lights, one of them directional with a zero component) renders to the same image either way,
with the sample solution's stale texture coordinates too (``-quirks binary``: the scene-order test ``before``).
"""

from __future__ import annotations

import numpy as np
from helpers import SCENES

KINDS = """PerspectiveCamera { center 0 1.5 8 direction 0 -0.2 -1 up 0 1 0 angle 40 }
Lights { numLights 3
  DirectionalLight { direction 0.5 -1 0 color 0.3 0.3 0.3 }
  PointLight { position -1 3 2 color 0.5 0.5 0.5 }
  PointLight { position 2 2 3 color 0.3 0.4 0.3 falloff 0.05 } }
Background { color 0.2 0.1 0.3 ambientLight 0.2 0.2 0.2 }
Materials { numMaterials 5
  Material { diffuseColor 0.1 0.1 0.1 specularColor 0.9 0.9 0.9 refractionIndex 1.4 }
  Material { diffuseColor 0.9 0.2 0.1 specularColor 0.3 0.3 0.3 }
  Material { diffuseColor 0.5 0.5 0.5 texture tex/checker.bmp }
  Material { diffuseColor 0.2 0.7 0.3 specularColor 0.5 0.5 0.5 }
  Material { diffuseColor 0.8 0.8 0.2 } }
Group { numObjects 8
  MaterialIndex 2 Transform { Translate 0 0.3 -2.5 UniformScale 1.2 TriangleMesh { obj_file meshes/icosphere.obj } }
  MaterialIndex 2 Sphere { center 0 0.3 0 radius 0.7 }
  MaterialIndex 3 Plane { normal 0 1 0 offset -1 }
  MaterialIndex 1 Transform { Translate 2.5 0 -2 XRotate 70 Plane { normal 0 1 0 offset 0 } }
  MaterialIndex 0 Sphere { center -1.5 -0.5 1.5 radius 0.5 }
  MaterialIndex 4 Transform { Translate -2.2 0.3 -1 Scale 0.6 1.4 0.6 ZRotate 30 Sphere { center 0 0 0 radius 1 } }
  MaterialIndex 0 Transform { Translate 1.6 -0.4 1.2 Scale 0.5 0.3 0.5 Sphere { center 0 0 0 radius 1 } }
  MaterialIndex 1 Transform { Translate 1 0.5 -3 UniformScale 0.7 TriangleMesh { obj_file meshes/box.obj } }
}
"""
OPTIONS = {"width": 48, "height": 48, "shadows": True, "bounces": 4}


def test_the_set_of_every_kind_is_unrolled_in_scene_order(variant: str) -> None:
    import drjit as dr

    from a5mi.converters.a5_parser import parse_text
    from a5mi.converters.describe import describe
    from a5mi.plugins.emulation.planes import PLACED_PLANE, PLANE, SPHERE, WORLD_SPHERE
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import build_scene

    scene = build_scene(describe(parse_text(KINDS, str(SCENES / "x.txt"))), RenderOptions(**OPTIONS))
    entries = scene.integrator()._planes.entries
    assert [e.kind for e in entries] == [SPHERE, PLANE, PLACED_PLANE, SPHERE, SPHERE, SPHERE]
    assert [None if e.world is None else bool(e.world[0]) for e in entries] == [True, None, None, True, False, False]
    assert scene.integrator()._planes.objects.kind.numpy().tolist() == [WORLD_SPHERE, PLANE, PLACED_PLANE, WORLD_SPHERE,
                                                                 SPHERE, SPHERE]
    worlds = [e.world for e in entries if e.world is not None]
    values = [v for e in entries for v in (*e.n, e.offset, *e.a, *e.centre)] + worlds
    assert all(v.state == dr.VarState.Evaluated and dr.width(v) == 1 for v in values)  # kernel inputs, not literals


def test_unrolled_set_and_loop_render_the_same_bits(render_text, monkeypatch) -> None:  # noqa: ANN001
    from a5mi.plugins.emulation import planes

    path = str(SCENES / "x.txt")
    unrolled = render_text(KINDS, path, quirks="binary", **OPTIONS)
    assert (unrolled != render_text(KINDS, path, **OPTIONS)).any()   # the stale uv is in the image
    monkeypatch.setattr(planes, "UNROLL", 0)
    assert np.array_equal(render_text(KINDS, path, quirks="binary", **OPTIONS), unrolled)

"""A warm RenderSession (a5mi/render/session.py): the scene it drops is freed before the next build, without a
full garbage collection when reference counting frees it, and the next render equals a fresh process's."""

from __future__ import annotations

from pathlib import Path

import numpy as np

SCENE = """
PerspectiveCamera {{ center 0 1 8 direction 0 -0.1 -1 up 0 1 0 angle 30 }}
Lights {{ numLights 1 DirectionalLight {{ direction -0.5 -0.3 -1 color 0.9 0.9 0.9 }} }}
Background {{ color 0.1 0.2 0.3 ambientLight {ambient} }}
Materials {{ numMaterials 2
  PhongMaterial {{ diffuseColor 1 0 0 specularColor 0.5 0.5 0.5 }}
  PhongMaterial {{ diffuseColor 0 1 0 }} }}
Group {{ numObjects 3
  MaterialIndex 0 Sphere {{ center 0 0 0 radius 1 }}
  MaterialIndex 1 Sphere {{ center 1.5 0.5 -1 radius 0.8 }}
  MaterialIndex 1 Plane {{ normal 0 1 0 offset -1.2 }} }}
"""


def _desc(folder: Path, name: str, ambient: str):
    from a5mi.render.session import describe_file

    path = folder / name
    path.write_text(SCENE.format(ambient=ambient))
    return describe_file(str(path))[0]


def test_a_dropped_scene_is_freed_without_a_full_collection(tmp_path: Path, variant: str, monkeypatch) -> None:
    """The second scene replaces the first (max_scenes=1): nothing else holds the first, so no gc.collect();
    the second render launches cached kernels only (the freed plugins' registry IDs reused) and equals the
    same scene rendered by a fresh session."""
    from a5mi.render import session as sessions
    from a5mi.render.options import RenderOptions

    collected: list[int] = []
    monkeypatch.setattr(sessions.gc, "collect", lambda *a: collected.append(1) or 0)
    options = RenderOptions(width=20, height=20, shadows=True, bounces=3, jitter=True, filter=True)
    warm = sessions.RenderSession()
    warm.render(_desc(tmp_path, "a.txt", "0.2 0.2 0.2"), options)
    second = _desc(tmp_path, "b.txt", "0.3 0.1 0.2")
    b = warm.render(second, options)
    assert collected == [] and warm.scenes_built == 2
    assert b.kernels["compiled"] == 0 and b.kernels["memory"] > 0, b.kernels
    assert np.array_equal(b.image, sessions.render(second, options).image)


def test_a_scene_still_held_is_collected_for(tmp_path: Path, variant: str, monkeypatch) -> None:
    """When a plugin of the dropped scene outlives the drop (held here, as a reference cycle would hold it), the
    session falls back to a full gc.collect() before building the next scene."""
    import gc

    from a5mi.render import session as sessions
    from a5mi.render.options import RenderOptions

    collected: list[int] = []
    collect = gc.collect
    monkeypatch.setattr(sessions.gc, "collect", lambda *a: collected.append(1) or collect(*a))
    options = RenderOptions(width=12, height=12)
    warm = sessions.RenderSession()
    scene, integrator, _ = warm.integrator(_desc(tmp_path, "a.txt", "0.2 0.2 0.2"), options)
    del scene
    warm.render(_desc(tmp_path, "b.txt", "0.3 0.1 0.2"), options)
    assert collected == [1]
    assert integrator is not None

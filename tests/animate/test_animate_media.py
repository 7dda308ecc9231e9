"""Keyframed area-light colours and media (docs/EXTENSIONS.md E.2, E.8, E.9, E.11): the warm scene's frame
equals a fresh still render of the scene at that time, and differs from frame 0."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from a5mi.converters import keyframes
from a5mi.converters.a5_parser import parse_text
from a5mi.converters.errors import SceneError
from a5mi.render.options import RenderOptions

AREA = """PerspectiveCamera { center 0 1 8 direction 0 -0.1 -1 up 0 1 0 angle 35 }
Lights { numLights 2
  AreaLight { corner -1 4 -1 edge1 2 0 0 edge2 0 0 2 color 0.9 0.9 0.9 samples 4 }
  SphereLight { center 3 3 2 radius 0.5 color 0.5 0.5 0.5 samples 4 }
}
Background { color 0.1 0.1 0.1 ambientLight 0 0 0 }
Materials { numMaterials 1 Material { diffuseColor 0.8 0.8 0.8 } }
Group { numObjects 2 MaterialIndex 0
  Plane { normal 0 1 0 offset -1 }
  Sphere { center 0 0 0 radius 1 }
}
Animation { frames 2 fps 1
  Track { Light 0 color linear key 0 0.9 0.9 0.9 key 1 0.1 0.8 0.2 }
  Track { Light 1 color linear key 0 0.5 0.5 0.5 key 1 1 0.2 0.2 }
}
"""


@pytest.mark.parametrize("light", [0, 1], ids=["AreaLight", "SphereLight"])
def test_area_and_sphere_light_colour_tracks_animate(mi, light: int) -> None:
    """A colour track on an AreaLight / SphereLight (E.2) changes the frame: frame 1 equals the fresh still
    render of scene_at(1) (the light at its last key) and differs from frame 0; no kernel is compiled."""
    from a5mi.animate.warm import FrameTiming, WarmScene
    from a5mi.converters.describe import describe
    from a5mi.render.session import render

    text = AREA.replace(f"  Track {{ Light {1 - light}", "  # Track { Light")  # only this light's track
    text = "\n".join(line for line in text.splitlines() if not line.startswith("  # Track"))
    scene = parse_text(text)
    opts = RenderOptions(width=24, height=24, shadows=True, spp=2)
    warm = WarmScene(scene, opts)
    first = warm.render(0).image
    later = FrameTiming()
    second = warm.render(1, later).image
    assert later.kernels.get("compiled", 0) == 0, later.kernels
    fresh = render(describe(keyframes.scene_at(scene, 1.0)), opts).image
    assert np.array_equal(second, fresh)
    assert not np.array_equal(first, second)
    assert np.array_equal(warm.render(0).image, first)


FOG = """PerspectiveCamera { center 0 1 8 direction 0 -0.1 -1 up 0 1 0 angle 35 }
Lights { numLights 1 PointLight { position 2 4 3 color 0.9 0.9 0.9 } }
Background { color 0.3 0.3 0.4 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 1 Material { diffuseColor 0.8 0.8 0.8 } }
Group { numObjects 2 MaterialIndex 0
  Plane { normal 0 1 0 offset -1 }
  Sphere { center 0 0 0 radius 1 }
}
MEDIUM
Animation { frames 3 fps 1 TRACKS }
"""


def _scene(medium: str, tracks: str, folder: Path | None = None) -> str:
    text = FOG.replace("MEDIUM", medium).replace("TRACKS", tracks)
    if folder is not None:
        (folder / "s.txt").write_text(text)
    return text


def _warm_frames(scene, opts: RenderOptions, frames: tuple[int, ...]) -> tuple[dict[int, np.ndarray], dict[str, int]]:
    from a5mi.animate.warm import FrameTiming, WarmScene

    warm = WarmScene(scene, opts)
    images = {frames[0]: warm.render(frames[0]).image}
    later = FrameTiming()
    for f in frames[1:]:
        images[f] = warm.render(f, later).image
    return images, later.kernels


def test_fog_density_and_colour_tracks_animate(mi) -> None:
    """E.8 keyframed: ``Track { Fog density ... }`` and ``Fog color``; frame 2 (after 0 and 1) equals the fresh
    still render of scene_at(2) and differs from frame 0, with no kernel compiled after the first frame."""
    from a5mi.converters.describe import describe
    from a5mi.render.session import render

    tracks = ("Track { Fog density linear key 0 0.05 key 2 0.4 } "
              "Track { Fog color linear key 0 1 1 1 key 2 0.2 0.4 0.9 }")
    scene = parse_text(_scene("Fog { color 1 1 1 density 0.05 steps 4 }", tracks))
    opts = RenderOptions(width=20, height=20, shadows=True)
    images, kernels = _warm_frames(scene, opts, (0, 1, 2, 0))
    assert kernels.get("compiled", 0) == 0, kernels
    assert scene_at_density(scene, 2.0) == 0.4
    fresh = render(describe(keyframes.scene_at(scene, 2.0)), opts).image
    assert np.array_equal(images[2], fresh)
    assert not np.array_equal(images[0], images[2])
    still = render(describe(parse_text(_scene("Fog { color 1 1 1 density 0.05 steps 4 }", ""))), opts).image
    assert np.array_equal(images[0], still)


def scene_at_density(scene, t: float) -> float:
    return keyframes.scene_at(scene, t).medium.density


def _grids(folder: Path, count: int) -> list[np.ndarray]:
    """``folder/puff_%03d.vol``: a Gaussian puff rising through the box, one grid per frame."""
    from a5mi.converters.volgrid import write_vol

    z, y, x = np.meshgrid(*(np.arange(8) + 0.5,) * 3, indexing="ij")
    out = []
    for f in range(count):
        g = np.exp(-((x - 4) ** 2 + (y - 2 - 2 * f) ** 2 + (z - 4) ** 2) / 4.0).astype(np.float32)[..., None]
        write_vol(folder / f"puff_{f:03d}.vol", g)
        out.append(g)
    return out


def test_volume_grid_per_frame_and_density_track(mi, tmp_path: Path) -> None:
    """E.9 keyframed: ``grid "puff_%03d.vol"`` reads frame f's grid at frame f (the frame nearest t), and a
    density track scales it; each frame equals the fresh still render of scene_at(f / fps) (which names that
    frame's file), frames differ, nothing is compiled after the first; the still scene is frame 0's grid."""
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.render.session import render

    _grids(tmp_path, 3)
    volume = "Volume { grid puff_%03d.vol density 3 min -2 -1 -2 max 2 3 2 steps 8 }"
    _scene(volume, "Track { Volume density linear key 0 3 key 2 5 }", tmp_path)
    scene = parse_file(tmp_path / "s.txt")
    assert keyframes.scene_at(scene, 1.4).medium.grid == "puff_001.vol"
    assert keyframes.scene_at(scene, 1.6).medium.grid == "puff_002.vol"
    opts = RenderOptions(width=20, height=20, shadows=True, spp=2)
    images, kernels = _warm_frames(scene, opts, (0, 1, 2, 0))
    assert kernels.get("compiled", 0) == 0, kernels
    for f in (1, 2):
        fresh = render(describe(keyframes.scene_at(scene, float(f))), opts).image
        assert np.array_equal(images[f], fresh), f
    assert len({images[f].tobytes() for f in (0, 1, 2)}) == 3
    (tmp_path / "still.txt").write_text((tmp_path / "s.txt").read_text().split("Animation")[0])
    assert np.array_equal(render(describe(parse_file(tmp_path / "still.txt")), opts).image, images[0])


def test_grid_frame_names() -> None:
    from a5mi.converters.volgrid import frame_name, is_pattern

    assert frame_name("smoke_%03d.vol", 7) == "smoke_007.vol"
    assert frame_name("d/s%d.vol", 1234) == "d/s1234.vol"
    assert frame_name("plain.vol", 3) == "plain.vol" and not is_pattern("a%03d_%03d.vol")


@pytest.mark.parametrize(("medium", "track", "message"), [
    ("", "Track { Fog density linear key 0 1 }", "the scene has no Fog block to keyframe"),
    ("Fog { color 1 1 1 density 0.1 }", "Track { Volume density linear key 0 1 }",
     "the scene has no Volume block to keyframe"),
    ("Fog { color 1 1 1 density 0.1 }", "Track { Fog density linear key 0 0.1 key 1 -0.5 }",
     "keyframed Fog density -0.5 is negative at this time (key time 1)"),
    ("Fog { color 1 1 1 density 0.1 }", "Track { Fog color linear key 0 1 1 1 key 1 1 2 1 }",
     "keyframed Fog color must stay in [0, 1], found 1 2 1 at this time (key time 1)"),
    ("Fog { color 1 1 1 density 0.1 }", "Track { Fog steps linear key 0 1 }",
     "expected density, color after 'Fog', found 'steps'"),
])
def test_medium_track_errors_are_positioned(medium: str, track: str, message: str) -> None:
    """Errors at the track's field keyword (E.11)."""
    text = _scene(medium, track)
    with pytest.raises(SceneError) as err:
        parse_text(text, "m.txt")
    line = text[:text.index("Track {")].count("\n") + 1
    start = text.index("Track {")
    col = start - text.rfind("\n", 0, start) + len("Track { ") + len(track.split()[2]) + 1
    assert str(err.value) == f"m.txt:{line}:{col}: error: {message}"

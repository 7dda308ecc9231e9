"""Keyframed animation and motion blur (docs/EXTENSIONS.md E.11, E.12): keyframes against hand values,
the parser's positioned errors, the warm scene against fresh still renders, the kernel count per frame, motion
blur against the analytic coverage, frames on Dask and ``--resume``."""

from __future__ import annotations

import dataclasses
import math
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import ROOT

from a5mi.converters import keyframes
from a5mi.converters.a5_parser import parse_text
from a5mi.converters.errors import SceneError
from a5mi.render.options import RenderOptions

BOX = ROOT / "scenes" / "meshes" / "box.obj"

STILL = """PerspectiveCamera { center 0 1 10 direction 0 -0.1 -1 up 0 1 0 angle 35 aperture 0.2 focusDistance 10 }
Lights { numLights 3
  PointLight { position -3 5 4 color 0.8 0.8 0.8 falloff 0.01 }
  DirectionalLight { direction 0.5 -1 -0.5 color 0.3 0.3 0.3 }
  SpotLight { position 0 6 0 direction 0 -1 0 color 1 1 1 angle 40 }
}
Background { color 0.2 0.3 0.5 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 3
  Material { diffuseColor 0.8 0.8 0.8 }
  Material { diffuseColor 0.9 0.2 0.1 specularColor 0.3 0.3 0.3 }
  Material { diffuseColor 0.1 0.5 0.9 }
}
Group { numObjects 5
  MaterialIndex 0
  Transform { Translate 0 0 0 Plane { normal 0 1 0 offset -1 } }
  MaterialIndex 1
  Transform { Translate 0 0 0 Sphere { center 0 0 0 radius 1 } }
  Transform { Translate 2 0 0 Scale 0.5 1 0.5 Sphere { center 0 0 0 radius 1 } }
  MaterialIndex 2
  Transform { Translate -2 0 0 YRotate 0 TriangleMesh { obj_file BOX } }
  Transform { Translate 0 0 -3 Triangle { vertex0 -3 -1 0 vertex1 3 -1 0 vertex2 0 3 0 } }
}
""".replace("BOX", str(BOX))

#: Every kind of track: camera (with a focus pull), the three light kinds, materials, every primitive.
TRACKS = """Animation { frames 12 fps 12 SHUTTER
  Track { Camera center smooth key 0 0 1 10 key 1 1 1.5 9 }
  Track { Camera focusDistance linear key 0 10 key 1 5 }
  Track { Camera direction linear key 0 0 -0.1 -1 key 1 0.1 -0.15 -1 }
  Track { Light 0 position linear key 0 -3 5 4 key 1 3 5 4 }
  Track { Light 0 color linear key 0 0.8 0.8 0.8 key 1 0.2 0.9 0.2 }
  Track { Light 1 direction linear key 0 0.5 -1 -0.5 key 1 -0.5 -1 0.2 }
  Track { Light 2 direction smooth key 0 0 -1 0 key 1 0.3 -1 0 }
  Track { Material 1 diffuseColor linear key 0 0.9 0.2 0.1 key 1 0.1 0.9 0.2 }
  Track { Material 0 specularColor linear key 0 0 0 0 key 1 0.5 0.5 0.5 }
  Track { Material 2 diffuseColor linear key 0 0.1 0.5 0.9 key 1 0.9 0.5 0.1 }
  Track { Transform 0 0 linear key 0 0 0 0 key 1 0 -0.5 0 }
  Track { Transform 1 0 linear key 0 0 0 0 key 1 0 1 0 }
  Track { Transform 2 1 smooth key 0 0.5 1 0.5 key 1 0.3 1.5 0.3 }
  Track { Transform 3 1 linear key 0 0 key 1 90 }
  Track { Transform 4 0 linear key 0 0 0 -3 key 1 1 0 -3 }
}
"""


def animated(shutter: str = "") -> str:
    return STILL + TRACKS.replace("SHUTTER", shutter)


# ------------------------------------------------------------------------------------------ keyframes, parser
def _track(interp: str, keys: str):
    scene = parse_text(STILL + f"Animation {{ frames 2 fps 1 Track {{ Camera aperture {interp} {keys} }} }}")
    return scene.animation.tracks[0]


def test_linear_keys_against_hand_values() -> None:
    tr = _track("linear", "key 1 10 key 3 20 key 4 0")
    assert keyframes.evaluate(tr, 0.0) == (10.0,)     # held before the first key
    assert keyframes.evaluate(tr, 1.0) == (10.0,)
    assert keyframes.evaluate(tr, 2.5) == (17.5,)     # 10 + (20 - 10) * 0.75
    assert keyframes.evaluate(tr, 3.0) == (20.0,)
    assert keyframes.evaluate(tr, 3.25) == (15.0,)    # 20 + (0 - 20) * 0.25
    assert keyframes.evaluate(tr, 9.0) == (0.0,)      # held after the last key


def test_smooth_keys_against_hand_values() -> None:
    two = _track("smooth", "key 0 10 key 2 30")
    # two keys: smoothstep, 10 + 20 (3 s^2 - 2 s^3); s = 0.25 -> 0.15625
    assert keyframes.evaluate(two, 0.5) == pytest.approx((13.125,), abs=1e-12)
    assert keyframes.evaluate(two, 1.0) == pytest.approx((20.0,), abs=1e-12)
    three = _track("smooth", "key 0 0 key 1 10 key 3 10")
    # inner tangent m1 = (10 - 0) / (3 - 0) = 10/3; on [0, 1] at s = 0.5:
    # h00 0 + h10 0 + h01 10 + h11 * 1 * m1 = 0.5 * 10 - 0.125 * 10/3
    assert keyframes.evaluate(three, 0.5) == pytest.approx((5.0 - 0.125 * 10 / 3,), abs=1e-12)
    # on [1, 3] at s = 0.5: h00 10 + h10 * 2 * m1 + h01 10 = 5 + 0.125 * 2 * 10/3 + 5
    assert keyframes.evaluate(three, 2.0) == pytest.approx((10.0 + 0.25 * 10 / 3,), abs=1e-12)
    assert keyframes.evaluate(three, 1.0) == (10.0,)


def test_scene_at_recomposes_transforms() -> None:
    scene = parse_text(animated())
    at = keyframes.scene_at(scene, 0.5)
    m = at.objects[3].to_world  # the mesh: Translate -2 0 0, YRotate 45
    c, s = math.cos(math.radians(45)), math.sin(math.radians(45))
    np.testing.assert_allclose(m[:3, :3], [[c, 0, s], [0, 1, 0], [-s, 0, c]], atol=1e-12)
    np.testing.assert_allclose(m[:3, 3], [-2, 0, 0])
    assert at.lights[0].position == (0.0, 5.0, 4.0)
    assert at.camera.focus_distance == 7.5
    assert keyframes.scene_at(scene, 0.0).objects[3].to_world.tolist() == scene.objects[3].to_world.tolist()


def test_scene_without_animation_is_todays_scene() -> None:
    still = parse_text(STILL)
    assert still.animation is None
    with_block = parse_text(STILL + "Animation { frames 3 fps 24 }")
    assert dataclasses.replace(with_block, animation=None) == still
    assert keyframes.scene_at(still, 1.0) is still


def track(body: str) -> str:
    """An Animation block of 3 frames at 24 fps holding the one Track ``body``."""
    return f"Animation {{ frames 3 fps 24 Track {{ {body} }} }}"


@pytest.mark.parametrize(("tail", "where", "message"), [
    ("Animation { fps 24 }", "23:1", "Animation needs 'frames'"),
    ("Animation { frames 0 fps 24 }", "23:20", "frames must be between 1"),
    ("Animation { frames 3 fps 24 shutter 2 }", "23:29", "shutter must be between 0 and 1"),
    (track("Light 7 color linear key 0 1 1 1"), "23:45", "Light 7 out of range"),
    (track("Light 1 position linear key 0 1 1 1"), "23:45", "is a DirectionalLight: it has no keyframable 'position'"),
    (track("Camera center linear key 1 0 0 1 key 1 0 0 2"), "23:70", "key times must increase"),
    (track("Camera center cubic key 0 0 0 1"), "23:51", "expected linear or smooth"),
    (track("Transform 3 1 linear key 0 1 2 3"), "23:49",
     "Transform 3 keyword 1 is YRotate: each key needs 1 numbers, found 3"),
    (track("Transform 9 0 linear key 0 1"), "23:49", "Transform 9 out of range"),
    (track("Transform 1 0 linear key 0 0 0 0 key 1 x"), "23:76", "expected a number after 'key', found 'x'"),
    (track("Camera angle linear key 0 30 key 1 200"), "23:44", "camera angle 200 is outside"),
    (track("Camera zoom linear key 0 1"), "23:44", "expected center, direction"),
])
def test_parser_errors_are_positioned(tail: str, where: str, message: str) -> None:
    with pytest.raises(SceneError) as err:
        parse_text(STILL + tail, "s.txt")
    assert str(err.value).startswith(f"s.txt:{where}: error: "), str(err.value)
    assert message in str(err.value)


# ---------------------------------------------------------------------------------------------- warm scene
def test_warm_frames_equal_fresh_still_renders_and_compile_nothing(mi) -> None:
    """Frame 0 (after other frames) equals the still render of the file; frame k equals a fresh render of
    scene_at(k / fps); after the first frame no kernel is compiled or even loaded from the disk cache."""
    from a5mi.animate.warm import FrameTiming, WarmScene
    from a5mi.converters.describe import describe
    from a5mi.render.session import render

    scene = parse_text(animated())
    opts = RenderOptions(width=20, height=20, spp=2, shadows=True)
    warm = WarmScene(scene, opts)
    warm.render(5)
    later = FrameTiming()
    images = {f: warm.render(f, later).image for f in (9, 0, 5)}
    assert later.kernels.get("compiled", 0) == 0 and later.kernels.get("disk", 0) == 0, later.kernels
    assert later.kernels.get("memory", 0) > 0
    still = render(describe(parse_text(STILL)), opts).image
    assert np.array_equal(images[0], still)
    for f in (5, 9):
        fresh = render(describe(keyframes.scene_at(scene, f / 12)), opts).image
        assert np.array_equal(images[f], fresh), f
    assert not np.array_equal(images[5], images[9])


def test_static_scene_is_the_same_with_and_without_shutter(mi) -> None:
    """Motion blur on a scene whose tracks hold still: every pass sees the same scene, so the passes of E.12
    average to the -spp image of E.5 bit for bit (the lens makes the passes differ)."""
    from a5mi.animate.warm import WarmScene

    hold = "Animation { frames 4 fps 4 SHUTTER Track { Transform 1 0 linear key 0 0 0 0 } }"
    opts = RenderOptions(width=20, height=20, spp=3)
    blurred = WarmScene(parse_text(STILL + hold.replace("SHUTTER", "shutter 1")), opts).render(2).image
    sharp = WarmScene(parse_text(STILL + hold.replace("SHUTTER", "")), opts).render(2).image
    assert np.array_equal(blurred, sharp)


def _coverage(width: int, t0: float, t1: float) -> np.ndarray:
    """Middle row: the share of [t0, t1] in which the pixel's camera ray meets the unit sphere at
    (-2 + 4 t, 0, 0), camera at (0, 0, 10) looking down -z, angle 30 (SPEC B.2 rays, in float64)."""
    f = 1.0 / math.tan(math.radians(30) / 2)
    out = np.empty(width)
    for i in range(width):
        x = 2.0 * i / (width - 1) - 1.0
        d = np.array([x, 0.0, -f]) / math.hypot(x, f)
        # |c - o|^2 - ((c - o)·d)^2 < 1 with c - o = (X, 0, -10): a X^2 + b X + c < 0
        a, b, c = 1.0 - d[0] ** 2, 20.0 * d[0] * d[2], 100.0 - 100.0 * d[2] ** 2 - 1.0
        disc = b * b - 4 * a * c
        if disc <= 0:
            out[i] = 0.0
            continue
        lo, hi = (-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)
        ta, tb = max(t0, (lo + 2) / 4), min(t1, (hi + 2) / 4)
        out[i] = max(0.0, tb - ta) / (t1 - t0)
    return out


def test_motion_blur_edge_matches_box_filtered_coverage(mi) -> None:
    """A white unit sphere, no lights (colour = ambient 1 · diffuse 1), moving 4 units/s along x; frame 1 at
    2 fps, shutter 1: the scene at 8 stratified times of [0.25, 0.75] s. Each pixel is the share of those
    times its ray hits the sphere; the box-filtered coverage is the share of the interval: with midpoint
    strata of an interval the two differ by at most 1/8 (tolerance 1/8 + 1e-3), and by about 1/32 on average."""
    from a5mi.animate.warm import WarmScene

    text = """PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 30 }
Background { color 0 0 0 }
Materials { numMaterials 1 Material { diffuseColor 1 1 1 } }
Group { numObjects 1 MaterialIndex 0 Transform { Translate 0 0 0 Sphere { center 0 0 0 radius 1 } } }
Animation { frames 2 fps 2 SHUTTER Track { Transform 0 0 linear key 0 -2 0 0 key 1 2 0 0 } }"""
    w = 48
    opts = RenderOptions(width=w, height=9, spp=8)
    image = WarmScene(parse_text(text.replace("SHUTTER", "shutter 1")), opts).render(1).image
    row = image[4, :, 0].astype(np.float64)
    expected = _coverage(w, 0.25, 0.75)
    assert np.max(np.abs(row - expected)) <= 1 / 8 + 1e-3
    assert np.mean(np.abs(row - expected)) < 0.05
    assert np.any((row > 0.2) & (row < 0.8)), "no blur at all"
    sharp = WarmScene(parse_text(text.replace("SHUTTER", "")), opts).render(1).image[4, :, 0]
    assert np.max(np.abs(sharp - expected)) > 0.4  # without the shutter the edge is hard: the test can fail


# ------------------------------------------------------------------------------------------ frames, resume
SMALL = animated().replace("frames 12 fps 12", "frames 6 fps 6")


def test_resume_renders_only_missing_and_damaged_frames(mi, tmp_path: Path) -> None:
    from a5mi.animate import batch, frames
    from a5mi.platform import imageio

    scene = tmp_path / "anim.txt"
    scene.write_text(SMALL)
    out = tmp_path / "frames"
    opts = RenderOptions(width=16, height=16)
    first = batch.render_animation(scene, out, opts, range(6))
    assert first.rendered == list(range(6)) and frames.missing_frames(out, range(6)) == []
    before = {f: imageio.read_uint8(frames.frame_path(out, f)) for f in range(6)}
    frames.frame_path(out, 1).unlink()                               # missing
    with open(frames.frame_path(out, 3), "ab") as fh:                # damaged: checksum mismatch
        fh.write(b"x")
    frames.checksum_path(frames.frame_path(out, 4)).unlink()         # no checksum: not trusted
    (out / ".frame_00002.png.a5mi-999999999-abc.png").write_bytes(b"partial")  # a dead writer's temporary
    again = batch.render_animation(scene, out, opts, range(6), resume=True)
    assert again.rendered == [1, 3, 4] and again.skipped == 3
    assert frames.missing_frames(out, range(6)) == []
    assert not (out / ".frame_00002.png.a5mi-999999999-abc.png").exists()
    for f in range(6):
        assert np.array_equal(imageio.read_uint8(frames.frame_path(out, f)), before[f]), f


def test_frames_on_two_dask_workers_match_one_process_even_with_a_worker_killed(mi, tmp_path: Path) -> None:
    from distributed import Client, LocalCluster

    from a5mi.animate import batch, frames
    from a5mi.platform import imageio

    scene = tmp_path / "anim.txt"
    scene.write_text(animated().replace("frames 12 fps 12", "frames 10 fps 10"))
    opts = RenderOptions(width=16, height=16)
    local = tmp_path / "local"
    batch.render_animation(scene, local, opts, range(10))
    out = tmp_path / "dask"
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=50)  # never 8787: a second suite may hold it
    try:
        with Client(cluster) as client:
            pids = list(client.run(os.getpid).values())
        killed: list[int] = []

        def kill_one() -> None:  # as soon as the first frame is written, kill a worker mid-run
            deadline = time.time() + 120
            while time.time() < deadline and not any(out.glob("frame_*.png.sha256")):
                time.sleep(0.05)
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])

        killer = threading.Thread(target=kill_one)
        killer.start()
        outcome = batch.render_animation(scene, out, opts, range(10), scheduler=cluster.scheduler_address)
        killer.join()
    finally:
        cluster.close()
    assert killed
    # nothing partial under a frame's name: every image present has its checksum
    for p in out.glob("frame_*.png"):
        assert frames.frame_done(out, int(p.stem.split("_")[1])), p
    missing = frames.missing_frames(out, range(10))
    if missing:  # the killed worker's chunk failed for good: --resume completes exactly those frames
        again = batch.render_animation(scene, out, opts, range(10), resume=True)
        assert again.rendered == missing
    else:
        assert sorted(outcome.rendered) == list(range(10))
    assert frames.missing_frames(out, range(10)) == []
    for f in range(10):
        assert np.array_equal(imageio.read_uint8(frames.frame_path(out, f)),
                              imageio.read_uint8(frames.frame_path(local, f))), f


# --------------------------------------------------------------------------------------------------- CLI
def test_cli_animate_writes_frames_and_a_gif(mi, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from a5mi.cli import command
    from a5mi.cli.app import execute

    scene = tmp_path / "anim.txt"
    scene.write_text(SMALL)
    gif = tmp_path / "clip.gif"
    code = execute(command("animate"), [str(scene), "-o", str(tmp_path / "f"), "--frames", "2:5", "-size", "16",
                                        "16", "--video", str(gif)])
    assert code == 0, capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "f").glob("*.png")) == [f"frame_0000{i}.png" for i in (2, 3, 4)]
    assert gif.read_bytes()[:6] == b"GIF89a"
    still = tmp_path / "still.txt"
    still.write_text(STILL)
    assert execute(command("animate"), [str(still), "-o", str(tmp_path / "g")]) == 2
    assert "has no Animation block" in capsys.readouterr().err
    assert execute(command("animate"), [str(scene), "-o", str(tmp_path / "g"), "--frames", "3:99"]) == 2


def test_bump_flag_reaches_the_warm_scene(mi, tmp_path: Path) -> None:
    """``-bump`` (E.7) in an animation: frame 0 of ``scenes/bumps.txt`` with a light track equals the still
    ``-bump`` render bit for bit, and differs from the frame without ``-bump`` (the flag is not ignored)."""
    from a5mi.animate.warm import WarmScene
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.render.session import render

    still = (ROOT / "scenes" / "bumps.txt").read_text()
    still = still.replace("tex/", f"{ROOT / 'scenes' / 'tex'}/").replace("meshes/", f"{ROOT / 'scenes' / 'meshes'}/")
    (tmp_path / "still.txt").write_text(still)
    (tmp_path / "anim.txt").write_text(
        still + "Animation { frames 2 fps 1 Track { Light 1 position linear key 0 1.5 2.5 2 key 1 -1.5 2.5 2 } }\n")
    on = RenderOptions(width=24, height=24, shadows=True, bump=True)
    off = dataclasses.replace(on, bump=False)
    frame_on = WarmScene(parse_file(tmp_path / "anim.txt"), on).render(0).image
    frame_off = WarmScene(parse_file(tmp_path / "anim.txt"), off).render(0).image
    assert np.array_equal(frame_on, render(describe(parse_file(tmp_path / "still.txt"), bump=True), on).image)
    assert not np.array_equal(frame_on, frame_off)

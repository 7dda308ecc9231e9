"""A render split into row bands across Dask workers (a5mi/render/bands.py, docs/EXTENSIONS.md E.24):
bit for bit the one-process image with the same seed (jitter + filter, spp, path), also when a worker is
killed mid-render (its band re-run elsewhere)."""

from __future__ import annotations

import dataclasses
import os
import signal
import threading

import numpy as np
import pytest
from helpers import ROOT

from a5mi.render.options import RenderOptions

SCENES = str(ROOT / "scenes")


def _one_process(name: str, options: RenderOptions) -> np.ndarray:
    from a5mi.render.session import describe_file, render
    from a5mi.runtime.variant import activate

    activate()
    desc, _ = describe_file(os.path.join(SCENES, name))
    return render(desc, options).image


def test_split_rows_cover_the_buffer_on_packet_boundaries() -> None:
    from a5mi.render.bands import split_rows

    for rw, rh, parts in ((48, 30, 4), (21, 13, 3), (64, 5, 8), (7, 100, 1)):
        bands = split_rows(rw, rh, parts)
        assert bands[0][0] == 0 and bands[-1][1] == rh
        assert all(a[1] == b[0] for a, b in zip(bands, bands[1:], strict=False))
        assert all(j0 * rw % 64 == 0 for j0, _ in bands) and len(bands) <= parts


def test_bands_in_this_process_are_the_whole_render() -> None:
    """The stitching alone (no Dask): bands rendered one by one and assembled, -jitter -filter -normals."""
    from a5mi.render.bands import split_rows
    from a5mi.render.driver import assemble, render_band, render_scene
    from a5mi.render.session import build_scene, describe_file
    from a5mi.runtime.variant import activate

    activate()
    desc, _ = describe_file(os.path.join(SCENES, "soft_shadows.txt"))
    # a seed: numpy's jitter stream; none: glibc's seed-1 rand() stream of SPEC B.5
    for seed, spp in ((5, 3), (None, 1)):
        options = RenderOptions(width=16, height=12, shadows=True, spp=spp, seed=seed, jitter=True, filter=True,
                                normals=True)
        scene = build_scene(desc, options)
        whole = render_scene(scene, desc.camera, options)
        rw, rh = options.render_size
        bands = [render_band(scene, desc.camera, options, b) for b in split_rows(rw, rh, 3)]
        stitched = assemble(options, bands[::-1])
        assert len(bands) == 3
        assert np.array_equal(stitched.image, whole.image)
        assert np.array_equal(stitched.normals, whole.normals)


@pytest.mark.parametrize(("name", "extra"), [("soft_shadows.txt", {"jitter": True, "filter": True}),
                                             ("colour_bleeding.txt", {"integrator": "path", "bounces": 2})])
def test_split_render_on_two_workers_is_bit_identical_even_with_a_worker_killed(name: str, extra: dict) -> None:
    from distributed import Client, LocalCluster

    from a5mi.render.bands import render_split

    options = RenderOptions(width=32, height=20, shadows=True, spp=4, seed=7, **extra)
    reference = _one_process(name, options)
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0", silence_logs=50)  # never 8787: a second suite may hold it
    first = threading.Event()
    killed: list[int] = []
    try:
        with Client(cluster) as client:
            pids = list(client.run(os.getpid).values())

            def kill_one() -> None:   # once the first band is back, kill a worker that holds another
                if first.wait(120):
                    os.kill(pids[0], signal.SIGKILL)
                    killed.append(pids[0])

            killer = threading.Thread(target=kill_one)
            killer.start()
            result, info = render_split(os.path.join(SCENES, name), options, client=client, parts=6,
                                        progress=lambda done, total: first.set())
            killer.join()
    finally:
        cluster.close()
    assert killed
    assert info["bands"][0][0] == 0 and len(info["bands"]) == 6
    assert np.array_equal(result.image, reference)
    assert reference.std() > 0.0


def test_split_refuses_integrators_with_state() -> None:
    from a5mi.render.bands import render_split, splittable

    options = RenderOptions(width=8, height=8, integrator="ppm")
    assert splittable(options) is not None
    assert splittable(dataclasses.replace(options, integrator="whitted")) is None
    with pytest.raises(ValueError, match="ppm"):
        render_split("x.txt", options, workers=1)


def test_cli_workers_writes_the_one_process_image(tmp_path) -> None:
    """``a5 ... -workers 2`` (a local TLS cluster, a5mi.runtime.cluster.start_client): the same PNG bytes as without."""
    from a5mi.cli import run

    scene = os.path.join(SCENES, "soft_shadows.txt")
    flags = ["-input", scene, "-size", "32", "24", "-spp", "4", "-seed", "3", "-shadows", "-q"]
    assert run([*flags, "-output", str(tmp_path / "one.png")]) == 0
    assert run([*flags, "-output", str(tmp_path / "two.png"), "-workers", "2"]) == 0
    assert (tmp_path / "one.png").read_bytes() == (tmp_path / "two.png").read_bytes()
    assert run([*flags, "-output", str(tmp_path / "x.png"), "-workers", "2", "-integrator",
                            "ppm"]) == 2
    assert run([*flags, "-output", str(tmp_path / "x.png"), "-tls_ca", "ca.pem"]) == 2

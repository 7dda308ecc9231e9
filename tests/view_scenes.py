"""Shared by the ``a5mi view`` tests: a small scene (glass and red spheres, a floor, two lights, no cube map, so
a render takes well under a second), a hard per-test timeout, and the ``a5`` render to compare with."""

from __future__ import annotations

import faulthandler
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

SCENE = """PerspectiveCamera {
    center 0 1.5 5
    direction 0 -0.2 -1
    up 0 1 0
    angle 30
}
Lights {
    numLights 2
    DirectionalLight {
        direction 0.5 -1 0
        color 0.3 0.3 0.3
    }
    PointLight {
        position -1 1 0
        color 0.5 0.5 0.5
    }
}
Materials {
    numMaterials 3
    PhongMaterial {
        diffuseColor 0.1 0.1 0.1
        specularColor 1 1 1
        refractionIndex 1.3
    }
    PhongMaterial {
        diffuseColor RED
        specularColor 0.3 0.3 0.3
    }
    PhongMaterial {
        diffuseColor 0.8 0.8 0.8
        specularColor 0.1 0.1 0.5
    }
}
Background {
    color 0.2 0.1 0.6
    ambientLight 0.2 0.2 0.2
}
Group {
    numObjects 3
    MaterialIndex 0
    Sphere {
        center 0.3 0.0 -1
        radius 1.0
    }
    MaterialIndex 1
    Sphere {
        center -0.5 -0.6 0.2
        radius 0.4
    }
    MaterialIndex 2
    Plane {
        normal 0 1 0
        offset -1
    }
}
"""

RED = "1 0.1 0.1"


def scene_text(red: str = RED) -> str:
    return SCENE.replace("RED", red)


def write_scene(path: Path, red: str = RED) -> Path:
    path.write_text(scene_text(red))
    return path


def a5_png(scene: Path, out: Path, *flags: str) -> bytes:
    """The PNG file ``a5 -input SCENE -output OUT FLAGS`` writes (run in this process)."""
    from a5mi.cli import run

    assert run(["-input", str(scene), "-output", str(out), *flags]) == 0
    return out.read_bytes()


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Fail the test after ``seconds``: SIGALRM raises TimeoutError in the main thread; elsewhere faulthandler
    ends the process with every thread's traceback."""
    if threading.current_thread() is threading.main_thread():
        def expire(signum: int, frame: object) -> None:
            raise TimeoutError(f"the test ran past its {seconds:g} s limit")

        old = signal.signal(signal.SIGALRM, expire)
        signal.setitimer(signal.ITIMER_REAL, seconds)
        try:
            yield
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
    else:
        faulthandler.dump_traceback_later(seconds, exit=True)
        try:
            yield
        finally:
            faulthandler.cancel_dump_traceback_later()


def beside_loop(check: Callable[[], None], stop: threading.Event, loop: Callable[[], None]) -> None:
    """Run ``loop()`` on this thread (the view's render loop runs on the main thread, as in ``a5mi view``) with
    ``check()`` on a thread beside it, which sets ``stop`` when it ends; re-raises the check's failure here."""
    errors: list[BaseException] = []

    def checks() -> None:
        try:
            check()
        except BaseException as exc:  # noqa: BLE001 - re-raised on the main thread
            errors.append(exc)
        finally:
            stop.set()

    checker = threading.Thread(target=checks)
    checker.start()
    loop()
    checker.join(timeout=10)
    if errors:
        raise errors[0]


def view_loop(engine: Any, options: Any, drive: Callable[[Any, list[dict]], None], **loop: Any) -> None:
    """``run_engine`` on this thread, as ``a5mi view`` runs it (``loop``: its keyword arguments), ``drive(jobs,
    states)`` beside it (:func:`beside_loop`); each state the loop publishes is recorded with the render's PNG
    (``png``) and value blob (``values``); re-raises the drive's failure."""
    from a5mi.view.live import run_engine
    from a5mi.view.server import Hub, Jobs
    from a5mi.view.watcher import Watcher

    states: list[dict] = []

    class Recorder(Hub):
        def update(self, images: Any = None, **state: Any) -> None:
            super().update(images, **state)
            states.append({**self.state(), "png": self.image("render"), "values": self.image("values-render")})

    hub, jobs, stop = Recorder(), Jobs(), threading.Event()
    watcher = Watcher(lambda: jobs.render(reload=True))
    watcher.start()
    try:
        beside_loop(lambda: drive(jobs, states), stop,
                    lambda: run_engine(engine, hub, jobs, watcher, options, stop=stop, **loop))
    finally:
        watcher.stop()


def wait_for(states: list[dict], pred: Callable[[dict], Any], what: str) -> dict:
    """The last recorded state for which ``pred`` holds, waiting for one (at most 120 s)."""
    t0 = time.monotonic()
    while True:
        found = [s for s in states if pred(s)]
        if found:
            return found[-1]
        assert time.monotonic() - t0 < 120, (what, states[-1] if states else None)
        time.sleep(0.02)

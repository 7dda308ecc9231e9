"""``a5mi serve`` (docs/SERVE.md): an ``a5`` handed to a warm server writes the same bytes, prints the same lines
and exits with the same status as an ``a5`` that renders in-process; without a usable server it renders
in-process; the socket is ``0600`` and this user's; another uid is refused; a client's Ctrl-C stops the
served render and the server lives on."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

A5 = [sys.executable, "-m", "a5mi"]
A5MI = [sys.executable, "-c", "import sys; sys.argv[0] = 'a5mi'; from a5mi.entry import a5mi; a5mi()"]

SCENE = """PerspectiveCamera { center 0 0 10 direction 0 0 -1 up 0 1 0 angle 20 }
Lights { numLights 1 DirectionalLight { direction -0.2 -0.5 -1 color 1 1 1 } }
Background { color 0.1 0.2 0.3 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2
 Material { diffuseColor 0.8 0.2 0.1 specularColor 0.5 0.5 0.5 }
 Material { diffuseColor 0.1 0.1 0.1 specularColor 0.5 0.5 0.5 refractionIndex 1.5 } }
Group { numObjects 3 MaterialIndex 0
 Plane { normal 0 1 0 offset -1 }
 Sphere { center -0.6 0 0 radius 0.5 }
 MaterialIndex 1 Sphere { center 0.6 0 0.5 radius 0.5 } }
"""
FLAGS = ["-size", "40", "40", "-shadows", "-bounces", "3", "-jitter", "-filter"]
#: CPU seconds the server may use to start (interpreter, Mitsuba, the variant, the plugins) before the test fails
START_CPU_S = 120.0


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Server:
    def __init__(self, sock: Path, log: Path, proc: subprocess.Popen[bytes]) -> None:
        self.sock, self.log, self.proc = sock, log, proc

    def lines(self, word: str) -> list[str]:
        return [ln for ln in self.log.read_text().splitlines() if word in ln]


def _env(sock: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "A5MI_NO_SERVE"}
    return {**env, "A5MI_SERVE_SOCKET": str(sock), **extra}


@pytest.fixture(scope="module")
def server() -> Iterator[Server]:
    folder = Path(tempfile.mkdtemp(prefix="a5s-", dir="/tmp"))  # short: a socket path has at most 107 bytes
    sock, log = folder / "run" / "s.sock", folder / "server.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen([*A5MI, "serve", "--socket", str(sock)], env=_env(sock), stdout=out, stderr=out)
    try:
        while "listening" not in log.read_text():
            assert proc.poll() is None, log.read_text()
            assert _cpu_seconds(proc.pid) < START_CPU_S, "the server did not start"
            time.sleep(0.05)
        yield Server(sock, log, proc)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=120)
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    (tmp_path / "s.txt").write_text(SCENE)
    return tmp_path


def _a5(cwd: Path, env: dict[str, str], *argv: str) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([*A5, *argv], cwd=cwd, env=env, capture_output=True, timeout=600)


def test_served_images_are_byte_identical_to_in_process_ones(server: Server, scene: Path) -> None:
    before = len(server.lines("served"))
    served = [_a5(scene, _env(server.sock), "-input", "s.txt", "-output", f"served{i}.png", *FLAGS) for i in (1, 2)]
    local = _a5(scene, {**os.environ, "A5MI_NO_SERVE": "1"}, "-input", "s.txt", "-output", "local.png", *FLAGS)
    assert [r.returncode for r in (*served, local)] == [0, 0, 0], [r.stderr for r in (*served, local)]
    assert [r.stdout + r.stderr for r in served] == [local.stdout + local.stderr] * 2
    assert len(server.lines("served")) == before + 2  # the server rendered both (a warm kernel the second time)
    image = (scene / "local.png").read_bytes()
    assert (scene / "served1.png").read_bytes() == image
    assert (scene / "served2.png").read_bytes() == image


def test_a_served_a5_loads_neither_mitsuba_nor_the_command_layer(server: Server, scene: Path) -> None:
    """The client is an interpreter and the standard library: ``-X importtime`` of a served ``a5 -h`` (its
    lines go to the client's own stderr) names no Mitsuba, Dr.Jit, numpy or command-layer module."""
    run = subprocess.run([sys.executable, "-X", "importtime", "-m", "a5mi", "-h"], cwd=scene, env=_env(server.sock),
                         capture_output=True, timeout=600)
    assert run.returncode == 0 and b"usage: a5" in run.stdout
    lines = run.stderr.decode().splitlines()
    imported = {ln.rsplit("|", 1)[1].strip() for ln in lines if ln.startswith("import time:")}
    assert "a5mi.serve.client" in imported
    assert not {m for m in imported if m.split(".")[0] in ("mitsuba", "drjit", "numpy", "OpenImageIO")}
    assert not {m for m in imported if m.startswith(("a5mi.cli", "a5mi.commands", "a5mi.render"))}


MESH_SCENE = """PerspectiveCamera { center 0 1 6 direction 0 -0.15 -1 up 0 1 0 angle 30 }
Lights { numLights 1 PointLight { position 2 4 4 color 1 1 1 } }
Background { color 0.2 0.2 0.3 ambientLight 0.2 0.2 0.2 }
Materials { numMaterials 2
 Material { diffuseColor 1 1 1 texture t.bmp }
 Material { diffuseColor 0.7 0.6 0.2 specularColor 0.3 0.3 0.3 } }
Group { numObjects 2 MaterialIndex 0 Plane { normal 0 1 0 offset -1 }
 MaterialIndex 1 TriangleMesh { obj_file m.obj } }
"""


def test_edited_meshes_and_textures_are_read_again(server: Server, tmp_path: Path) -> None:
    """The server keeps decoded images and meshes while their files stay the same (KeptFiles): after the mesh
    and the texture are replaced, the served image is still the in-process one, and it changed."""
    root = Path(__file__).resolve().parents[2] / "scenes"
    (tmp_path / "s.txt").write_text(MESH_SCENE)
    argv = ["-input", "s.txt", "-size", "40", "40", "-shadows", "-bounces", "2"]
    images = []
    for mesh, texture in (("box", "checker"), ("box", "checker"), ("icosphere", "ripples")):
        shutil.copy(root / "meshes" / f"{mesh}.obj", tmp_path / "m.obj")
        shutil.copy(root / "tex" / f"{texture}.bmp", tmp_path / "t.bmp")
        served = _a5(tmp_path, _env(server.sock), *argv, "-output", "served.png")
        local = _a5(tmp_path, {**os.environ, "A5MI_NO_SERVE": "1"}, *argv, "-output", "local.png")
        assert served.returncode == local.returncode == 0, (served.stderr, local.stderr)
        assert (served.stdout, served.stderr) == (local.stdout, local.stderr)
        images.append((tmp_path / "served.png").read_bytes())
        assert images[-1] == (tmp_path / "local.png").read_bytes()
    assert images[0] == images[1] != images[2]


def test_the_socket_is_this_users_and_closed_to_others(server: Server) -> None:
    st = os.lstat(server.sock)
    assert stat.S_ISSOCK(st.st_mode) and st.st_uid == os.getuid()
    assert stat.S_IMODE(st.st_mode) == 0o600
    folder = os.stat(server.sock.parent)
    assert folder.st_uid == os.getuid() and not folder.st_mode & 0o077


@pytest.mark.parametrize("argv, status", [
    (["-input", "missing.txt", "-output", "o.png"], 2),
    (["-input", "s.txt", "-output", "o.png", "-bogus"], 2),
    (["-input", "s.txt", "-output", "o.png", "-size", "0", "10"], 2),
    (["-input", "s.txt", "-output", "s.txt"], 2),
    (["-h"], 0),
])
def test_errors_and_output_are_relayed_with_the_same_status(server: Server, scene: Path, argv: list[str],
                                                            status: int) -> None:
    before = len(server.lines("served"))
    served = _a5(scene, _env(server.sock), *argv)
    local = _a5(scene, {**os.environ, "A5MI_NO_SERVE": "1"}, *argv)
    assert served.returncode == local.returncode == status
    assert (served.stdout, served.stderr) == (local.stdout, local.stderr)
    assert len(server.lines("served")) == before + 1
    if status:
        assert len(served.stderr.decode().splitlines()) == 1
    assert not (scene / "o.png").exists()


def test_without_a_server_a5_renders_in_process(scene: Path, tmp_path: Path) -> None:
    stale = tmp_path / "stale.sock"  # a dead server's socket: nothing listens
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(stale))
    listener.close()
    os.chmod(stale, 0o600)
    local = _a5(scene, {**os.environ, "A5MI_NO_SERVE": "1"}, "-input", "s.txt", "-output", "local.png", *FLAGS)
    for i, sock in enumerate((tmp_path / "none.sock", stale)):
        run = _a5(scene, _env(sock), "-input", "s.txt", "-output", f"o{i}.png", *FLAGS)
        assert run.returncode == 0, run.stderr
        assert (run.stdout, run.stderr) == (local.stdout, local.stderr)
        assert (scene / f"o{i}.png").read_bytes() == (scene / "local.png").read_bytes()


def test_another_environment_is_declined_and_rendered_in_process(server: Server, scene: Path) -> None:
    before = len(server.lines("declined"))
    run = _a5(scene, _env(server.sock, DRJIT_CACHE_DIR=str(scene / "jit")), "-input", "s.txt", "-output", "o.png",
              *FLAGS)
    assert run.returncode == 0, run.stderr
    assert (scene / "o.png").is_file()
    assert len(server.lines("declined")) == before + 1


@pytest.mark.skipif(os.getuid() != 0 or shutil.which("setpriv") is None, reason="needs root and setpriv")
def test_another_uid_is_refused(server: Server) -> None:
    """The socket opened to everyone (as a careless chmod would): a process of uid 65534 connects, and the
    server closes the connection without a word (SO_PEERCRED)."""
    before = len(server.lines("refused"))
    probe = ("import socket, sys\ns = socket.socket(socket.AF_UNIX)\ns.connect(sys.argv[1])\ns.settimeout(60)\n"
             "try:\n s.sendall(b'R\\0\\0\\0\\2{}')\n print(repr(s.recv(100)))\n"
             "except OSError as exc:\n print(type(exc).__name__)")
    folders = (server.sock.parent.parent, server.sock.parent)
    for folder in folders:
        os.chmod(folder, 0o711)
    os.chmod(server.sock, 0o666)
    try:
        run = subprocess.run(["setpriv", "--reuid", "65534", "--regid", "65534", "--clear-groups", "/usr/bin/python3",
                              "-c", probe, str(server.sock)], capture_output=True, timeout=120)
    finally:
        os.chmod(server.sock, 0o600)
        for folder in folders:
            os.chmod(folder, 0o700)
    assert run.returncode == 0, run.stderr
    assert run.stdout.decode().strip() in ("b''", "BrokenPipeError", "ConnectionResetError")  # closed, no answer
    assert len(server.lines("refused")) == before + 1


def test_a_signal_stops_the_served_render_and_the_server_goes_on(server: Server, scene: Path) -> None:
    """Ctrl-C of a served ``a5`` (a render of several seconds): 130, one line, no image; the server then
    serves the next command. The signal is sent once the server has started on the command (its CPU time
    rises)."""
    cpu0 = _cpu_seconds(server.proc.pid)
    proc = subprocess.Popen([*A5, "-input", "s.txt", "-output", "big.png", "-size", "700", "700", "-shadows",
                             "-bounces", "6", "-jitter"], cwd=scene, env=_env(server.sock), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    while _cpu_seconds(server.proc.pid) < cpu0 + 0.3 and proc.poll() is None:
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 130, err
    lines = err.decode().splitlines()  # the work estimate's warning, then the one line of the signal
    assert [ln for ln in lines if "error" in ln] == ["a5: error: interrupted (SIGINT)"] == lines[-1:]
    assert not (scene / "big.png").exists()
    assert server.proc.poll() is None
    run = _a5(scene, _env(server.sock), "-input", "s.txt", "-output", "after.png", *FLAGS)
    assert run.returncode == 0, run.stderr
    assert server.lines("served")[-1].split(": exit ")[1].startswith("0 ")

"""A hostile class: student folders whose ``a5`` (a shell script) attacks the grader, plus honest ones.

:func:`make_class` writes the folders and returns what each must get (``docs/GRADING.md`` "Threat model").
Every attack is what a student could hand in: read secrets (``/etc/shadow``, the checkout, a file in the
grader's home), write outside its folder, connect to a port on the host's loopback and to a public address,
fork without end, kill its parent and every process it may signal, answer with a symbolic link to the
reference or to a classmate's image, a hard link, a FIFO, an image header of 30000 x 30000 pixels in a tiny
file, a decompression-bomb PNG, ``unshare -r`` and remounting, fill the disk (six files under the per-file limit,
in its folder and ``$TMPDIR``) or its inodes (60,000 files and 808-deep folders) and still write a correct image.
A pyenv-style wrapper (``exec VENV/bin/a5``, its interpreter a copy of ``dash`` outside ``/usr``) is honest
but cannot start without ``--allow-read``: its cause names the paths. Image-folder students hand in links instead of
images. The honest ones write a correct image (the reference's bytes, embedded), use ``mktemp`` and ``$HOME``,
or write a wrong image.
"""

from __future__ import annotations

import base64
import os
import socket
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import pytest
from helpers import ROOT

#: How a script finds the image path it must write (the a5 command line: ``-output FILE``).
ARGS = 'out=out.png\nwhile [ $# -gt 0 ]; do [ "$1" = -output ] && out="$2"; shift; done\n'


@dataclass(frozen=True)
class Expect:
    """What a student must get: one of ``verdicts`` and, when given, ``detail`` in the record's detail,
    ``stderr`` in its stderr tail and ``cause`` in its cause."""

    verdicts: tuple[str, ...]
    detail: str = ""
    stderr: tuple[str, ...] = ()
    cause: str = ""


def _embed(data: bytes, target: str = '"$out"') -> str:
    return f"base64 -d > {target} <<'EOF'\n{base64.encodebytes(data).decode()}EOF\n"


def tga_header(width: int, height: int) -> bytes:
    """An uncompressed 24-bit TGA header of ``width`` x ``height`` and 12 bytes of pixels (truncated)."""
    return struct.pack("<BBBHHBHHHHBB", 0, 0, 2, 0, 0, 0, 0, 0, width, height, 24, 0) + bytes(12)


def png_bomb(side: int = 20000) -> bytes:
    """A valid 1-bit grey PNG of ``side`` x ``side`` zeros: about ``side²/8`` bytes once inflated, 1000 times
    fewer on disk, ``side²`` pixels (x 3 channels x 8 bytes as levels) if decoded."""
    row = b"\0" + bytes((side + 7) // 8)
    raw = zlib.compress(row * side, 9)

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 1, 0, 0, 0, 0))
            + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


def sandbox_processes(uids: object) -> list[int]:
    """Live (non-zombie) processes of the runs' own user ids ``uids`` (the ``uid`` of each record or
    :class:`a5mi.sandbox.records.RunResult`; None entries are skipped): after a run, none may be left. Only what these
    runs started is looked at, never the machine's other sandboxes (another suite may run beside this one)."""
    from a5mi.sandbox.accounting import live_processes

    if uids is None or isinstance(uids, int):
        uids = [uids]
    return [pid for uid in set(uids) if uid is not None for pid in live_processes(uid)]  # type: ignore[union-attr]


def pyenv_wrapper(subs: Path) -> Path:
    """A virtual environment's ``a5`` beside ``subs`` (``VENV/bin/a5``) whose interpreter is a copy of ``dash``
    in a pyenv-style prefix (``PYENV/versions/3.11.7/bin/sh``): made once, returns the venv's ``a5``."""
    import shutil

    venv_a5 = subs.parent / "venv" / "bin" / "a5"
    interp = subs.parent / "pyenv" / "versions" / "3.11.7" / "bin" / "sh"
    if not venv_a5.exists():
        interp.parent.mkdir(parents=True)
        venv_a5.parent.mkdir(parents=True)
        shutil.copy2("/usr/bin/dash", interp)
        venv_a5.write_text(f"#!{interp}\necho started >&2\n")
        venv_a5.chmod(0o755)
        for d in (subs.parent / "venv", subs.parent / "pyenv", *interp.parents, *venv_a5.parents):
            if d.is_relative_to(subs.parent):
                d.chmod(0o755)
    return venv_a5


def host_tmp(port: int) -> Path:
    """The file in the host's ``/tmp`` the writer tries to create (named by the test's ``port``)."""
    return Path(f"/tmp/a5mi-pwned-{port}")


def make_class(subs: Path, *, output: str, good: bytes, wrong: bytes, reference: Path, secrets: dict[str, Path],
               outside: Path, port: int) -> dict[str, Expect]:
    """Write the class into ``subs`` (one folder per student, 0755, scripts 0755) for a case whose output is
    ``output``; ``good`` / ``wrong`` are image files' bytes (the correct one and a wrong one), ``reference``
    the reference image's path, ``secrets`` files a student must not read (name -> path), ``outside`` a
    world-writable folder it must not write to, ``port`` one the test listens on (127.0.0.1)."""
    mate = subs / "athome" / output
    cat = " ".join(f"'{p}'" for p in secrets.values())
    scripts: dict[str, tuple[str, Expect]] = {
        "good": (ARGS + _embed(good), Expect(("match",))),
        "mktemp": (ARGS + 't=$(mktemp) || exit 7\n' + _embed(good, '"$t"') +
                   'case "$HOME" in /*) ;; *) echo "relative HOME $HOME" >&2; exit 8;; esac\n'
                   'echo ok > "$HOME/.cache-test" || exit 9\nmv "$t" "$out"\n', Expect(("match",))),
        "wrongimg": (ARGS + _embed(wrong), Expect(("wrong",))),
        "secrets": (f"cat {cat} /etc/shadow >&2\nls / >&2\n", Expect(("no output",))),
        "writer": ("".join(f"echo pwned > '{t}'\n" for t in (outside / "pwned", subs / "athome" / "pwned",
                                                             subs / "pwned", host_tmp(port)))
                   + f"echo x > /tmp/a5mi-private-{port} || exit 5\n", Expect(("no output",))),
        "net": ("#!/usr/bin/python3\nimport socket, sys\ncode = 0\n"
                f"for addr in (('127.0.0.1', {port}), ('192.0.2.1', 80)):\n"
                "    s = socket.socket()\n    s.settimeout(3)\n    try:\n        s.connect(addr)\n"
                "        print('CONNECTED', addr, file=sys.stderr)\n    except OSError as exc:\n"
                "        print('refused', addr[0], exc.strerror, file=sys.stderr)\n        code = 3\n"
                "sys.exit(code)\n", Expect(("crash",), "exit status 3",
                                           ("refused 127.0.0.1 Connection refused",
                                            "refused 192.0.2.1 Network is unreachable"))),
        "forkstorm": ("while :; do sleep 100 & done\n", Expect(("timeout", "crash"))),
        "killer": ("kill -9 $PPID\nkill -9 -1\nsleep 2\n", Expect(("crash", "no output"))),
        "symref": (ARGS + f"ln -s '{reference}' \"$out\"\n",
                   Expect(("unreadable",), f"{output}: not a regular file (a symbolic link)")),
        "symmate": (ARGS + f"ln -s '{mate}' \"$out\"\n",
                    Expect(("unreadable",), f"{output}: not a regular file (a symbolic link)")),
        "hardlink": (ARGS + _embed(good, "mine") + 'ln mine "$out"\n',
                     Expect(("unreadable",), f"{output}: a hard link (2 names for one file)")),
        "hardmate": (ARGS + f"ln '{mate}' \"$out\"\n", Expect(("crash",))),
        "huge": (ARGS + _embed(tga_header(30000, 30000)), Expect(("unreadable", "wrong size"))),  # never decoded
        "bomb": (ARGS + _embed(png_bomb()), Expect(("wrong size",), "20000x20000")),
        "fifo": (ARGS + 'mkfifo "$out"\n', Expect(("unreadable",), f"{output}: not a regular file (a FIFO)")),
        "userns": ("unshare -r id >&2\n", Expect(("crash",), "", ("unshare failed",))),
        "remount": (f"mount -o remount,rw / >&2\nmount -o remount,bind,rw '{subs}' >&2\n"
                    f"echo pwned > '{subs / 'pwned-remount'}'\n", Expect(("crash",), "", ("superuser",))),
        "diskfill": ('for d in . "$TMPDIR" . "$TMPDIR" . "$TMPDIR"; do i=$((i+1)); head -c 50000000 /dev/zero '
                     '> "$d/fill$i"; done\n'
                     + ARGS + _embed(good), Expect(("over disk",), "filled its")),
        "inodes": ('i=0; while [ $i -lt 60000 ]; do : > "f$i" || break; i=$((i+1)); done\n'
                   'j=0; while [ $j -lt 808 ]; do mkdir d && cd d || break; j=$((j+1)); done\ncd "$HOME"\n'
                   + ARGS + _embed(good), Expect(("over disk",), "filled its")),
        "pyenvwrap": (f'exec "{pyenv_wrapper(subs)}" "$@"\n',
                      Expect(("crash",), "exit status 127", (), "add --allow-read ")),
    }
    expect: dict[str, Expect] = {}
    subs.mkdir(parents=True, exist_ok=True)
    for name, (script, exp) in scripts.items():
        d = subs / name
        d.mkdir()
        d.chmod(0o755)
        body = script if script.startswith("#!") else "#!/bin/sh\n" + script
        (d / "a5").write_text(body)
        (d / "a5").chmod(0o755)
        expect[name] = exp
    image_folders: dict[str, tuple[Path | bytes, Expect]] = {
        "athome": (good, Expect(("match",))),
        "shadowlink": (Path("/etc/shadow"),
                       Expect(("unreadable",), f"{output}: not a regular file (a symbolic link)")),
        "reflink": (reference, Expect(("unreadable",), f"{output}: not a regular file (a symbolic link)")),
    }
    for name, (content, exp) in image_folders.items():
        d = subs / name
        d.mkdir()
        d.chmod(0o755)
        if isinstance(content, Path):
            (d / output).symlink_to(content)
        else:
            (d / output).write_bytes(content)
            (d / output).chmod(0o644)
        expect[name] = exp
    (subs / "hardcopy").mkdir()
    (subs / "hardcopy").chmod(0o755)
    elsewhere = outside / f"copy-{output}"  # a file of someone else's, hard-linked into the folder
    elsewhere.write_bytes(good)
    os.link(elsewhere, subs / "hardcopy" / output)
    expect["hardcopy"] = Expect(("unreadable",), f"{output}: a hard link (2 names for one file)")
    return expect


__all__ = ["ARGS", "Expect", "host_tmp", "make_class", "png_bomb", "pyenv_wrapper", "tga_header"]


def confinement_probe(outside: Path, port: int) -> str:
    """A Python program that tries every escape (secrets, capabilities, user namespace, remount, writing
    outside, the host's loopback, a public address) and prints one JSON line of what happened."""
    return "#!/usr/bin/python3\n" + f"""import json, os, socket, subprocess
res = {{}}
for key, path in (("shadow", "/etc/shadow"), ("checkout", {str(ROOT / "pyproject.toml")!r})):
    try:
        open(path).read(1)
        res[key] = "READ"
    except OSError as exc:
        res[key] = exc.strerror
res["capeff"] = [ln.split()[1] for ln in open("/proc/self/status") if ln.startswith("CapEff")][0]
res["unshare"] = subprocess.run(["unshare", "-r", "true"], capture_output=True).returncode
res["remount"] = subprocess.run(["mount", "-o", "remount,bind,rw", "/usr"], capture_output=True).returncode
try:
    open({str(outside / "pwned")!r}, "w").write("x")
    res["write"] = "WROTE"
except OSError as exc:
    res["write"] = exc.strerror
for key, addr in (("loopback", ("127.0.0.1", {port})), ("public", ("192.0.2.1", 80))):
    s = socket.socket()
    s.settimeout(2)
    try:
        s.connect(addr)
        res[key] = "CONNECTED"
    except OSError as exc:
        res[key] = exc.strerror
print(json.dumps(res))
"""


CONFINED = {"shadow": "No such file or directory", "checkout": "No such file or directory",
            "capeff": "0000000000000000", "write": "Read-only file system", "loopback": "Connection refused",
            "public": "Network is unreachable"}


def check_confined(res: dict, listener: socket.socket) -> None:
    """What :func:`confinement_probe` printed (``res``) shows every escape failed, and nothing reached the test's
    own ``listener`` on the host's loopback."""
    assert res["unshare"] != 0 and res["remount"] != 0, res
    assert {k: res[k] for k in CONFINED} == CONFINED | {"write": res["write"]}, res
    assert res["write"] in ("Read-only file system", "No such file or directory", "Permission denied"), res
    listener.settimeout(0.01)
    with pytest.raises(OSError):
        listener.accept()

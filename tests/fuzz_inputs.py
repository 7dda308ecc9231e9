"""The input mutators of ``make fuzz`` beyond the scene text: OBJ meshes, images, and every sub-command's flags.

* :func:`mutate_obj`: face and vertex lines of an OBJ file: coincident copies of a face, degenerate and sliver
  faces, a star of thin triangles crossing at one point, bad or huge indices, non-finite coordinates, other
  line endings, truncation.
* :func:`mutate_image`: the bytes of a texture or cube face: truncation, header bytes flipped, the header's
  width and height set huge (BMP and PNG), an empty file, text, or a valid image of an odd kind (1, 2 or 4
  channels, 16-bit, alpha 128, 1x1) written by OpenImageIO.
* :func:`command_argv`: a command line for any ``a5mi`` sub-command (:data:`a5mi.cli.SUBCOMMANDS`): real small
  runs for the commands that finish in seconds, and for the long ones (``bench``, ``fidelity``, ``grade``)
  lines with at least one junk value or flag, so the run ends at the flag checks (exit 2, one line).
"""

from __future__ import annotations

import random
import struct
from pathlib import Path

import numpy as np

#: Commands whose real runs take minutes (every reference, the benchmarks, a class): flag checks only.
PARSE_ONLY = ("bench", "fidelity", "grade", "serve")  # long or endless: their flag checks only
JUNK_VALUES = ("-1", "0", "nan", "1e39", "x", "", "１", "3:1", "/dev/zero", "/nonexistent/x.png", "a" * 300)


def _face_lines(lines: list[str]) -> list[int]:
    return [k for k, ln in enumerate(lines) if ln.startswith("f ")]


def _vertex_count(lines: list[str]) -> int:
    return sum(1 for ln in lines if ln.startswith("v "))


def _star(rng: random.Random, base: int, count: int) -> list[str]:
    """``count`` thin triangles crossing at the origin (valid geometry that stresses the octree rule)."""
    out: list[str] = []
    for k in range(count):
        a = np.pi * k / count
        c, s = float(np.cos(a)), float(np.sin(a))
        out += [f"v {c:.6f} {s:.6f} 0.001", f"v {-c:.6f} {-s:.6f} 0.001", f"v 0 0 {rng.uniform(-1e-3, 1e-3):.7f}"]
        out.append(f"f {base + 3 * k + 1} {base + 3 * k + 2} {base + 3 * k + 3}")
    return out


def mutate_obj(text: str, rng: random.Random) -> str:
    """1-3 mutations of an OBJ file's lines (module docstring); the result may be valid or not."""
    lines = text.splitlines()
    for _ in range(rng.randint(1, 3)):
        faces = _face_lines(lines)
        nv = _vertex_count(lines)
        op = rng.randrange(12)
        if op == 0 and faces:  # coincident copies of one face
            k = rng.choice(faces)
            lines[k + 1:k + 1] = [lines[k]] * rng.choice((1, 7, 8, 50, 400))
        elif op == 1 and faces:  # degenerate: a repeated corner
            i = rng.randint(1, max(nv, 1))
            lines.append(f"f {i} {i} {rng.randint(1, max(nv, 1))}")
        elif op == 2:  # sliver: three almost collinear vertices
            lines += ["v 0 0 0", "v 1 1e-7 0", "v 2 0 1e-7", f"f {nv + 1} {nv + 2} {nv + 3}"]
        elif op == 3:  # a star of thin triangles crossing at one point
            lines += _star(rng, nv, rng.choice((4, 16, 64)))
        elif op == 4 and faces:  # bad, negative, huge, non-integer or textured indices
            k = rng.choice(faces)
            parts = lines[k].split()
            j = rng.randint(1, len(parts) - 1)
            parts[j] = rng.choice(("0", "-1", str(nv + 1), "2147483648", "1.5", "x", "1/2/3", "1//1", "-999999"))
            lines[k] = " ".join(parts)
        elif op == 5 and nv:  # a non-finite or extreme coordinate
            verts = [k for k, ln in enumerate(lines) if ln.startswith("v ")]
            k = rng.choice(verts)
            parts = lines[k].split()
            parts[rng.randint(1, len(parts) - 1)] = rng.choice(("nan", "inf", "-inf", "1e39", "1e-45", "-0", "3e38"))
            lines[k] = " ".join(parts)
        elif op == 6 and faces:  # a polygon of more than three corners
            k = rng.choice(faces)
            lines[k] += " " + " ".join(str(rng.randint(1, max(nv, 1))) for _ in range(rng.randint(1, 3)))
        elif op == 7 and faces:  # every face removed, or every vertex
            keep = "f " if rng.random() < 0.5 else "v "
            lines = [ln for ln in lines if not ln.startswith(keep)]
        elif op == 8:  # other directives and junk
            lines.insert(rng.randint(0, len(lines)), rng.choice(("vt 0.5 0.5", "vn 0 0 1", "usemtl x", "o obj",
                                                                  "g grp", "s 1", "#", "", "\t", "f", "v", "v 1 2")))
        elif op == 9 and lines:  # truncated
            cut = "\n".join(lines)
            lines = cut[:rng.randint(0, len(cut))].splitlines()
        elif op == 10 and faces:  # the whole face list repeated (every face coincident with another)
            lines += [lines[k] for k in faces]
        elif lines:
            del lines[rng.randrange(len(lines))]
    ending = rng.choice(("\n", "\n", "\r\n", "\r"))
    return ending.join(lines) + ending


def _huge_header(data: bytes, rng: random.Random) -> bytes:
    side = rng.choice((30000, 65535, 2**31 - 1, 0))
    if data[:2] == b"BM" and len(data) >= 26:
        return data[:18] + struct.pack("<ii", side, side) + data[26:]
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        return data[:16] + struct.pack(">II", side, side) + data[24:]
    return data[:8]


def odd_image(rng: random.Random, path: Path) -> None:
    """A valid image of an odd kind at ``path`` (its extension picks the format): 1, 2 or 4 channels,
    8 or 16 bits, alpha 128, sizes down to 1x1."""
    import OpenImageIO as oiio

    w, h = rng.choice(((1, 1), (3, 2), (17, 5), (64, 32)))
    channels = rng.choice((1, 2, 3, 4))
    pixels = np.random.default_rng(rng.randrange(2**32)).random((h, w, channels)).astype(np.float32)
    if channels in (2, 4):
        pixels[..., -1] = 128 / 255
    fmt = oiio.UINT16 if rng.random() < 0.3 and path.suffix.lower() in (".png", ".tif") else oiio.UINT8
    for chans, kind in ((channels, fmt), (3, oiio.UINT8)):  # a kind the format cannot hold: plain RGB instead
        out = oiio.ImageOutput.create(str(path))
        if out is not None and out.open(str(path), oiio.ImageSpec(w, h, chans, kind)):
            out.write_image(np.ascontiguousarray(pixels[..., :chans]) if chans <= channels
                            else np.repeat(pixels[..., :1], chans, axis=2))
            out.close()
            return
    path.write_bytes(b"")


def mutate_image(data: bytes, rng: random.Random, path: Path) -> None:
    """Write a mutant of the image ``data`` to ``path`` (module docstring)."""
    op = rng.randrange(7)
    if op == 0:
        path.write_bytes(data[:rng.randint(0, len(data))])
    elif op == 1:
        b = bytearray(data)
        for _ in range(rng.randint(1, 6)):
            if b:
                b[rng.randrange(min(len(b), 64))] = rng.randrange(256)
        path.write_bytes(bytes(b))
    elif op == 2:
        path.write_bytes(_huge_header(data, rng))
    elif op == 3:
        path.write_bytes(b"" if rng.random() < 0.5 else b"not an image\n" * 10)
    else:
        odd_image(rng, path)


def _pick(rng: random.Random, options: list[list[str]], most: int) -> list[str]:
    out: list[str] = []
    for extra in rng.sample(options, rng.randint(0, min(most, len(options)))):
        out += extra
    return out


def _junk(rng: random.Random) -> list[str]:
    """Arguments no command accepts: an unknown flag, a junk size, a flag without its value, a stray
    positional after ``--`` (each ends any command at its flag checks)."""
    return rng.choice((["--frobnicate"], ["--size", rng.choice(JUNK_VALUES[:-1]), "4"], ["--json-file"],
                       ["--", "--x"], ["--size", "1"]))


def command_argv(name: str, rng: random.Random, scene: str, images: tuple[str, str], xml: str | None
                 ) -> tuple[list[str], list[str]]:
    """``(argv, outputs)``: a command line for sub-command ``name`` run in a folder holding ``scene`` (a mutant
    scene file), two images and, when given, a converted scene ``xml``; ``outputs`` are the files it
    should write on success (and never on an error)."""
    a, b = images
    hostile = rng.random() < 0.2 or name in PARSE_ONLY
    size = ["--size", str(rng.randint(1, 8)), str(rng.randint(1, 8))]
    argv: list[str]
    outs: list[str] = []
    if name == "render":  # the caller makes the folder "outdir"
        argv = ["render", scene, "--output-dir", "outdir", *size, *_pick(rng, [["-shadows"], ["-jitter"]], 2)]
        outs = [f"outdir/{Path(scene).stem}.png"]
    elif name == "convert":
        argv = ["convert", scene, "-o", "c.xml", *_pick(rng, [["--stock"], ["--spp", "4"]], 2)]
        outs = ["c.xml"]
    elif name == "compare":
        argv = ["compare", a, b, *_pick(rng, [["--diff", "d.png"], ["--flip"], ["--json"],
                                              ["--threshold", rng.choice(("0", "2", "-1", "nan", "300"))],
                                              ["--scale", rng.choice(("auto", "0", "16", "-3"))],
                                              ["--flip-map", "f.png"], ["--match", "0.5"]], 3)]
    elif name == "trace":
        argv = ["trace", "-input", scene, *size, "--pixel", str(rng.randint(-1, 8)), str(rng.randint(-1, 8)),
                *_pick(rng, [["--json"], ["--svg", "t.svg"], ["-shadows"], ["--diff", a], ["-jitter"]], 2)]
    elif name == "render-xml":
        argv = ["render-xml", xml or scene, "-o", "x.png", *_pick(rng, [["--spp", "2"], ["-D", "x=1"]], 1)]
        outs = ["x.png"]
    elif name == "crosscheck":
        argv = ["crosscheck", scene, *size, "--spp", str(rng.randint(1, 2)), "-o", "cc.png", "--bounces", "2"]
        outs = ["cc.png"]
    elif name == "converge":
        argv = ["converge", scene, *size, "--max-spp", "2", "--reference-spp", "4"]
    elif name == "completion":
        argv = ["completion", rng.choice(("bash", "zsh", "fish"))]
    elif name == "difftest":
        argv = ["difftest", "--binary", rng.choice(("/bin/false", "/bin/true", "/nonexistent")), "--count", "1",
                "--mean-size", "16", "--timeout", "5", "--budget", "2", "-o", "dt"]
    elif name == "animate":
        argv = ["animate", scene, "-o", "frames", *size, "--frames", rng.choice(("0:1", "0:2", "5:1", "x"))]
    elif name == "grade":
        argv = ["grade", "subs", "-o", "report"]
    elif name == "fidelity":
        argv = ["fidelity"]
    else:  # bench, and any command added later: its flag checks
        argv = [name]
    if hostile:
        junk = [rng.choice(("--frobnicate", "--no-such-flag=1", "-z"))] if name in PARSE_ONLY else _junk(rng)
        at = rng.randint(1, len(argv))
        argv[at:at] = junk
        outs = []
    return argv, outs

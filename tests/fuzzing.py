"""The mutation campaign of ``make fuzz``: mutated scenes, meshes, images and command lines through the real commands.

Each mutant (:data:`KINDS`) is a course scene with a few token-level mutations (:func:`mutate`) and a random command
line (:func:`random_flags`: tiny sizes, bounces <= 5 so a glass ray tree stays small); or a course scene whose OBJ
mesh or texture / cube face is mutated (tests/fuzz_inputs.py: coincident, degenerate, sliver and crossing faces, bad
indices, image headers, odd channel counts); or a command line of any ``a5mi`` sub-command (tests/fuzz_inputs.py
:func:`command_argv`); or (:data:`KINDS_ALL`, ``make fuzz``) a numeric keyword of docs/EXTENSIONS.md E.1-E.24, the
E.13-E.24 ones most often, at its documented bounds, float32's edges or a random finite value
(tests/keyword_bounds.py), rendered to an EXR whose pixels must all be finite; or one hostile request to ``a5mi
view``'s HTTP server (tests/fuzz_http.py). It is run through ``a5mi.cli.run`` (``a5``: parse -> describe ->
``mi.load_dict`` -> a real render -> atomic writes) or ``a5mi.cli.run_a5mi`` (``convert``, followed by
``mi.load_file`` of the XML, and the sub-commands), in this process (the variant is loaded once), and judged by
:func:`verdict`: exit 0 with every output written (exit 1 too for a command that gives a verdict), or exit 2 with
exactly one error line and no output; anything else (exit 1 elsewhere, 70, a traceback, two lines, an exception
escaping the guard, a run longer than ``HANG_SECONDS``) is a failure, returned with its seed so that :func:`mutant`
rebuilds it exactly.
"""

from __future__ import annotations

import contextlib
import io
import os
import random
import re
import signal
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

#: A run longer than this is a hang (the renders are at most 36 x 36 samples, 5 bounces; ``crosscheck`` compiles
#: six kernels, ~1 min on a loaded 2-core machine).
HANG_SECONDS = 150

NUMBERS = ("0", "-0", "1", "-1", "0.5", "1.5", "2", "-3", "1e30", "-1e30", "3e38", "1e39", "1e-40", "1e-30",
           "1e20", "2147483647", "2147483648", "-2147483649", "100", "360", "180", "1.0000001", "1" * 60,
           "nan", "inf", "0x10", "1_0", "١", "1e", ".", "-", "+.5", "5.", "1}", "}}")
WORDS = ("{", "}", "Group", "Transform", "Sphere", "Plane", "Triangle", "TriangleMesh", "Material", "Materials",
         "numObjects", "numMaterials", "MaterialIndex", "Lights", "PointLight", "DirectionalLight", "Background",
         "cubeMap", "texture", "obj_file", "Noise", "diffuseColor", "specularColor", "refractionIndex",
         "shininess", "PerspectiveCamera", "Scale", "UniformScale", "Rotate", "XRotate", "Matrix4f", "Translate",
         "falloff", "color", "ambientLight", "octaves", "frequency", "amplitude", "tex/church2", "bunny_200.obj",
         "missing.obj", "tex/none.png", "a\u2028b", "x\x1cy", "#", "//", "é")


#: Finite numbers the grammar accepts: a mild mutant changes values only, so it parses and renders.
FINITE = ("0", "-0", "1", "-1", "0.5", "1.5", "2", "-3", "1e30", "-1e30", "3e38", "1e-40", "1e-30", "1e20",
          "100", "360", "1.0000001", "7", "0.001")


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return word.replace(".", "").replace("-", "").replace("e", "").isdigit()


def mutate_values(text: str, rng: random.Random) -> str:
    """1-6 numbers replaced by other finite numbers (counts and indices included: those may then fail)."""
    tokens = text.split()
    numbers = [k for k, t in enumerate(tokens) if _is_number(t)]
    for k in rng.sample(numbers, min(len(numbers), rng.randint(1, 6))):
        tokens[k] = rng.choice(FINITE)
    return " ".join(tokens) + "\n"


def mutate(text: str, rng: random.Random) -> str:
    """1-4 token mutations: replace a number or a word, delete, duplicate, swap, insert a brace pair, nest a
    Group, truncate."""
    tokens = text.split()
    for _ in range(rng.randint(1, 4)):
        if not tokens:
            break
        k = rng.randrange(len(tokens))
        op = rng.randrange(9)
        if op == 0:
            tokens[k] = rng.choice(NUMBERS)
        elif op == 1:
            tokens[k] = rng.choice(WORDS)
        elif op == 2:
            del tokens[k]
        elif op == 3:
            tokens.insert(k, tokens[k])
        elif op == 4 and k + 1 < len(tokens):
            tokens[k], tokens[k + 1] = tokens[k + 1], tokens[k]
        elif op == 5:
            tokens[k:k] = ["{", "}"]
        elif op == 6:
            if tokens[k] in ("Sphere", "Plane", "Triangle", "TriangleMesh", "Transform", "Group"):
                depth = rng.choice((2, 50, 120))
                tokens[k:k] = ["Group", "{", "numObjects", "1"] * depth
                tokens.extend(["}"] * depth)
        elif op == 7:
            tokens = tokens[:k]
        else:
            tokens[k] = rng.choice(NUMBERS) if rng.random() < 0.5 else tokens[k] + rng.choice(NUMBERS)
    return " ".join(tokens) + "\n"


def random_flags(rng: random.Random, hostile: bool) -> list[str]:
    """A random a5 command line after ``-input``/``-output`` (tiny renders; junk values when ``hostile``)."""
    w, h = rng.randint(1, 12), rng.randint(1, 12)
    flags = ["-size", str(w), str(h)]
    pool: list[list[str]] = [
        ["-shadows"], ["-bounces", str(rng.randint(0, 5))], ["-jitter"], ["-filter"], ["-normals", "n.png"],
        ["-depth", rng.choice(("9", "0", "-1", "1e30")), rng.choice(("11", "10", "0")), "d.exr"],
        ["-reflection_off"], ["-refraction_off"], ["-phong"], ["-fresnel", rng.choice(("a5", "schlick", "exact",
                                                                                       "bogus"))],
        ["-kernel", rng.choice(("binary", "handout"))], ["-normals_mode", rng.choice(("main", "quadrant"))],
        ["-seed", str(rng.randint(0, 9))],
    ]
    if hostile:
        pool += [["-size", rng.choice(("0", "-1", "1_0", "１")), "4"], ["-bounces", rng.choice(("99", "-1", "x"))],
                 ["-frobnicate"], ["-output", rng.choice(("o.gif", "o"))], ["-normals", "o.png"]]
    for extra in rng.sample(pool, rng.randint(0, 4)):
        flags += extra
    return flags


@dataclass
class Outcome:
    seed: int
    argv: list[str]
    status: int | None
    stderr: str
    seconds: float
    problem: str = ""


@dataclass
class Campaign:
    outcomes: list[Outcome] = field(default_factory=list)

    @property
    def failures(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.problem]

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for o in self.outcomes:
            key = o.problem.split(":")[0] if o.problem else f"exit {o.status}"
            out[key] = out.get(key, 0) + 1
        return out


class _Hang(BaseException):  # not an Exception: a command's own "except Exception" must not swallow it
    pass


@contextlib.contextmanager
def _alarm(seconds: int) -> Iterator[None]:
    def on_alarm(signum: int, frame: object) -> None:
        raise _Hang()

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


#: The project's folder: a Python warning raised by its code during a mutant is a failure.
PROJECT = Path(__file__).resolve().parents[1]

#: The closing line of a batch (``a5mi render`` with --output-dir or --jobs): one error line per failed job, then this.
BATCH_SUMMARY = re.compile(r"a5mi render: \d+ of \d+ jobs written in ")

#: Mutant kinds and their shares: a mutated scene through ``a5`` or ``convert``; a course scene with a mutated
#: OBJ mesh, or with a mutated texture / cube face (tests/fuzz_inputs.py); a sub-command's command line.
KINDS = (("scene", 0.5), ("mesh", 0.15), ("image", 0.1), ("command", 0.25))
#: ``make fuzz``'s kinds: :data:`KINDS` and the keywords at their bounds and the view's HTTP surface.
KINDS_ALL = (("scene", 0.35), ("mesh", 0.1), ("image", 0.07), ("command", 0.18), ("keyword", 0.15), ("http", 0.15))


@dataclass
class Mutant:
    """What the seed of a mutant rebuilds: its kind, the source scene, the scene text, the files laid over the
    scene's folder (relative path -> bytes, or a seed for :func:`fuzz_inputs.mutate_image`), and the command."""

    kind: str
    src: Path
    text: str
    files: dict[str, bytes] = field(default_factory=dict)
    image: tuple[str, int] | None = None
    flags: list[str] = field(default_factory=list)
    convert: bool = False
    command: str = ""


def _named(text: str, keyword: str) -> list[str]:
    tokens = text.split()
    return [tokens[k + 1] for k, t in enumerate(tokens[:-1]) if t == keyword]


def _image_files(src: Path, text: str) -> list[str]:
    faces = [f"{d}/{f}" for d in _named(text, "cubeMap") for f in sorted(os.listdir(src.parent / d))
             if f.endswith((".bmp", ".png"))]
    return [*_named(text, "texture"), *faces]


def mutant(seed: int, scenes: list[Path], kinds: tuple[tuple[str, float], ...] = KINDS) -> Mutant:
    """The mutant of ``seed`` (of ``kinds``, default :data:`KINDS`)."""
    from fuzz_inputs import mutate_obj

    from a5mi.cli import SUBCOMMANDS

    rng = random.Random(seed)
    kind = rng.choices([k for k, _ in kinds], [w for _, w in kinds])[0]
    if kind == "mesh":
        scenes = [s for s in scenes if "obj_file" in s.read_text(encoding="utf-8")] or scenes
    elif kind == "image":
        scenes = [s for s in scenes if _image_files(s, s.read_text(encoding="utf-8"))] or scenes
    src = rng.choice(scenes)
    original = src.read_text(encoding="utf-8")
    if kind == "http":
        return Mutant(kind, src, original)
    if kind == "keyword":
        from keyword_bounds import EDGES, KEYWORDS, scene_of

        late = [k for k in KEYWORDS if int(k.section.split(".")[1]) >= 13]
        k = rng.choice(late if rng.random() < 0.7 else KEYWORDS)
        value = rng.choice([*k.bounds, *EDGES, *FINITE])
        text, flags, _ = scene_of(k, value)
        extra = rng.sample([["-shadows"], ["-bounces", str(rng.randint(0, 5))], ["-jitter"], ["-spp", "2"]],
                           rng.randint(0, 2))
        return Mutant(kind, src, text, flags=["-size", str(rng.randint(1, 8)), str(rng.randint(1, 8)), *flags,
                                              *(f for e in extra for f in e)])
    if kind == "command":
        name = rng.choice(list(SUBCOMMANDS))
        r = rng.random()  # the command's own paths need scenes that load: a third unchanged, a fifth broken
        text = original if r < 0.35 else mutate_values(original, rng) if r < 0.8 else mutate(original, rng)
        return Mutant(kind, src, text, command=name)
    if kind == "mesh":
        obj = rng.choice(_named(original, "obj_file"))
        body = (src.parent / obj).read_text(encoding="utf-8", errors="replace")
        files = {obj: mutate_obj(body, rng).encode("utf-8")}
        convert = rng.random() < 0.2
        return Mutant(kind, src, original, files, flags=[] if convert else random_flags(rng, False), convert=convert)
    if kind == "image":
        image = (rng.choice(_image_files(src, original)), rng.randrange(2**31))
        return Mutant(kind, src, original, image=image, flags=random_flags(rng, False))
    hostile = rng.random() < 0.4
    text = mutate(original, rng) if hostile else mutate_values(original, rng)
    convert = rng.random() < 0.15
    return Mutant(kind, src, text, flags=[] if convert else random_flags(rng, hostile and rng.random() < 0.5),
                  convert=convert)


def verdict(status: int | None, err: str, outputs: list[Path], *, may_differ: bool = False,
            batch: bool = False) -> str:
    """'' when the run kept the promise (module docstring), else what went wrong; ``may_differ``: the command
    gives a verdict, so exit 1 (with its outputs) is an answer too; ``batch``: several scenes in one command
    (``a5mi render A B --output-dir``), where each failed job has its own one-line error."""
    lines = [ln for ln in err.splitlines() if ": warning: " not in ln and not BATCH_SUMMARY.match(ln)]
    if "Traceback" in err:
        return "traceback: " + err[-300:]
    if batch and status == 2 and lines and all(": error: " in ln for ln in lines):
        return ""  # the jobs that succeeded are written, each atomically (docs/USAGE.md, batches)
    if status == 0 or (status == 1 and may_differ):
        missing = [str(p) for p in outputs if not p.exists()]
        return f"missing output: {missing}" if missing else ""
    if status == 2:
        if len(lines) != 1:
            return f"not one line: {lines[:3]}"
        written = [str(p) for p in outputs if p.exists()]
        return f"written on error: {written}" if written else ""
    return f"exit {status}: {' | '.join(lines)[:300]}"


def _stage(m: Mutant, run: Path) -> None:
    """Lay the source scene's folder into ``run`` as links, the mutated files as real files."""
    from fuzz_inputs import mutate_image

    replaced = dict(m.files)
    if m.image is not None:
        replaced[m.image[0]] = b""
    dirs = {Path(r).parts[0] for r in replaced if len(Path(r).parts) > 1}
    for p in m.src.parent.iterdir():
        if p.name in dirs:
            _stage_dir(p, run / p.name, replaced, p.name)
        elif p.suffix == ".obj" or p.name == "tex":
            if p.name not in replaced:
                os.symlink(p, run / p.name)
    for rel, data in m.files.items():
        (run / rel).write_bytes(data)
    if m.image is not None:
        rel, image_seed = m.image
        mutate_image((m.src.parent / rel).read_bytes(), random.Random(image_seed), run / rel)


def _stage_dir(src: Path, dst: Path, replaced: dict[str, bytes], prefix: str) -> None:
    dst.mkdir()
    for p in src.iterdir():
        rel = f"{prefix}/{p.name}"
        if p.is_dir() and any(r.startswith(rel + "/") for r in replaced):
            _stage_dir(p, dst / p.name, replaced, rel)
        elif rel not in replaced:
            os.symlink(p, dst / p.name)


def _command(m: Mutant, run: Path, seed: int) -> tuple[list[str], list[Path], bool]:
    """The sub-command line of a command mutant, its inputs written into ``run``."""
    from fuzz_inputs import command_argv, odd_image

    from a5mi import cli

    rng = random.Random(seed ^ 0x5EED)
    a, b = run / "a.png", run / "b.png"
    odd_image(rng, a)
    if rng.random() < 0.5:
        b.write_bytes(a.read_bytes())
    else:
        odd_image(rng, b)
    xml = None
    (run / "outdir").mkdir()
    if m.command == "render-xml":
        with contextlib.redirect_stderr(io.StringIO()):
            if cli.run_a5mi(["convert", "s.txt", "-o", "c.xml", "-q", "--size", "6", "6"]) == 0:
                xml = "c.xml"
    if m.command == "animate" and rng.random() < 0.7:
        anim = Path(__file__).resolve().parents[1] / "scenes" / "animation.txt"
        (run / "s.txt").write_text(mutate_values(anim.read_text(encoding="utf-8"), rng), encoding="utf-8")
        os.symlink(anim.parent / "meshes", run / "meshes")
    argv, outs = command_argv(m.command, rng, "s.txt", ("a.png", "b.png"), xml)
    may_differ = cli.command(m.command).exit_differ is not None
    return [*argv, "-q"], [run / o for o in outs], may_differ


def run_one(seed: int, scenes: list[Path], work: Path, kinds: tuple[tuple[str, float], ...] = KINDS) -> Outcome:
    """Run the mutant of ``seed`` in a fresh folder of ``work`` (the course OBJ files and ``tex/`` linked in,
    the mutated ones written)."""
    from a5mi import cli

    m = mutant(seed, scenes, kinds)
    if m.kind == "http":
        from fuzz_http import judge

        t0 = time.monotonic()
        desc, printed, problem = judge(seed, float(HANG_SECONDS))
        return Outcome(seed, desc, None, printed, time.monotonic() - t0, problem)
    run = work / f"m{seed}"
    run.mkdir()
    _stage(m, run)
    (run / "s.txt").write_text(m.text, encoding="utf-8")
    may_differ = False
    if m.kind == "command":
        cwd = os.getcwd()
        try:
            os.chdir(run)
            argv, outputs, may_differ = _command(m, run, seed)
        finally:
            os.chdir(cwd)
    elif m.convert:
        argv = ["convert", "s.txt", "-o", "o.xml", "-q"]
        outputs = [run / "o.xml"]
    else:
        flags = m.flags
        argv = ["-input", "s.txt", "-output", "o.exr" if m.kind == "keyword" else "o.png", *flags, "-q"]
        names = [flags[i + 1] for i, f in enumerate(flags[:-1]) if f in ("-normals", "-output")]
        names += [flags[i + 3] for i, f in enumerate(flags[:-3]) if f == "-depth"]
        outputs = [run / argv[3], *(run / n for n in dict.fromkeys(names) if n.endswith((".png", ".exr")))]
    err = io.StringIO()
    t0 = time.monotonic()
    cwd = os.getcwd()
    status: int | None = None
    problem = ""
    caught: list[warnings.WarningMessage] = []
    try:
        os.chdir(run)
        with _alarm(HANG_SECONDS), contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            status = cli.run_a5mi(argv) if (m.convert or m.kind == "command") else cli.run(argv)
            if m.convert and status == 0:
                import mitsuba as mi

                mi.load_file(str(run / "o.xml"))
    except _Hang:
        problem = f"hang: more than {HANG_SECONDS} s"
    except BaseException as exc:  # noqa: BLE001 - an exception escaping the guard is a failure to report
        problem = f"escaped: {type(exc).__name__}: {str(exc)[:200]}"
    finally:
        os.chdir(cwd)
    seconds = time.monotonic() - t0
    text_err = err.getvalue()
    ours = [w for w in caught if str(Path(w.filename).resolve()).startswith(str(PROJECT))]
    if not problem and ours:  # a command run as a process would print it on stderr: a second line
        w = ours[0]
        problem = f"python warning: {w.category.__name__}: {w.message} ({w.filename}:{w.lineno})"
    if not problem:
        problem = verdict(status, text_err, outputs, may_differ=may_differ,
                          batch=m.kind == "command" and m.command == "render")
    if not problem and m.kind == "keyword" and status == 0:
        import numpy as np

        from a5mi.platform.imageio import read_image

        bad = int((~np.isfinite(read_image(run / "o.exr"))).any(axis=-1).sum())
        problem = f"non-finite image: {bad} pixels" if bad else ""
    return Outcome(seed, [m.kind, *argv], status, text_err, seconds, problem)


def campaign(scenes: list[Path], work: Path, *, seed: int, count: int, seconds: float,
             kinds: tuple[tuple[str, float], ...] = KINDS) -> Campaign:
    """Run mutants ``seed, seed+1, ...`` (of ``kinds``) until ``count`` are done or ``seconds`` have passed."""
    result = Campaign()
    t_end = time.monotonic() + seconds
    for k in range(count):
        if time.monotonic() > t_end:
            break
        result.outcomes.append(run_one(seed + k, scenes, work, kinds))
    return result

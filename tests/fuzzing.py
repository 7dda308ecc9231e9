"""The mutation campaign of ``make fuzz``: mutated course scenes with random flags through the real commands.

Each mutant is a course scene with a few token-level mutations (:func:`mutate`) and a random command line
(:func:`random_flags`: tiny sizes, bounces <= 5 so a glass ray tree stays small). It is run through
``a5mi.cli.run`` (``a5``: parse -> describe -> ``mi.load_dict`` -> a real render -> atomic writes) or
``a5mi convert`` followed by ``mi.load_file`` of the XML, in this process (the variant is loaded once), and
judged by :func:`verdict`: exit 0 with every output written, or exit 2 with exactly one error line and no
output; anything else (exit 1, a traceback, two lines, an exception escaping the guard, a run longer than
``HANG_SECONDS``) is a failure, returned with its seed so that :func:`mutant` rebuilds it exactly.
"""

from __future__ import annotations

import contextlib
import io
import os
import random
import signal
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

#: A run longer than this is a hang (the renders are at most 36 x 36 samples, 5 bounces).
HANG_SECONDS = 60

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


class _Hang(Exception):
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


def mutant(seed: int, scenes: list[Path]) -> tuple[Path, str, list[str], bool]:
    """The mutant of ``seed``: (source scene, mutated text, flags, convert instead of render)."""
    rng = random.Random(seed)
    src = rng.choice(scenes)
    hostile = rng.random() < 0.4
    original = src.read_text(encoding="utf-8")
    text = mutate(original, rng) if hostile else mutate_values(original, rng)
    convert = rng.random() < 0.15
    return src, text, ([] if convert else random_flags(rng, hostile and rng.random() < 0.5)), convert


def verdict(status: int | None, err: str, outputs: list[Path]) -> str:
    """'' when the run kept the promise (module docstring), else what went wrong."""
    lines = [ln for ln in err.splitlines() if ": warning: " not in ln]
    if "Traceback" in err:
        return "traceback: " + err[-300:]
    if status == 0:
        missing = [str(p) for p in outputs if not p.exists()]
        return f"missing output: {missing}" if missing else ""
    if status == 2:
        if len(lines) != 1:
            return f"not one line: {lines[:3]}"
        written = [str(p) for p in outputs if p.exists()]
        return f"written on error: {written}" if written else ""
    return f"exit {status}: {' | '.join(lines)[:300]}"


def run_one(seed: int, scenes: list[Path], work: Path) -> Outcome:
    """Run the mutant of ``seed`` in a fresh folder of ``work`` (the course OBJ files and ``tex/`` linked in)."""
    from a5mi import cli

    src, text, flags, convert = mutant(seed, scenes)
    run = work / f"m{seed}"
    run.mkdir()
    for p in src.parent.iterdir():
        if p.suffix == ".obj" or p.name == "tex":
            os.symlink(p, run / p.name)
    (run / "s.txt").write_text(text, encoding="utf-8")
    if convert:
        argv = ["convert", "s.txt", "-o", "o.xml", "-q"]
        outputs = [run / "o.xml"]
    else:
        argv = ["-input", "s.txt", "-output", "o.png", *flags, "-q"]
        names = [flags[i + 1] for i, f in enumerate(flags[:-1]) if f in ("-normals", "-output")]
        names += [flags[i + 3] for i, f in enumerate(flags[:-3]) if f == "-depth"]
        outputs = [run / "o.png", *(run / n for n in dict.fromkeys(names) if n.endswith((".png", ".exr")))]
    err = io.StringIO()
    t0 = time.monotonic()
    cwd = os.getcwd()
    status: int | None = None
    problem = ""
    try:
        os.chdir(run)
        with _alarm(HANG_SECONDS), contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            status = cli.run_a5mi(argv) if convert else cli.run(argv)
            if convert and status == 0:
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
    if not problem:
        problem = verdict(status, text_err, outputs)
    return Outcome(seed, argv, status, text_err, seconds, problem)


def campaign(scenes: list[Path], work: Path, *, seed: int, count: int, seconds: float) -> Campaign:
    """Run mutants ``seed, seed+1, ...`` until ``count`` are done or ``seconds`` have passed."""
    result = Campaign()
    t_end = time.monotonic() + seconds
    for k in range(count):
        if time.monotonic() > t_end:
            break
        result.outcomes.append(run_one(seed + k, scenes, work))
    return result

"""Probe scenes for ``a5mi diagnose --binary``: another a5 program rendered on scenes that show every catalogued
mistake and tell any two apart (docs/MISTAKES.md "Probes").

Five small scenes, each with its a5 flags (:data:`PROBES`): ``lit`` (a marble plane, a triangle that shadows it,
three lights of which one point light lies under the triangle and one lights from below: the light loop, shadows,
marble, the saved image), ``corridor`` (two facing mirror planes: the reflection and the bounce budget), ``glass``
(a glass slab with a tilted lower face over marble floors: Snell, Fresnel, total internal reflection), ``spheres``
(a mirror sphere, a glass sphere and a cube map of six gradient faces, narrow field of view: background direction,
camera) and ``placed`` (a stretched sphere, a mirror triangle and a wall under non-uniform ``Transform`` s, a
uniformly scaled sphere: the normal transform, SPEC B.3 notes). :func:`signatures` renders a5mi's own mutants on
them (the test that every mistake shows and every pair differs); :func:`diagnose_binary` runs a program on each in
the sandbox (:func:`a5mi.difftest.runner.run_binary`) and diagnoses each image against a5mi's reference
(:func:`a5mi.diagnose.rank.diagnose`).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.diagnose.rank import Diagnosis, as_levels, diagnose
from a5mi.render.options import RenderOptions

LIT = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 50 }
Lights { numLights 3
  DirectionalLight { direction 0.3 -0.2 -1 color 0.6 0.5 0.4 }
  DirectionalLight { direction 0.1 0.2 1 color 0.3 0.3 0.3 }
  PointLight { position 0.5 0.3 1.0 color 1.6 1.2 0.9 } }
Background { color 0.1 0.1 0.15 ambientLight 0.15 0.15 0.15 }
Materials { numMaterials 2
  Material { diffuseColor 0.5 0.5 0.5
    Noise { color 0.9 0.3 0.1 color 0.1 0.3 0.8 octaves 3 frequency 4 amplitude 2 } }
  Material { diffuseColor 0.2 0.7 0.3 specularColor 0.3 0.3 0.3 shininess 8 } }
Group { numObjects 2
  MaterialIndex 0 Plane { normal 0 0 1 offset 0 }
  MaterialIndex 1 Triangle { vertex0 -0.8 -0.6 1.5 vertex1 0 0.9 1.5 vertex2 0.7 -0.5 1.5 } }
"""

CORRIDOR = """PerspectiveCamera { center 0 0 5 direction 0.2 0.1 -1 up 0 1 0 angle 40 }
Lights { numLights 1
  DirectionalLight { direction 0.2 0.3 -1 color 0.7 0.7 0.7 } }
Background { color 0.3 0.2 0.1 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 2
  Material { diffuseColor 0.3 0.3 0.3 specularColor 0.5 0.4 0.3
    Noise { color 0.9 0.8 0.2 color 0.1 0.2 0.6 octaves 0 frequency 1.5 amplitude 1 } }
  Material { diffuseColor 0.2 0.5 0.2 specularColor 0.6 0.6 0.6 } }
Group { numObjects 3
  MaterialIndex 0 Plane { normal 0 0 1 offset 0 }
  MaterialIndex 1 Plane { normal 0 0 -1 offset -10 }
  MaterialIndex 1 Sphere { center 0.8 0.5 2 radius 0.4 } }
"""

GLASS = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 110 }
Lights { numLights 1
  DirectionalLight { direction 0 0 -1 color 0.8 0.8 0.8 } }
Background { color 0.05 0.05 0.05 ambientLight 0.2 0.2 0.2 }
Materials { numMaterials 3
  Material { diffuseColor 0 0 0 specularColor 0.9 0.9 0.9 refractionIndex 1.5 }
  Material { diffuseColor 0.5 0.5 0.5
    Noise { color 0.9 0.2 0.2 color 0.2 0.9 0.2 octaves 0 frequency 2 amplitude 1 } }
  Material { diffuseColor 0.5 0.5 0.5
    Noise { color 0.2 0.2 0.9 color 0.9 0.9 0.2 octaves 0 frequency 1.3 amplitude 1 } } }
Group { numObjects 4
  MaterialIndex 0 Plane { normal 0 0 1 offset 0 }
  MaterialIndex 0 Plane { normal 0.6 0 -0.8 offset 0.8 }
  MaterialIndex 1 Plane { normal 0 0 1 offset -6 }
  MaterialIndex 2 Plane { normal 0 0 -1 offset -12 } }
"""

SPHERES = """PerspectiveCamera { center 0 1.2 6 direction 0 -0.2 -1 up 0 1 0 angle 40 }
Lights { numLights 2
  DirectionalLight { direction -0.4 -1 -0.5 color 0.7 0.7 0.7 }
  PointLight { position 2 3 2 color 0.5 0.5 0.4 } }
Background { cubeMap cube ambientLight 0.2 0.2 0.2 }
Materials { numMaterials 3
  Material { diffuseColor 0.8 0.3 0.2 }
  Material { diffuseColor 0.6 0.6 0.6 specularColor 0.4 0.4 0.4 }
  Material { diffuseColor 0.1 0.1 0.1 specularColor 0.8 0.8 0.8 refractionIndex 1.5 } }
Group { numObjects 4
  MaterialIndex 1 Plane { normal 0 1 0 offset -1 }
  MaterialIndex 0 Sphere { center -1 0 0 radius 1 }
  MaterialIndex 2 Sphere { center 1.2 -0.2 0.8 radius 0.8 }
  MaterialIndex 0 Sphere { center 0.2 1.6 -1.5 radius 0.5 } }
"""

PLACED = """PerspectiveCamera { center 0 0 5 direction 0 0 -1 up 0 1 0 angle 50 }
Lights { numLights 2
  DirectionalLight { direction -0.3 -0.4 -1 color 0.7 0.7 0.7 }
  PointLight { position 1.5 1.5 3 color 0.4 0.4 0.4 } }
Background { color 0.2 0.1 0.1 ambientLight 0.1 0.1 0.1 }
Materials { numMaterials 3
  Material { diffuseColor 0.8 0.5 0.3 }
  Material { diffuseColor 0.3 0.6 0.8 specularColor 0.5 0.5 0.5 }
  Material { diffuseColor 0.6 0.6 0.6 } }
Group { numObjects 5
  MaterialIndex 2 Plane { normal 0 1 0 offset -1.5 }
  MaterialIndex 0 Transform { Translate -0.8 0.3 0.5 ZRotate 30 Scale 1.8 0.7 0.9
    Sphere { center 0 0 0 radius 0.6 } }
  MaterialIndex 1 Transform { Translate 0.9 -0.2 1 UniformScale 1.3 Scale 1 2.5 1 YRotate 35
    Triangle { vertex0 -0.5 -0.4 0.2 vertex1 0.5 -0.3 -0.2 vertex2 0 0.5 0.1 } }
  MaterialIndex 0 Transform { Translate 0.2 -1 0.8 UniformScale 0.5 Sphere { center 0 0 0 radius 0.6 } }
  MaterialIndex 2 Transform { Scale 2 1 1 YRotate 30 Plane { normal 0 0 1 offset -3 } } }
"""

#: The six cube-map faces of ``spheres``: a colour per face, shaded along the face's u (SPEC A.4), so that the
#: direction a ray looks along is visible in the colour.
FACES: dict[str, tuple[float, float, float]] = {
    "left": (0.9, 0.2, 0.2), "right": (0.2, 0.9, 0.2), "up": (0.3, 0.4, 0.95), "down": (0.9, 0.9, 0.2),
    "front": (0.2, 0.9, 0.9), "back": (0.9, 0.3, 0.9)}


@dataclass(frozen=True)
class Probe:
    """One probe: ``name``, scene text (``cubeMap cube``: the folder :func:`stage` writes) and a5 flags."""

    name: str
    text: str
    size: int = 30
    shadows: bool = True
    bounces: int = 4

    def options(self) -> RenderOptions:
        """The probe's flags as options (always ``-jitter -filter``)."""
        return RenderOptions(width=self.size, height=self.size, shadows=self.shadows, bounces=self.bounces,
                             jitter=True, filter=True)

    def argv(self) -> list[str]:
        """The probe's a5 flags (SPEC B.1 spelling)."""
        return ["-size", str(self.size), str(self.size), *(["-shadows"] if self.shadows else []),
                "-bounces", str(self.bounces), "-jitter", "-filter"]


PROBES: tuple[Probe, ...] = (
    Probe("lit", LIT, bounces=0),
    Probe("corridor", CORRIDOR, shadows=False, bounces=3),
    Probe("glass", GLASS, shadows=False, bounces=4),
    Probe("spheres", SPHERES, bounces=3),
    Probe("placed", PLACED, bounces=2),
)


def stage(probe: Probe, folder: Path) -> Path:
    """Write ``scene.txt`` (and the cube map's 24-bit BMP faces under ``cube/``) into ``folder``; the path."""
    from a5mi.platform.imageio import write_image

    if "cubeMap cube" in probe.text:
        (folder / "cube").mkdir(exist_ok=True)
        ramp = np.linspace(0.35, 1.0, 8, dtype=np.float32)
        for name, colour in FACES.items():
            face = ramp[None, :, None] * np.array(colour, np.float32)[None, None, :]
            write_image(folder / "cube" / f"{name}.bmp", np.repeat(face, 8, axis=0))
    path = folder / "scene.txt"
    path.write_text(probe.text)
    return path


def describe_probe(probe: Probe, folder: Path) -> Any:
    """The scene description of ``probe`` staged in ``folder``."""
    from a5mi.render.session import describe_file

    return describe_file(str(stage(probe, folder)))[0]


def signatures(mistakes: list[str], session: Any = None) -> dict[str, list[np.ndarray]]:
    """Each mistake's images on every probe (a5mi's mutants, 8-bit levels in [0, 1], glibc's jitter), and the
    correct renders under the key ``""``."""
    from a5mi.render.session import RenderSession

    session = session if session is not None else RenderSession()
    out: dict[str, list[np.ndarray]] = {m: [] for m in ["", *mistakes]}
    with tempfile.TemporaryDirectory(prefix="a5mi-probes-") as tmp:
        for probe in PROBES:
            folder = Path(tmp) / probe.name
            folder.mkdir()
            desc = describe_probe(probe, folder)
            for m in out:
                opts = probe.options()
                img = session.render(desc, RenderOptions(**{**opts.__dict__, "mistakes": (m,) if m else ()})).image
                out[m].append(as_levels(img))
    return out


@dataclass
class ProbeResult:
    """One probe's run: ``status`` (``ok`` or why the program gave no image) and its :class:`Diagnosis`."""

    probe: str
    status: str
    diagnosis: Diagnosis | None = None


@dataclass
class BinaryReport:
    """What :func:`diagnose_binary` found: per probe results, the mistakes named (``found``: name -> probes that
    named it) and the probes whose difference no mistake explains (``unexplained``)."""

    binary: str
    probes: list[ProbeResult] = field(default_factory=list)
    found: dict[str, list[str]] = field(default_factory=dict)
    unexplained: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"binary": self.binary, "found": self.found, "unexplained": self.unexplained,
                "probes": [{"probe": p.probe, "status": p.status,
                            "diagnosis": None if p.diagnosis is None else p.diagnosis.to_dict()} for p in self.probes]}


def diagnose_binary(binary: str, *, read_only: tuple[str, ...] = (), timeout: float = 60.0,
                    require_sandbox: bool = True, progress: Callable[[str], None] | None = None) -> BinaryReport:
    """Run ``binary`` (an a5 program) on every probe in the sandbox and diagnose each image (module docstring);
    ``read_only``: more paths the program may read (an interpreter, its libraries)."""
    from a5mi.difftest.runner import Binary, check_binary, run_binary
    from a5mi.render.session import RenderSession

    path = check_binary(binary)
    prog = Binary(path, read_only, require_sandbox)
    session = RenderSession()
    report = BinaryReport(str(path))
    with tempfile.TemporaryDirectory(prefix="a5mi-diagnose-") as tmp:
        for probe in PROBES:
            folder = Path(tmp) / probe.name
            folder.mkdir()
            desc = describe_probe(probe, folder)
            folder.chmod(0o777)
            if progress:
                progress(f"probe {probe.name}: running {path.name}")
            levels, status = run_binary(prog, folder, probe.argv(), timeout)
            if levels is None:
                report.probes.append(ProbeResult(probe.name, status))
                continue
            try:
                d = diagnose(np.clip(np.rint(levels[..., :3]), 0, 255).astype(np.uint8), desc, probe.options(),
                             session=session, progress=progress)
            except ValueError as exc:   # DiagnoseError: the program wrote another size
                report.probes.append(ProbeResult(probe.name, f"image not comparable: {exc}"))
                continue
            report.probes.append(ProbeResult(probe.name, "ok", d))
            if d.verdict == "diagnosis" and d.causes:
                for m in d.causes[0].mistakes:
                    report.found.setdefault(m, []).append(probe.name)
            elif d.verdict == "unexplained":
                report.unexplained.append(probe.name)
    return report


def format_binary(report: BinaryReport) -> str:
    """The report as text: one line per probe, then the mistakes found."""
    lines = [f"{report.binary} on {len(report.probes)} probe scenes:"]
    for p in report.probes:
        d = p.diagnosis
        if d is None:
            lines.append(f"  {p.probe:9s} {p.status}")
        elif d.verdict == "diagnosis":
            best = d.causes[0]
            lines.append(f"  {p.probe:9s} {' + '.join(best.mistakes)} (explains {100 * (best.explained or 0):.1f}%, "
                         f"PSNR {d.psnr:.1f} dB)")
        else:
            lines.append(f"  {p.probe:9s} {d.verdict} (PSNR {d.psnr:.1f} dB)")
    if report.found:
        lines.append("mistakes found: " + ", ".join(f"{m} ({', '.join(ps)})" for m, ps in report.found.items()))
    elif not report.unexplained and all(p.diagnosis is not None for p in report.probes):
        lines.append("no mistake found: every probe matches the reference")
    if report.unexplained:
        lines.append("unexplained differences on: " + ", ".join(report.unexplained))
    return "\n".join(lines)

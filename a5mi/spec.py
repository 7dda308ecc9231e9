"""SPEC constants shared by every layer (a leaf module: standard library only).

Converters, plugins, the driver and the command layer cannot import each other freely (ARCHITECTURE.md,
import rules); everything that must agree between them lives here, once. Each constant names the SPEC
section (``../shared/a5/SPEC.md``) it comes from.
"""

from __future__ import annotations

from pathlib import Path

#: SPEC B.3: tmin of secondary and shadow rays (camera rays start at t = 0).
TMIN: float = 0.001
#: SPEC B.3: a mirror ray is traced when ``|specularColor| > 0.001`` (Euclidean length).
MIRROR_THRESHOLD: float = 0.001
#: SPEC B.3 and its note on the binary's R0: ``a5`` (the binary's R0 = ((nt-1)/(nt+1))²), ``schlick``
#: (textbook R0 = ((nt-n)/(nt+n))²), ``exact`` (unpolarised Fresnel, Mitsuba's ``dielectric``).
FRESNEL_MODES: tuple[str, ...] = ("a5", "schlick", "exact")
#: SPEC B.1: defaults of the a5 command line.
DEFAULT_SIZE: tuple[int, int] = (100, 100)
DEFAULT_BOUNCES: int = 4
#: SPEC B.1: largest accepted side of ``-size``.
MAX_SIZE: int = 16384
#: SPEC B.5: the render buffer is ``JITTER_FACTOR`` times the image size per axis with ``-jitter``.
JITTER_FACTOR: int = 3
#: SPEC A.4: the six cube-map faces, in the order the ``a5_cubemap`` plugin stores them.
CUBE_FACES: tuple[str, ...] = ("left", "right", "up", "down", "front", "back")
#: SPEC A.4: extensions looked for, in order, for a cube-map face named without one.
IMAGE_EXTENSIONS: tuple[str, ...] = (".bmp", ".png", ".jpg", ".jpeg", ".tga", ".ppm", ".tif", ".tiff", ".exr", ".hdr")


def find_cube_face(folder: Path, face: str) -> Path | None:
    """SPEC A.4: the file holding cube-map ``face`` in ``folder``: ``face`` + the first of
    :data:`IMAGE_EXTENSIONS` that is a file, else the first other ``face.*`` file (sorted by name);
    None if there is none."""
    for ext in IMAGE_EXTENSIONS:
        if (folder / f"{face}{ext}").is_file():
            return folder / f"{face}{ext}"
    return next((p for p in sorted(folder.glob(f"{face}.*")) if p.is_file()), None)
#: docs/EXTENSIONS.md E.10 (dispersion): the sampled wavelength range (nm) and the centre wavelength, where a
#: stock (RGB) mapping evaluates Cauchy's n(λ) = A + B/λ².
DISPERSION_RANGE_NM: tuple[float, float] = (400.0, 700.0)
CENTRE_WAVELENGTH_NM: float = 550.0

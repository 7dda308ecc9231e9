"""Reference images and noise bands of grading cases, rendered by a5mi once and cached (docs/GRADING.md).

For a case (scene + a5 flags, :class:`~a5mi.grade.cases.Case`) the reference is a5mi's render through the
normal library path (parse -> :func:`~a5mi.converters.describe.describe` -> :func:`a5mi.render.session.render`,
quantised as SPEC B.1), with the binary's glibc ``rand()`` jitter, or the file the case names in
``--reference DIR`` (e.g. the sample solution's renders). The **noise band** ``sigma`` is the per-pixel,
per-channel sample standard deviation (ddof 1, levels) of the K renders {glibc, ``-seed`` s_1 .. s_{K-1}}
(:data:`NOISE_SEEDS`, K = 8); without ``-jitter`` a render is deterministic and ``sigma`` = 0.

Cache: ``CACHE/<key>/reference.png`` and ``sigma.npy``, ``key`` = SHA-256 of the scene text, the bytes of
every file the scene names (OBJ meshes, textures, cube-map folders), the reference options, the seeds and the
a5mi version; written atomically, so concurrent workers at worst render the same case twice.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import os
from pathlib import Path

import numpy as np

from a5mi import __version__
from a5mi.platform.errors import UserError
from a5mi.platform.imageio import atomic_file, quantize, read_levels, write_image

#: Jitter seeds of the noise band's extra renders (the first render is the binary's glibc stream).
NOISE_SEEDS: tuple[int, ...] = (1001, 1002, 1003, 1004, 1005, 1006, 1007)


@dataclasses.dataclass(frozen=True)
class Reference:
    """A case's reference image (levels, H x W x 3, row 0 = top) and noise band, with their files."""

    image_path: str
    sigma_path: str
    source: str  # "a5mi" or the --reference file

    def load(self) -> tuple[np.ndarray, np.ndarray]:
        return read_levels(self.image_path), np.load(self.sigma_path)


def named_files(scene: Path) -> list[Path]:
    """Files and folders the scene text names (tokens that exist relative to its folder), sorted."""
    out = set()
    for token in scene.read_text(encoding="utf-8", errors="replace").split():
        token = token.strip('"')
        p = scene.parent / token
        if token and token not in (".", "..") and not token.startswith("-") and p.exists():
            out.add(p)
    return sorted(out)


def cache_key(scene: Path, options: object, seeds: tuple[int, ...] = NOISE_SEEDS) -> str:
    """SHA-256 of the scene, the files it names, the options, the seeds and the version (module docstring)."""
    h = hashlib.sha256()
    h.update(scene.read_bytes())
    for p in named_files(scene):
        for f in sorted(p.rglob("*")) if p.is_dir() else [p]:
            if f.is_file():
                h.update(f.name.encode() + b"\0" + f.read_bytes())
    h.update(repr(options).encode() + repr(seeds).encode() + __version__.encode())
    return h.hexdigest()[:24]


def render_levels(scene: Path, options: object) -> np.ndarray:
    """a5mi's 8-bit render of ``scene`` with ``options`` (a RenderOptions), in levels (row 0 = top)."""
    return render_many(scene, [options])[0]


def render_many(scene: Path, options: list[object]) -> list[np.ndarray]:
    """:func:`render_levels` of ``scene`` for each of ``options``, as one batch: the scene parsed, described
    and built once, the kernels reused (:class:`a5mi.render.session.RenderSession`); the images are
    bit-identical to separate renders."""
    from a5mi.render.session import RenderSession, describe_file

    session = RenderSession(None, max_scenes=1)
    desc, _ = describe_file(str(scene))
    return [quantize(session.render(desc, o).image).astype(np.float64) for o in options]  # type: ignore[arg-type]


def render_cpu_seconds(scene: str | Path, options: object) -> float:
    """CPU seconds (all threads of this process, :func:`time.process_time`) of one a5mi render of ``scene``
    with ``options``, parse to image: the yardstick a case's CPU-time bound is calibrated against
    (``docs/GRADING.md`` "Bounds")."""
    import time

    t0 = time.process_time()
    render_many(Path(scene), [options])
    return time.process_time() - t0


def noise_band(renders: list[np.ndarray]) -> np.ndarray:
    """Per-pixel, per-channel sample standard deviation (ddof 1) of the renders; zeros for one render."""
    if len(renders) < 2:
        return np.zeros_like(renders[0], dtype=np.float32)
    return np.std(np.stack(renders), axis=0, ddof=1).astype(np.float32)


def build_reference(scene: str | Path, options: object, cache_dir: str | Path, *,
                    reference_file: str | Path | None = None, seeds: tuple[int, ...] = NOISE_SEEDS) -> Reference:
    """The case's :class:`Reference`, from the cache or rendered now (module docstring). Raises
    :class:`UserError` for a missing scene or unreadable ``reference_file``."""
    scene = Path(scene)
    if not scene.is_file():
        raise UserError(f"scene '{scene}' not found")
    folder = Path(cache_dir) / cache_key(scene, options, seeds)
    folder.mkdir(parents=True, exist_ok=True)
    ref_png, sigma_npy = folder / "reference.png", folder / "sigma.npy"
    if not (ref_png.is_file() and sigma_npy.is_file()):
        variants = [options]
        if getattr(options, "jitter", False):
            variants += [dataclasses.replace(options, seed=s) for s in seeds]  # type: ignore[type-var]
        renders = render_many(scene, variants)
        buf = io.BytesIO()
        np.save(buf, noise_band(renders))
        with atomic_file(sigma_npy) as f:
            f.write(buf.getvalue())
        write_image(ref_png, renders[0] / 255.0 + 0.5 / 255.0)  # exact levels through quantize's truncation
    if reference_file is not None:
        given = Path(reference_file)
        read_levels(given)  # raises ImageReadError (a UserError) when unreadable
        return Reference(str(given), str(sigma_npy), str(given))
    return Reference(str(ref_png), str(sigma_npy), "a5mi")


def default_cache_dir() -> Path:
    """``$A5MI_CACHE_DIR/grade``, else ``$XDG_CACHE_HOME/a5mi/grade``, else ``~/.cache/a5mi/grade``."""
    env = os.environ.get("A5MI_CACHE_DIR")
    if env:
        return Path(env) / "grade"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "a5mi" / "grade"


__all__ = ["NOISE_SEEDS", "Reference", "build_reference", "cache_key", "default_cache_dir", "named_files",
           "noise_band", "render_cpu_seconds", "render_levels", "render_many"]

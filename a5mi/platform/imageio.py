"""Image output and input through OpenImageIO: quantisation, orientation, atomic writes (SPEC B.1, A.4).

* Quantisation as the sample solution: ``byte = clamp(int(c * 255), 0, 255)`` with ``c * 255`` in float32
  and ``int`` truncating toward zero (0.5 -> 127, 1.2 -> 255, -0.1 -> 0; NaN -> 0). No gamma.
* Orientation: the a5 image origin is the bottom-left pixel (SPEC B.1). :func:`write_image` takes the
  image with row 0 = the **top** row of the file, i.e. the renderer's row ``j = H-1``; the driver flips.
* Formats by extension: ``.png .bmp .tga .ppm .tif .tiff`` (8-bit, quantised) and ``.exr`` (float32,
  unquantised, linear).
* Writes are atomic: the image goes to a temporary file in the destination folder, then ``os.replace``
  moves it over the target, so a failure never leaves a partial file and never clobbers an existing one.
  :func:`write_images` is all-or-nothing for several outputs (``-output``, ``-normals``, ``-depth``):
  every temporary file is written first and only then are they all renamed; if any write fails, every
  temporary is removed and no target is touched.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt

from a5mi.platform import interrupts, resources
from a5mi.platform.errors import ImageReadError, ImageWriteError
from a5mi.platform.paths import check_target, file_kind, remove_stale, short, temp_prefix

#: Extensions written as 8-bit (quantised) images.
BYTE_FORMATS: frozenset[str] = frozenset({".png", ".bmp", ".tga", ".ppm", ".tif", ".tiff"})
#: Extensions written as float images.
FLOAT_FORMATS: frozenset[str] = frozenset({".exr"})
EXTENSIONS: tuple[str, ...] = tuple(sorted(BYTE_FORMATS | FLOAT_FORMATS))
#: zlib level of PNG outputs: 1 writes a 300x300 render in 7 ms instead of 26 ms (OpenImageIO's default 6)
#: for a file about 15% larger; the pixels are the same.
PNG_COMPRESSION = 1


#: ``2³¹``: the first float the x86 conversion to int32 (``cvttss2si``) cannot represent.
_INT32_LIMIT = np.float32(2.0**31)


def quantize(img: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """``byte = clamp(int(c * 255), 0, 255)``: float32 product, truncation toward zero (SPEC B.1), with the x86
    conversion's rule for what int32 cannot hold: a product ``>= 2³¹`` (``c >= 8,421,504.5``), ``< −2³¹``, ``±inf``
    or NaN converts to ``INT_MIN`` (the "integer indefinite" value), which the clamp makes 0. So a colour
    beyond 8.4 million is black, as in a5soln (measured: a Lambert colour of 8.0e6 renders 255, 8.5e6 renders 0;
    docs/FIDELITY.md, the Schlick blow-up)."""
    with np.errstate(over="ignore", invalid="ignore"):  # c near FLT_MAX: c·255 = inf, no warning
        scaled = np.asarray(img, dtype=np.float32) * np.float32(255.0)
        held = (scaled < _INT32_LIMIT) & (scaled >= -_INT32_LIMIT)          # False for NaN and ±inf too
    scaled = np.where(held, scaled, np.float32(0.0))
    return np.clip(np.trunc(scaled), 0.0, 255.0).astype(np.uint8)


def _extension(path: str | os.PathLike[str]) -> str:
    return Path(path).suffix.lower()


def check_output_path(path: str | os.PathLike[str]) -> Path:
    """Raise :class:`ImageWriteError` unless ``path`` can be written: known extension, then
    :func:`check_target`. Called by the CLI **before** rendering. Returns the path."""
    p = Path(path)
    ext = _extension(p)
    if ext not in BYTE_FORMATS and ext not in FLOAT_FORMATS:
        found = f"unknown image extension '{ext}'" if ext else "no image extension"
        raise ImageWriteError(f"{short(p)}: {found} (expected one of {' '.join(EXTENSIONS)})")
    return check_target(p)


def _as_hwc(img: npt.ArrayLike) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"expected an HxW, HxWx1, HxWx3 or HxWx4 image, got shape {a.shape}")
    return a


def _target_mode(p: Path) -> int:
    """The permission bits the file would get from a plain ``open``: the old file's, else 0o666 & ~umask."""
    try:
        return p.stat().st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0o022)
        os.umask(umask)
        return 0o666 & ~umask


def write_image(path: str | os.PathLike[str], img: npt.ArrayLike) -> None:
    """Write ``img`` (HxWxC float, row 0 = top of the file) to ``path`` atomically, format by extension.

    8-bit formats are quantised with :func:`quantize` (a ``uint8`` image is written as it is); ``.exr``
    stores float32 as is. Raises
    :class:`ImageWriteError` (and leaves any existing file untouched) on failure.
    """
    write_images([(path, img)])


def _write_temp(p: Path, img: npt.ArrayLike) -> str:
    """Write ``img`` to a new temporary file beside ``p`` (same extension, the mode ``p`` will get) and
    return its name; on failure nothing is left behind."""
    a = _as_hwc(img)
    import OpenImageIO as oiio  # deferred: only the commands that write images pay for it

    if _extension(p) in FLOAT_FORMATS:
        pixels, fmt = np.ascontiguousarray(a, dtype=np.float32), oiio.FLOAT
    elif a.dtype == np.uint8:
        pixels, fmt = np.ascontiguousarray(a), oiio.UINT8  # already 8-bit levels (montages, diffs)
    else:
        pixels, fmt = np.ascontiguousarray(quantize(a)), oiio.UINT8
    h, w, c = pixels.shape
    folder = p.parent if str(p.parent) else Path(".")
    remove_stale(folder, p.name)
    fd, tmp = tempfile.mkstemp(prefix=temp_prefix(p.name), suffix=p.suffix, dir=folder)
    os.close(fd)
    try:
        out = oiio.ImageOutput.create(tmp)
        if out is None:
            raise ImageWriteError(f"{p}: cannot create a writer: {oiio.geterror()}")
        spec = oiio.ImageSpec(w, h, c, fmt)
        if _extension(p) == ".png":
            spec.attribute("png:compressionLevel", PNG_COMPRESSION)
        with native_stderr() as printed:
            ok = out.open(tmp, spec) and out.write_image(pixels)
            err = out.geterror() if not ok else ""
            ok = out.close() and ok
        if not ok:
            err = _with_native(err or out.geterror() or "unknown OpenImageIO error", printed)
            raise ImageWriteError(f"{p}: write failed: {err}")
        _verify(p, tmp, pixels)
        os.chmod(tmp, _target_mode(p))
    except BaseException:
        _remove(tmp)
        raise
    return tmp


def _no_space(folder: Path) -> str:
    try:
        st = os.statvfs(folder)
    except OSError:
        return ""
    return " (no space left on device)" if st.f_bavail * st.f_frsize < (1 << 20) else ""


def _verify(p: Path, tmp: str, pixels: np.ndarray) -> None:
    """The written temporary is on disk and decodes to ``pixels``: fsync it (ENOSPC shows here on delayed
    allocation), require a non-empty file, read it back and compare exactly (every format written is
    lossless). Raises :class:`ImageWriteError` naming the target."""
    folder = Path(tmp).parent
    try:
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
            size = os.fstat(fd).st_size
        finally:
            os.close(fd)
    except OSError as exc:
        raise ImageWriteError(f"{p}: write failed: {exc.strerror or exc}") from None
    if size == 0:
        raise ImageWriteError(f"{p}: write failed: the image file is empty{_no_space(folder)}")
    try:
        back, _ = _decode(Path(tmp), "float" if pixels.dtype == np.float32 else "uint8")
    except ImageReadError as exc:
        raise ImageWriteError(f"{p}: write failed: the written file does not read back ({exc.reason})"
                              f"{_no_space(folder)}") from None
    same = back.shape == pixels.shape and np.array_equal(back, pixels, equal_nan=pixels.dtype == np.float32)
    if not same:
        raise ImageWriteError(f"{p}: write failed: the written file does not hold the image"
                              f"{_no_space(folder)}")




def _remove(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except FileNotFoundError:
        pass


def write_images(outputs: Sequence[tuple[str | os.PathLike[str], npt.ArrayLike]]) -> None:
    """Write several images, all or nothing (module docstring).

    All paths are checked first (:func:`check_output_path`), then every image is written to a temporary
    file beside its target; only when all of them are written is each moved over its target with
    ``os.replace``. If a check or a write fails, the temporaries are removed, no target is touched, and
    the error (:class:`ImageWriteError`, or ``ValueError`` for a malformed image) is raised.
    """
    paths = [check_output_path(path) for path, _ in outputs]
    temps: list[str] = []
    renamed = 0
    interrupts.check()  # a signal that arrived before the write: nothing is written
    try:
        for p, (_, img) in zip(paths, outputs, strict=True):
            with interrupts.protected():
                temps.append(_write_temp(p, img))
        interrupts.check()
        with interrupts.protected():  # the renames are one step: a signal waits until all are done
            for tmp, p in zip(temps, paths, strict=True):
                os.replace(tmp, p)  # same folder: fails only if the target became a directory meanwhile
                renamed += 1
    except BaseException:
        for tmp in temps[renamed:]:
            _remove(tmp)
        raise


@contextmanager
def native_stderr() -> Iterator[list[str]]:
    """Capture what C libraries print on descriptor 2 in the body (libpng's ``libpng error: ...`` lines while
    OpenImageIO decodes or encodes): the descriptor points at a temporary file for the body and is restored
    after it; the yielded list then holds the captured text as one line (whitespace runs folded), empty when
    nothing was printed. The caller folds it into its one error line or drops it (the one-line rule of
    docs/CLI.md "Exit status"). When the descriptor cannot be redirected the body runs unchanged."""
    captured: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:
        yield captured
        return
    sink = tempfile.TemporaryFile()
    try:
        os.dup2(sink.fileno(), 2)
    except OSError:
        os.close(saved)
        sink.close()
        yield captured
        return
    try:
        yield captured
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        sink.seek(0)
        text = " ".join(sink.read(4096).decode("utf-8", "replace").split())
        sink.close()
        if text:
            captured.append(text)


def _with_native(reason: str, native: list[str]) -> str:
    """``reason`` plus the text a C library printed (:func:`native_stderr`) when it adds something."""
    extra = native[0] if native else ""
    if not extra or extra.removeprefix("libpng error: ") in reason:
        return reason
    return f"{reason} ({extra})" if reason else extra


def _read_error(p: Path, reason: str) -> ImageReadError:
    """The one error of an unreadable image: ``PATH: cannot read image: REASON`` (OpenImageIO's messages may
    span lines: one line here)."""
    reason = " ".join(reason.split()) or "unknown error"
    return ImageReadError(f"{p}: cannot read image: {reason}", reason=reason)


def _open_input(p: Path) -> Any:
    """OpenImageIO's ``ImageInput`` of ``p`` (the header read), or :class:`ImageReadError` with what the
    format library printed folded in (:func:`native_stderr`)."""
    import OpenImageIO as oiio  # deferred: only the commands that read images pay for it

    if not p.is_file():  # a FIFO would block the format library's open() (and with it SIGINT), a device never ends
        raise _read_error(p, "no such image file" if not p.exists() else f"not a regular file ({file_kind(p)})")
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # the stored colour bytes, never multiplied by an alpha channel
    with native_stderr() as printed:
        inp = oiio.ImageInput.open(str(p), config)
    if inp is None:
        raise _read_error(p, _with_native(oiio.geterror() or "unknown format", printed))
    return inp


def _require_memory(p: Path, w: int, h: int, c: int, copy_bytes: int = 0, pixel_bytes: int = 0) -> None:
    """Raise :class:`ImageReadError` unless decoding a ``w x h x c`` image fits in memory:
    ``resources.image_bytes(w, h, c) + w h (c copy_bytes + pixel_bytes) <= resources.available()``."""
    need = resources.image_bytes(w, h, c) + w * h * (c * copy_bytes + pixel_bytes)
    enough, have = resources.fits(need)
    if not enough:
        raise _read_error(p, f"{w}x{h} pixels need about {resources.gb(need)} of memory to decode; "
                             f"{resources.gb(have or 0)} is available")


def _decode(p: Path, dtype: str | None, copy_bytes: int = 0, pixel_bytes: int = 0) -> tuple[np.ndarray, bool]:
    """The one OpenImageIO reader of the project: the whole image at ``p`` as (H, W, C), row 0 = the top row,
    and whether the file stores 8 bits per channel. ``dtype``: ``"uint8"`` (converted by OpenImageIO when the
    file is deeper), ``"float"``, or None (uint8 for 8-bit files, float32 otherwise). Raises
    :class:`ImageReadError` whose ``reason`` is the cause without the path (empty, not an image, truncated).
    The header's size is checked before decoding: :func:`a5mi.platform.resources.image_bytes` plus ``copy_bytes`` per
    sample and ``pixel_bytes`` per pixel (the caller's converted copies) must fit in
    :func:`a5mi.platform.resources.available`."""

    def fail(reason: str) -> ImageReadError:
        return _read_error(p, reason)

    if not p.is_file():
        raise fail("no such image file") if not p.exists() else fail("not a regular file")
    if p.stat().st_size == 0:
        raise fail("the file is empty")
    import OpenImageIO as oiio  # deferred: only the commands that read images pay for it

    inp = _open_input(p)
    try:
        spec = inp.spec()
        _require_memory(p, spec.width, spec.height, spec.nchannels, copy_bytes, pixel_bytes)
        native = spec.format.basetype == oiio.UINT8
        want = dtype or ("uint8" if native else "float")
        with native_stderr() as printed:
            data = inp.read_image(0, 0, 0, spec.nchannels, want) if spec.width > 0 and spec.height > 0 else None
        reason = "" if data is not None else _with_native(inp.geterror() or oiio.geterror() or "no pixel data",
                                                          printed)
    finally:
        inp.close()
    if data is None:
        raise fail(reason)
    a = np.asarray(data).reshape(spec.height, spec.width, spec.nchannels)
    return a, native


def check_image_fits(path: str | os.PathLike[str], copy_bytes: int = 0) -> tuple[int, int, int]:
    """Read only the header of the image at ``path`` and raise :class:`ImageReadError` unless its decoded
    pixels fit in memory: :func:`a5mi.platform.resources.image_bytes` plus ``copy_bytes`` per sample must fit in
    :func:`a5mi.platform.resources.available` (for a decoder that is not this module's, e.g. Mitsuba's ``bitmap``).
    Returns (width, height, channels)."""
    p = Path(path)
    inp = _open_input(p)
    try:
        spec = inp.spec()
        w, h, c = spec.width, spec.height, spec.nchannels
    finally:
        inp.close()
    _require_memory(p, w, h, c, copy_bytes)
    return w, h, c


def read_uint8(path: str | os.PathLike[str]) -> npt.NDArray[np.uint8]:
    """An image file as (H, W, C) ``uint8`` exactly as OpenImageIO's ``read_image(..., "uint8")`` gives it
    (row 0 = top; SPEC A.4 uses the file's bytes as they are). Raises :class:`ImageReadError`."""
    a, _ = _decode(Path(path), "uint8")
    return np.ascontiguousarray(a, dtype=np.uint8)


def read_image(path: str | os.PathLike[str]) -> npt.NDArray[np.float32]:
    """Read an image as float32 HxWxC (row 0 = top of the file); 8-bit data is divided by 255, no gamma.

    Raises :class:`ImageReadError` for a missing, unreadable or corrupt file.
    """
    a, native = _decode(Path(path), None, copy_bytes=8)  # the float32 copy and its scaled copy
    if native:
        return a.astype(np.float32) / np.float32(255.0)
    return a.astype(np.float32)


def read_levels(path: str | os.PathLike[str]) -> npt.NDArray[np.float64]:
    """An image as float64 8-bit levels (H, W, 3), row 0 = top: 8-bit files exactly 0..255, deeper files
    ``value·255``; grey replicated to three channels, alpha dropped. Raises :class:`ImageReadError`."""
    # the float64 copy and its scaled copy; grey replicated to three float64 channels
    a, native = _decode(Path(path), None, copy_bytes=16, pixel_bytes=24)
    img = a.astype(np.float64) * (1.0 if native else 255.0)
    if img.shape[2] < 3:
        img = np.repeat(img[:, :, :1], 3, axis=2)
    return img[:, :, :3]


@contextmanager
def atomic_file(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; on a clean exit it is flushed, ``fsync``-ed, given
    the mode a plain ``open`` would give ``path`` and moved over it with ``os.replace``; on any exception it
    is removed and ``path`` is untouched. The one atomic text/binary writer (XML, caches)."""
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    remove_stale(folder, p.name)
    fd, tmp = tempfile.mkstemp(prefix=temp_prefix(p.name), suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as f:
            yield f
            with interrupts.protected():
                f.flush()
                os.fsync(f.fileno())
        with interrupts.protected():
            os.chmod(tmp, _target_mode(p))
            os.replace(tmp, p)
    except BaseException:
        _remove(tmp)
        raise

"""Frames to a video with ``imageio-ffmpeg`` (its ffmpeg binary ships in the PyPI wheel; docs/ANIMATION.md).

``.mp4``: H.264 (``libx264``, ``yuv420p``, quality 8 of 10), sizes rounded by ffmpeg's 2-pixel blocks.
``.gif``: one palette for the whole clip (``palettegen`` / ``paletteuse``), looping. The file is written
to a temporary name beside the target and renamed when ffmpeg has finished, so a failed or interrupted
encode leaves no partial video.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from a5mi.platform import imageio, paths
from a5mi.platform.errors import ImageWriteError
from a5mi.runtime.extras import require

FORMATS = (".mp4", ".gif")


def check_video_path(path: str | os.PathLike[str]) -> Path:
    """Raise :class:`ImageWriteError` unless ``path`` ends in ``.mp4`` / ``.gif`` in an existing folder."""
    p = Path(path)
    if p.suffix.lower() not in FORMATS:
        raise ImageWriteError(f"--video '{p}': expected a .mp4 or .gif file name")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ImageWriteError(f"--video '{p}': folder '{folder}' does not exist")
    return p


def encode(path: str | os.PathLike[str], frame_files: Iterable[Path], fps: float) -> None:
    """Encode the images ``frame_files`` (in order, all of one size) into ``path`` at ``fps``."""
    imageio_ffmpeg = require("imageio_ffmpeg", "animate")

    p = check_video_path(path)
    files = list(frame_files)
    if not files:
        raise ImageWriteError(f"--video '{p}': no frames to encode")
    first = imageio.read_uint8(files[0])
    h, w = first.shape[:2]
    gif = p.suffix.lower() == ".gif"
    folder = p.parent if str(p.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=paths.temp_prefix(p.name), suffix=p.suffix, dir=folder)
    os.close(fd)
    try:
        kwargs = (dict(codec="gif", pix_fmt_out="rgb8", macro_block_size=1,
                       output_params=["-vf", "split[a][b];[a]palettegen=stats_mode=full[p];[b][p]paletteuse",
                                      "-loop", "0"])
                  if gif else dict(codec="libx264", quality=8, macro_block_size=2))
        writer = imageio_ffmpeg.write_frames(tmp, (w, h), fps=fps, ffmpeg_log_level="error", **kwargs)
        writer.send(None)
        for f in files:
            img = imageio.read_uint8(f)
            if img.shape[:2] != (h, w):
                raise ImageWriteError(f"--video: frame '{f.name}' is {img.shape[1]}x{img.shape[0]}, not {w}x{h}")
            writer.send(np.ascontiguousarray(img[:, :, :3]))
        writer.close()
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)  # the mode a plain open() would give (mkstemp makes it 0600)
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise

"""The files a scene names (SPEC A.0 paths, A.4 images and cube maps, A.6 OBJ meshes), resolved and read once.

Every file name of the scene (``obj_file``, ``texture``, ``cubeMap``) is resolved with
:func:`resolve_path` (scene folder first, then the working directory; SPEC A.0 used only the
working directory) and checked here, so a bad file is a :class:`SceneSemanticError` at the keyword that named
it, before Mitsuba is imported. Images are decoded whole, once, with the project's one OpenImageIO reader
(:func:`a5mi.platform.imageio.read_uint8`, 8 bits per channel, row 0 = the top row: SPEC A.4 uses the file's bytes as
they are); the pixels travel in the scene description (:class:`Image`) to the plugins, which never read the
file again on the ``mi.load_dict`` path. A caller that describes an edited scene again (``a5mi view``) passes the
images (:data:`Decoded`) and OBJ meshes (:data:`Meshes`) of the earlier descriptions; a mesh is kept while its
file's identity (:func:`file_identity`) stays the same.
"""

from __future__ import annotations

import errno
import os
import stat
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from a5mi.converters import obj as objfile
from a5mi.converters.errors import FileLoc, SceneSemanticError, shown
from a5mi.converters.model import Material, Scene
from a5mi.platform import imageio
from a5mi.platform.errors import ImageReadError
from a5mi.spec import CUBE_FACES, find_cube_face

#: Largest file followed as a text "link" (a git symlink checked out as a file) for ``cubeMap``.
LINK_FILE_MAX_BYTES = 4096


def resolve_path(name: str, base_dir: Path, loc: FileLoc, what: str, *, directory: bool = False) -> Path:
    """Resolve a file name of the scene: ``base_dir / name`` if it exists, else ``cwd / name`` (SPEC A.0 used
    only the working directory; the scene folder first lets scenes run from anywhere). A missing path is a
    :class:`SceneSemanticError` at ``loc``, naming both places tried; so is a folder where a file is expected
    (or the reverse)."""
    p = Path(name)
    candidates = [p] if p.is_absolute() else [base_dir / p, Path.cwd() / p]
    kind = "folder" if directory else "file"
    found: list[tuple[Path, str]] = []  # (candidate, what is there) for entries of the wrong kind
    for c in candidates:
        try:
            mode = os.stat(c).st_mode
        except OSError as exc:  # missing, a name longer than the filesystem allows, a loop of links...
            if exc.errno not in (errno.ENOENT, errno.ENOTDIR):
                raise SceneSemanticError(f"{what} '{shown(name)}': {exc.strerror or exc}", loc) from None
            continue
        if stat.S_ISDIR(mode) if directory else stat.S_ISREG(mode):
            return c
        found.append((c, "a folder" if stat.S_ISDIR(mode) else "a file" if stat.S_ISREG(mode) else
                      "a FIFO" if stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                      else "a special file"))
    if found:
        c, there = found[0]
        raise SceneSemanticError(f"{what} '{shown(name)}' is {there}, not a {kind} ('{shown(str(c), 200)}')", loc)
    tried = " or ".join(f"'{shown(str(c), 200)}'" for c in dict.fromkeys(candidates))
    raise SceneSemanticError(f"{what} {kind} '{shown(name)}' not found (looked for {tried})", loc)


@dataclass(frozen=True, eq=False)
class Image:
    """A decoded image file: ``path`` (absolute) and its ``pixels`` as OpenImageIO's
    ``read_image(..., "uint8")`` gives them, (H, W, C) ``uint8``, row 0 = the top row, read-only."""

    path: Path
    pixels: np.ndarray

    @property
    def size(self) -> tuple[int, int]:
        """``(W, H)``."""
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])


#: Images already decoded during one description, by absolute path (several materials may share a file).
Decoded = dict[Path, Image]


def read_image(path: Path, loc: FileLoc, what: str, decoded: Decoded | None = None) -> Image:
    """Decode the whole image at ``path`` (SPEC A.4: 8 bits per channel) with :func:`a5mi.platform.imageio.read_uint8`,
    unless ``decoded`` holds it already (then that :class:`Image`; a new one is added to it). Raises
    :class:`SceneSemanticError` at ``loc``: ``{what} '{path}' is not a readable image: {reason}`` (empty,
    unreadable, not an image, truncated)."""
    key = path.resolve()
    if decoded is not None and key in decoded:
        return decoded[key]
    try:
        pixels = imageio.read_uint8(path)
    except ImageReadError as exc:
        raise SceneSemanticError(f"{what} '{path}' is not a readable image: {exc.reason}", loc) from None
    pixels.flags.writeable = False
    image = Image(key, pixels)
    if decoded is not None:
        decoded[key] = image
    return image


#: A file's identity: ``(st_mtime_ns, st_size, st_ino)`` (following links); a save, in place or by rename,
#: changes it.
Identity = tuple[int, int, int]
#: A mesh file modified less than this many nanoseconds before it was read is not kept (it may still have been
#: being written, and file times come from the kernel's coarse clock, some milliseconds behind): the next
#: description reads it again.
SETTLE_NS = 100_000_000


@dataclass(eq=False)
class KeptMesh:
    """An OBJ mesh read by an earlier description: the file's :data:`Identity` when it was read, the parsed mesh
    (its arrays read-only), once computed its :func:`.octree.reach_masks` and their warning messages, and the
    world-space :class:`~.geometry.MeshData` of its recent placements (read-only arrays; keyed by the
    description, :func:`.describe.placed_mesh`)."""

    identity: Identity
    mesh: objfile.ObjMesh
    reach: tuple[np.ndarray, tuple[str, ...]] | None = None
    placed: dict[tuple[Any, ...], Any] = field(default_factory=dict)


#: OBJ meshes of earlier descriptions by resolved absolute path (``a5mi view`` keeps them across saves).
Meshes = dict[Path, KeptMesh]


class KeptFiles:
    """The decoded images (:data:`Decoded`) and OBJ meshes (:data:`Meshes`) a caller that describes scene after
    scene (``a5mi view`` on each save, ``a5mi serve`` on each request) keeps between descriptions: pass
    :attr:`decoded` and :attr:`meshes` to :func:`.describe.describe` between :meth:`begin` and :meth:`end`. An
    image is kept while its file's :func:`file_identity` is the one it had just after it was decoded, and only
    when it was not modified after the description started (it may have been decoded half-written); a mesh by
    :func:`load_mesh`'s rule, and only while the last description names it."""

    def __init__(self) -> None:
        self.decoded: Decoded = {}
        self.meshes: Meshes = {}
        self._identities: dict[Path, Identity | None] = {}

    def begin(self) -> int:
        """Drop the images whose file changed (or vanished) since they were decoded; returns the start time
        (ns) for :meth:`end`."""
        for path, was in list(self._identities.items()):
            if file_identity(path) != was:
                self.decoded.pop(path, None)
                del self._identities[path]
        return time.time_ns()

    def end(self, started: int) -> None:
        """After a description begun at ``started`` (:meth:`begin`; also after a failed one): remember the
        identity of each newly decoded image, dropping one modified since ``started``."""
        for path in list(self.decoded):
            if path not in self._identities:
                now = file_identity(path)
                if now is None or now[0] >= started:
                    self.decoded.pop(path)
                else:
                    self._identities[path] = now

    def keep_meshes(self, used: set[Any]) -> None:
        """Let go of the meshes a description no longer names (``used``: its shapes' ``obj_file`` paths)."""
        for path in [p for p in self.meshes if p not in used]:
            del self.meshes[path]


def file_identity(path: Path) -> Identity | None:
    """:data:`Identity` of ``path``, None when it cannot be stat'ed."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size, st.st_ino


def load_mesh(scene: Scene, name: str, loc: FileLoc, kept: Meshes | None = None) -> tuple[Path, objfile.ObjMesh]:
    """The OBJ file ``name`` of a ``TriangleMesh`` (SPEC A.6): its resolved absolute path and the mesh parsed by
    :func:`.obj.load_obj` (which reports errors at the OBJ line at fault; a missing file is an error at
    ``loc``). With ``kept``: the mesh kept there for this path is returned unread while the file's identity is
    the one it was read with (and the scene names it with the same text); a mesh read is kept there unless its
    file changed during the read or within :data:`SETTLE_NS` before it."""
    path = resolve_path(name, scene.base_dir, loc, "obj_file")
    key = path.resolve()
    if kept is None:
        return key, objfile.load_obj(path, loc)
    before = file_identity(key)
    entry = kept.get(key)
    if entry is not None and before is not None and entry.identity == before and entry.mesh.path == str(path):
        return key, entry.mesh
    kept.pop(key, None)
    started = time.time_ns()
    mesh = objfile.load_obj(path, loc)
    if before is not None and before[0] < started - SETTLE_NS and file_identity(key) == before:
        for a in (mesh.vertices, mesh.faces, mesh.texcoords, mesh.face_texcoords):
            if a is not None:
                a.flags.writeable = False
        kept[key] = KeptMesh(before, mesh)
    return key, mesh


def texture_image(scene: Scene, mat: Material, decoded: Decoded | None = None) -> Image:
    """The material's ``texture`` file (SPEC A.5), resolved and decoded (:func:`read_image`); missing,
    unreadable or not an image -> :class:`SceneSemanticError` at its loc."""
    assert mat.texture is not None
    loc = mat.texture_loc or mat.loc
    assert loc is not None
    return read_image(resolve_path(mat.texture, scene.base_dir, loc, "texture"), loc, "texture", decoded)


def map_image(scene: Scene, mat: Material, which: str, decoded: Decoded | None = None
              ) -> tuple[Image, str | None]:
    """The material's ``bump`` or ``normalMap`` file (docs/EXTENSIONS.md E.7; ``which`` = ``bump`` |
    ``normal_map``), resolved and decoded, and a warning or None. A ``bump`` that is not found falls back to
    ``STEM-bump.EXT`` beside the material's ``texture`` (the layout the course's sibenik scene ships: its
    ``bump bump/kamen.bmp`` names a folder it does not have, the height field is ``tex/kamen-bump.bmp``), with
    a warning; otherwise the error of :func:`resolve_path` at the keyword's file name."""
    name = getattr(mat, which)
    loc = getattr(mat, f"{which}_loc") or mat.loc
    assert name is not None and loc is not None
    what = "bump" if which == "bump" else "normalMap"
    try:
        path = resolve_path(name, scene.base_dir, loc, what)
        warning = None
    except SceneSemanticError:
        if which != "bump" or mat.texture is None:
            raise
        tex, stem = Path(mat.texture), Path(name)
        sibling = str(tex.parent / f"{stem.stem}-bump{stem.suffix}")
        try:
            path = resolve_path(sibling, scene.base_dir, loc, what)
        except SceneSemanticError:
            raise SceneSemanticError(f"bump file '{name}' not found (nor '{sibling}' beside the texture)",
                                     loc) from None
        warning = f"bump file '{name}' not found; using '{sibling}' beside the texture"
    return read_image(path, loc, what, decoded), warning


def cube_map_folder(scene: Scene, warnings: list[tuple[FileLoc, str]]) -> Path:
    """The ``cubeMap`` folder (SPEC A.4; scene folder first, then cwd). A small regular file whose content is a
    relative path to an existing folder (a git symlink checked out as text, like extras/sibenik/tex/church) is
    followed, with a warning appended to ``warnings``; a real symlink is followed by the file system."""
    bg = scene.background
    assert bg.cube_map is not None
    loc = bg.cube_map_loc or bg.loc
    assert loc is not None
    try:
        return resolve_path(bg.cube_map, scene.base_dir, loc, "cubeMap", directory=True)
    except SceneSemanticError:
        p = Path(bg.cube_map)
        for cand in ([p] if p.is_absolute() else [scene.base_dir / p, Path.cwd() / p]):
            if cand.is_file() and cand.stat().st_size < LINK_FILE_MAX_BYTES:
                try:
                    target = cand.read_text().strip()
                except (OSError, UnicodeDecodeError):
                    continue
                dest = cand.parent / target
                if target and "\n" not in target and dest.is_dir():
                    warnings.append((loc, f"cubeMap '{bg.cube_map}' is a text file holding the path '{target}' "
                                          "(a symlink checked out as a file): following it"))
                    return dest
        raise


def cube_map(scene: Scene, warnings: list[tuple[FileLoc, str]],
             decoded: Decoded | None = None) -> tuple[Path, tuple[Image, ...]]:
    """The cube-map folder (:func:`cube_map_folder`, resolved) and its six faces in
    :data:`a5mi.spec.CUBE_FACES` order, each found by :func:`a5mi.spec.find_cube_face` (as the ``a5_cubemap``
    plugin finds it) and decoded. A missing or unreadable face is a :class:`SceneSemanticError` at the
    ``cubeMap`` keyword."""
    bg = scene.background
    loc = bg.cube_map_loc or bg.loc
    assert loc is not None
    folder = cube_map_folder(scene, warnings)
    faces = []
    for face in CUBE_FACES:
        path = find_cube_face(folder, face)
        if path is None:
            raise SceneSemanticError(f"cubeMap folder '{folder}' has no '{face}' face (expected {face}.bmp or "
                                     f"{face}.png)", loc)
        faces.append(read_image(path, loc, "cubeMap face", decoded))
    return folder.resolve(), tuple(faces)

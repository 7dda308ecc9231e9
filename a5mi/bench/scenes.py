"""The benchmark scenes, their published a5soln times, and the targets and stage names of the tables."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from a5mi import data_dir, require_data_dir

#: The benchmark scenes, relative to the course data folder.
SCENES: tuple[str, ...] = (
    "scenes/scene06_bunny_1k.txt",
    "scenes/scene10_sphere.txt",
    "scenes/scene11_cube.txt",
    "scenes/scene12_vase.txt",
    "scenes/scene13_diamond.txt",
    "extras/sibenik/s.txt",
)
#: The four assignment test scenes (the targets apply to these).
TEST_SCENES: tuple[str, ...] = ("scene06_bunny_1k", "scene10_sphere", "scene11_cube", "scene12_vase")

#: Used when ``reference/README.md`` cannot be read: a5soln, 2-vCPU Xeon, one core, ``-jitter -filter -bounces 4``.
PUBLISHED_A5SOLN: dict[str, float] = {"scene06": 5.7, "scene10": 4.8, "scene11": 3.5, "scene12": 64.7}

#: Speed targets (docs/SPEED.md; reported, never asserted by a timed test).
TARGET_WARM_S = 0.5
TARGET_COLD_S = 1.5
TARGET_FLOOR_RATIO = 1.5
TARGET_PEAK_MB = 300.0
#: a5soln / warm a5 on scene12 (docs/SPEED.md).
TARGET_SPEEDUP_SCENE12 = 100.0

#: Stages printed by ``a5 -v`` (its ``render`` = compile + execute + the tile loop's Python work).
VERBOSE_STAGES: tuple[str, ...] = ("parse", "variant", "build", "render", "filter", "write", "counts")
#: Stages measured in-process for the table (``render`` split into kernel compile and execution).
STAGES: tuple[str, ...] = ("parse", "build", "compile", "execute", "filter", "write")
RAY_KINDS: tuple[str, ...] = ("camera", "reflection", "refraction", "shadow")



# --------------------------------------------------------------------------------------------------------
# Published figures, scene names, tables
# --------------------------------------------------------------------------------------------------------

_PUBLISHED = re.compile(r"(scene\d+) ([0-9.]+) s")


def published_times(readme: str) -> dict[str, float]:
    """``scene06 5.7 s, scene10 4.8 s`` in ``reference/README.md`` -> ``{'scene06': 5.7, 'scene10': 4.8}``."""
    return {k: float(v) for k, v in _PUBLISHED.findall(readme)}


def load_published(root: Path | None = None) -> dict[str, float]:
    """The sample solution's published times, from the course README when readable (else the copy above)."""
    path = (root or data_dir()) / "reference" / "README.md"
    try:
        found = published_times(path.read_text())
    except OSError:
        found = {}
    return found or dict(PUBLISHED_A5SOLN)


def scene_name(path: str | Path) -> str:
    """Display name: the file stem, or ``folder/stem`` for generic stems (``extras/sibenik/s.txt`` -> ``sibenik/s``)."""
    p = Path(path)
    return p.stem if p.stem.startswith("scene") else f"{p.parent.name}/{p.stem}"


def published_key(name: str) -> str | None:
    """``scene06_bunny_1k`` -> ``scene06`` (the README's key); None for other names."""
    m = re.match(r"(scene\d+)", name)
    return m.group(1) if m else None


def resolve_scenes(names: Sequence[str], root: Path | None = None) -> list[Path]:
    """Benchmark scene files: :data:`SCENES` when ``names`` is empty; else each name is a path, or a stem /
    prefix of one of :data:`SCENES` (``scene10`` -> ``scenes/scene10_sphere.txt``). Raises ``ValueError``."""
    root = root or require_data_dir()
    if not names:
        return [root / s for s in SCENES]
    out = []
    for name in names:
        p = Path(name)
        if p.suffix == ".txt" and p.is_file():
            out.append(p.resolve())
            continue
        hits = [s for s in SCENES if scene_name(s).startswith(name) or Path(s).stem.startswith(name)]
        if len(hits) != 1:
            raise ValueError(f"unknown benchmark scene '{name}' (expected a .txt file or one of "
                             f"{', '.join(scene_name(s) for s in SCENES)})")
        out.append(root / hits[0])
    return out

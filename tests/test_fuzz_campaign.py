"""The mutation campaign of ``make fuzz`` (tests/fuzzing.py) through mi.load_dict and a real render.

``make test`` runs a fast seeded sample; ``make fuzz`` the campaign proper, bounded in time
(``A5MI_FUZZ_SECONDS``, 1800 in the Makefile), seeded (``A5MI_FUZZ_SEED``), at least ``A5MI_FUZZ_COUNT``
mutants when time allows; it writes its counts to ``A5MI_FUZZ_REPORT`` (JSON) when set. Any exit 1, traceback,
escaped exception, hang, two-line error, missing output or output written on error fails it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from fuzzing import KINDS_ALL, campaign, mutant


def _scenes(scenes_dir: Path) -> list[Path]:
    return sorted(scenes_dir.glob("scene*.txt"))


def _report(result) -> str:
    return "\n".join(f"seed {o.seed}: {o.argv} -> {o.problem}" for o in result.failures[:20])


def test_fuzz_campaign_sample(scenes_dir: Path, tmp_path: Path, mi) -> None:
    """A fast seeded sample of the campaign (the same mutants every run)."""
    result = campaign(_scenes(scenes_dir), tmp_path, seed=19_000, count=24, seconds=600)
    assert len(result.outcomes) == 24
    assert not result.failures, _report(result)
    counts = result.counts()
    assert counts.get("exit 0", 0) > 0 and counts.get("exit 2", 0) > 0, counts


def test_fuzz_mesh_and_image_mutants_sample(scenes_dir: Path, tmp_path: Path, mi) -> None:
    """Mutated OBJ meshes (coincident, degenerate, sliver, crossing faces, bad indices, other line ends) and
    mutated textures / cube faces (headers, truncation, odd channel counts) through real renders."""
    kinds = (("mesh", 0.6), ("image", 0.4))
    result = campaign(_scenes(scenes_dir), tmp_path, seed=23_000, count=14, seconds=600, kinds=kinds)
    assert len(result.outcomes) == 14
    assert not result.failures, _report(result)
    assert {o.argv[0] for o in result.outcomes} == {"mesh", "image"}
    counts = result.counts()
    assert counts.get("exit 0", 0) > 0 and counts.get("exit 2", 0) > 0, counts


def test_fuzz_commands_cover_every_sub_command(scenes_dir: Path) -> None:
    """The command mutants reach every sub-command of ``a5mi`` (the campaign proper runs them)."""
    from a5mi.cli import SUBCOMMANDS

    kinds = (("command", 1.0),)
    seen = {mutant(seed, _scenes(scenes_dir), kinds).command for seed in range(400)}
    assert seen == set(SUBCOMMANDS)


def test_fuzz_commands_sample(scenes_dir: Path, tmp_path: Path, mi) -> None:
    """A seeded sample of sub-command lines (cheap commands run for real, long ones end at their flag checks)."""
    kinds = (("command", 1.0),)
    result = campaign(_scenes(scenes_dir), tmp_path, seed=29_000, count=12, seconds=600, kinds=kinds)
    assert not result.failures, _report(result)
    assert len({o.argv[1] for o in result.outcomes}) >= 6, [o.argv[:2] for o in result.outcomes]


def test_fuzz_keyword_and_http_mutants_sample(scenes_dir: Path, tmp_path: Path, mi) -> None:
    """Numeric keywords of E.1-E.24 at their bounds and float32's edges (finite EXR or one positioned line) and
    hostile requests to the view's HTTP server (an answer, no 5xx, no traceback, 403 without token/Host/Origin)."""
    kinds = (("keyword", 0.5), ("http", 0.5))
    result = campaign(_scenes(scenes_dir), tmp_path, seed=31_000, count=24, seconds=600, kinds=kinds)
    assert len(result.outcomes) == 24
    assert not result.failures, _report(result)
    assert {o.argv[0] for o in result.outcomes if o.argv[0] == "http"} == {"http"}
    counts = result.counts()
    assert counts.get("exit 0", 0) > 0 and counts.get("exit None", 0) > 0, counts


@pytest.mark.skipif(not os.environ.get("A5MI_FUZZ_SECONDS"), reason="the campaign runs in make fuzz")
def test_fuzz_campaign_full(scenes_dir: Path, tmp_path: Path, mi) -> None:
    seconds = float(os.environ["A5MI_FUZZ_SECONDS"])
    seed = int(os.environ.get("A5MI_FUZZ_SEED", "1"))
    count = int(os.environ.get("A5MI_FUZZ_COUNT", "100000"))
    result = campaign(_scenes(scenes_dir), tmp_path, seed=seed, count=count, seconds=seconds, kinds=KINDS_ALL)
    summary = {"seed": seed, "seconds": seconds, "mutants": len(result.outcomes), "counts": result.counts(),
               "slowest_s": max((o.seconds for o in result.outcomes), default=0.0),
               "failures": [{"seed": o.seed, "argv": o.argv, "problem": o.problem} for o in result.failures]}
    if os.environ.get("A5MI_FUZZ_REPORT"):
        Path(os.environ["A5MI_FUZZ_REPORT"]).write_text(json.dumps(summary, indent=1))
    print(json.dumps({k: v for k, v in summary.items() if k != "failures"}))
    assert not result.failures, _report(result)

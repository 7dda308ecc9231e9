"""The grade report's cause line (a5mi/grade/cause.py, docs/GRADING.md "Causes"): a wrong image's cause names the
docs/MISTAKES.md mistake that ``a5mi diagnose`` finds; an image no catalogued mistake explains, a diagnosis that
fails or an image too large to diagnose gets the ray-tree culprit of its worst pixels, never a lost grade."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import a5mi.diagnose.rank
from a5mi.grade import cause
from a5mi.grade.cause import cause_of, diagnosed
from a5mi.grade.references import render_many
from a5mi.render.options import RenderOptions

SIZE = 24
OPTIONS = RenderOptions(width=SIZE, height=SIZE, shadows=True, bounces=2)
WRONG = {"verdict": "wrong", "detail": "12.0 % of pixels beyond the noise band"}


@pytest.fixture(scope="module")
def sphere(scenes_dir: Path) -> tuple[Path, np.ndarray, np.ndarray, np.ndarray]:
    """scene10_sphere at SIZE: the reference, the image without shadows and the reference with a bright square
    (a change no catalogued mistake makes), in levels."""
    scene = scenes_dir / "scene10_sphere.txt"
    ref, lacking = render_many(scene, [OPTIONS, dataclasses.replace(OPTIONS, shadows=False)])
    patched = ref.astype(np.float64).copy()
    patched[4:10, 4:10] = np.minimum(patched[4:10, 4:10] + 90.0, 255.0)
    return scene, ref, lacking, patched


def _cause(sphere: tuple, student: np.ndarray) -> str:
    scene, ref, *_ = sphere
    return cause_of(WRONG, scene=scene, options=OPTIONS, student=student, reference=ref, sigma=None)


def test_a_wrong_image_is_named_by_its_mistake(sphere) -> None:
    assert _cause(sphere, sphere[2]).startswith("mistake: no_shadows (SPEC B.3 S: S = 1 always, even with -shadows), "
                                                "explains ")
    assert _cause(sphere, sphere[2]).endswith("% of the difference (a5mi diagnose)")


def test_an_unexplained_image_gets_the_ray_tree_culprit(sphere) -> None:
    assert diagnosed(sphere[0], OPTIONS, sphere[3]) == ""
    line = _cause(sphere, sphere[3])
    assert not line.startswith("mistake:") and "worst pixels" in line, line


def test_a_failed_diagnosis_falls_back_to_the_trace(sphere, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []

    def broken(*_args: object, **_kw: object) -> None:
        calls.append(1)
        raise RuntimeError("no diagnosis today")

    monkeypatch.setattr(a5mi.diagnose.rank, "diagnose", broken)
    line = _cause(sphere, sphere[2])
    assert calls == [1] and "the student adds" in line and "shadow" in line and "worst pixels" in line, line


def test_only_small_whitted_renders_are_diagnosed(sphere, monkeypatch: pytest.MonkeyPatch) -> None:
    """Beyond DIAGNOSED_PIXELS, or with another integrator, the diagnosis is not run (its cost is bounded)."""
    calls: list[int] = []
    monkeypatch.setattr(a5mi.diagnose.rank, "diagnose", lambda *_a, **_k: calls.append(1))
    monkeypatch.setattr(cause, "DIAGNOSED_PIXELS", SIZE * SIZE - 1)
    assert "the student adds" in _cause(sphere, sphere[2])
    monkeypatch.setattr(cause, "DIAGNOSED_PIXELS", SIZE * SIZE)
    assert diagnosed(sphere[0], dataclasses.replace(OPTIONS, integrator="path"), sphere[2]) == ""
    assert diagnosed(sphere[0], None, sphere[2]) == ""
    assert calls == []

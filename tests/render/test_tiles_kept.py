"""The kept jittered tiles of a5mi/render/tiles.py: a warm session's next render with the same size, rows, seed
and mistakes reads the coordinates drawn before; they are the ones a new draw gives (SPEC B.5), bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from a5mi.render import tiles


def _draw(rw: int, rows: list[tuple[int, int]], seed: int | None, mistakes: tuple[str, ...] = ()) -> list:
    return list(tiles.main_tiles(rw, rows, seed, True, {}, mistakes))


@pytest.fixture(autouse=True)
def _empty() -> None:
    tiles._KEPT_TILES.clear()


def _same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(s.j0 == t.j0 and s.j1 == t.j1 and np.array_equal(s.x_pix, t.x_pix)
                                    and np.array_equal(s.y_pix, t.y_pix) for s, t in zip(a, b, strict=True))


@pytest.mark.parametrize("seed", [None, 7])
def test_kept_tiles_are_the_ones_a_new_draw_gives(seed: int | None) -> None:
    rows = [(0, 4), (4, 8), (8, 9)]
    first = _draw(30, rows, seed)
    again = _draw(30, rows, seed)
    assert all(s.x_pix is t.x_pix and s.y_pix is t.y_pix for s, t in zip(first, again, strict=True))
    assert not again[0].x_pix.flags.writeable and not again[0].y_pix.flags.writeable
    tiles._KEPT_TILES.clear()
    assert _same(again, _draw(30, rows, seed))   # drawn anew: the same coordinates
    one_tile = _draw(30, [(0, 9)], seed)          # other rows, same samples (SPEC B.5 order): same values
    assert np.array_equal(one_tile[0].x_pix, np.concatenate([t.x_pix for t in again]))


def test_other_seed_rows_or_mistakes_draw_again() -> None:
    rows = [(0, 6)]
    base = _draw(12, rows, None)
    seeded = _draw(12, rows, 3)
    shifted = _draw(12, rows, None, ("jitter_0_1",))   # docs/MISTAKES.md: offsets in [0, 1)
    assert not np.array_equal(seeded[0].x_pix, base[0].x_pix)
    assert not np.array_equal(shifted[0].x_pix, base[0].x_pix)
    assert _same(_draw(12, rows, None), base)            # the kept one is the last drawn: drawn again, equal
    tiles._KEPT_TILES.clear()
    assert _same(_draw(12, rows, None, ("jitter_0_1",)), shifted)


def test_partial_or_large_sequences_are_not_kept(monkeypatch) -> None:
    rows = [(0, 2), (2, 4)]
    gen = tiles.main_tiles(8, rows, None, True, {})
    next(gen)
    gen.close()                               # a render stopped after its first tile
    assert tiles._KEPT_TILES == {}
    monkeypatch.setattr(tiles, "KEEP_SAMPLES", 31)
    _draw(8, rows, None)                      # 32 samples
    assert tiles._KEPT_TILES == {}


def test_second_render_in_a_session_equals_a_fresh_one(tmp_path, variant: str) -> None:
    """A warm session's renders with -jitter -filter (kept tiles, kept atlases) equal one with every cache empty."""
    from a5mi.plugins.textures import imagedata
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import RenderSession, describe_file

    path = tmp_path / "s.txt"
    path.write_text("PerspectiveCamera { center 0 0 6 direction 0 0 -1 up 0 1 0 angle 30 }\n"
                    "Lights { numLights 1 PointLight { position 2 3 4 color 1 1 1 } }\n"
                    "Background { color 0.1 0.2 0.3 ambientLight 0.1 0.1 0.1 }\n"
                    "Materials { numMaterials 1 PhongMaterial { diffuseColor 1 0.5 0 specularColor 0.4 0.4 0.4 } }\n"
                    "Group { numObjects 1 MaterialIndex 0 Sphere { center 0 0 0 radius 1 } }\n")
    options = RenderOptions(width=18, height=15, shadows=True, bounces=3, jitter=True, filter=True)
    session = RenderSession()
    first = session.render(describe_file(str(path))[0], options).image
    second = session.render(describe_file(str(path))[0], options)
    assert second.timings["jitter"] == 0.0    # read from the kept tiles
    tiles._KEPT_TILES.clear()
    imagedata._KEPT.clear()
    fresh = RenderSession().render(describe_file(str(path))[0], options)
    assert fresh.timings["jitter"] > 0.0
    assert np.array_equal(second.image, fresh.image) and np.array_equal(first, fresh.image)

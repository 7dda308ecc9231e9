"""Every numeric keyword of docs/EXTENSIONS.md E.1-E.24 at its documented bounds and at float32's edges: the scene
is refused at the value's line (a positioned :class:`SceneError`) or renders a finite image (no NaN, no inf), for
the integrator and flags the keyword is used with. Each keyword sits on its own line of the scene, so a refusal
must name that line. The fast tier runs the values that once gave NaN images from accepted input (milled
``alphaU 1e-38``, ``dispersion 1e30 1e30``, ``1e20 0``, ``3e38 0``) and each keyword's documented bounds; the
``slow`` tier adds float32's edges for every keyword (``pytest -m slow``)."""

from __future__ import annotations

import numpy as np
import pytest
from keyword_bounds import EDGES, KEYWORDS, ONCE_NAN, Keyword, scene_of


def _cases(slow: bool) -> list[object]:
    out: list[object] = []
    for k in KEYWORDS:
        values = [*k.bounds, *ONCE_NAN.get((k.section, k.name), ())]
        for v in dict.fromkeys(values):
            out.append(pytest.param(k, v, id=f"{k.section}-{k.name}-{v}"))
        if slow:
            for v in EDGES:
                if v not in values:
                    out.append(pytest.param(k, v, id=f"{k.section}-{k.name}-{v}", marks=pytest.mark.slow))
    return out


def _check(tmp_path, k: Keyword, value: str) -> None:  # noqa: ANN001
    from a5mi.cli import parse_a5_args
    from a5mi.commands.render import check_render_args, render_options
    from a5mi.converters.a5_parser import parse_file
    from a5mi.converters.describe import describe
    from a5mi.converters.errors import SceneError
    from a5mi.platform.errors import UserError
    from a5mi.render.session import render

    text, flags, line = scene_of(k, value)
    path = tmp_path / "s.txt"
    path.write_text(text)
    try:
        args = parse_a5_args(["-input", str(path), "-output", str(tmp_path / "o.png"), "-size", "8", "8", *flags])
        check_render_args(args)
    except UserError as exc:  # a flag's value refused by its range: one line naming the flag
        assert line is None and k.name in str(exc), str(exc)
        return
    try:
        desc = describe(parse_file(path))
    except SceneError as exc:
        assert line is not None and exc.loc is not None and exc.loc.line == line, (str(exc), line)
        return
    image = render(desc, render_options(args, count_rays=False)).image
    bad = int((~np.isfinite(image)).any(axis=-1).sum())
    assert bad == 0, f"{bad} of {image.shape[0] * image.shape[1]} pixels are not finite"


@pytest.mark.parametrize("k, value", _cases(slow=True))
def test_a_keyword_at_its_bounds_is_refused_at_its_line_or_renders_finite(tmp_path, variant, k: Keyword,  # noqa: ANN001
                                                                          value: str) -> None:
    _check(tmp_path, k, value)

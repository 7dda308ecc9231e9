"""Rank the catalogued mistakes by how much of an image's difference from the reference each explains.

:func:`diagnose` (docs/MISTAKES.md "How the diagnosis works"): the image ``I`` (8-bit, row 0 = top) against the
reference ``R`` that a5mi renders from the scene and flags (SPEC B), and the mutants ``M`` of every applicable
mistake (:func:`a5mi.diagnose.catalogue.applicable`) rendered with ``RenderOptions.mistakes`` in one warm
:class:`~a5mi.render.session.RenderSession`. Every comparison is on the quantised images (SPEC B.1) scaled to [0, 1].

The measure is the **explained share** ``E(M) = 1 - ||I - M||² / ||I - R||²`` (sums over pixels and channels):
the share of the squared difference that assuming the mistake removes. 1: the mutant reproduces the image; 0 or
less: no better than the correct render. Squared error because it is additive over pixels (a mistake that fixes
half of the differing pixels exactly explains about half), independent of how large the difference is, and the
quantity PSNR is built from (``E = 1 - 10^(-ΔPSNR/10)``). It is taken at two scales, pixels and 4x4-pixel block
means, and the larger counts (:func:`explained_at`): with ``-jitter`` the image was made with other jitter offsets
than the diagnosis uses, and a mistake whose pixels depend on them (acne, sampling) agrees with the image only in
its block means.

Stages (small renders first, full size only for the finalists):

1. ``R`` at full size; with ``-jitter`` the render buffer is kept, so ``R`` and every blur/downsample mistake come
   from one render (:func:`a5mi.render.filters.mistaken_postprocess`), and the saved-image mistakes are
   :func:`a5mi.render.filters.image_mistakes` of ``R``: both scored at full size for free. The noise floor ``σ²`` (the
   mean squared difference two jitter seeds make, halved) comes from a second full render with another seed.
2. ``match`` when ``mse(I, R) <= max(MATCH_NOISE · σ², MATCH_MSE)``: within the seed noise, or above
   :data:`MATCH_PSNR` dB (SPEC C: a faithful implementation lands above 50 dB, anything under is a semantic
   difference); unless a mistake without jitter noise reproduces it or the mean difference shows a bias
   (:func:`a5mi.diagnose.match.hidden_in_noise`).
3. Kernel, marble and camera mutants at a small size (the longer side ``SMALL``, one ray per pixel; an image of at
   most ``ALL_FULL`` pixels a side skips this stage and renders them all at full size): the predicted
   difference ``M_s - R_s`` against the observed one, ``I`` interpolated at the small render's sample positions
   (:func:`sample_positions`) minus ``R_s``; its explained share ranks them. Point samples, not block means: a
   mistake in fine detail (marble, acne) keeps its signal.
4. The best :data:`FINALISTS` of stage 3 and the jitter mutants rendered at full size and scored by ``E``; then pairs
   (two mistakes at once): for each of the best :data:`PAIR_FROM` singles, the two partners whose differences, added
   to its own, best predict the observed difference (at the scale both were rendered at; for a :data:`MOVING` single,
   the pair rendered together), rendered together at full size; a pair is kept when it explains clearly more than
   either alone, and only where the better one leaves more than its own noise floor ``2σ²_M`` again beyond it (within
   that a second mistake only fits another seed's noise): by 0.1 of ``E``, or by removing half of that excess;
   ``σ²_M`` the larger of σ² and the mutant's own seed noise, its render with the noise seed. Pairs are searched when
   no single explains 0.98 or the best leaves more than ``MATCH_NOISE · σ²``; every saved-image and filter partner of
   a finalist is scored (free from its kept render); and each reversible saved-image mistake (:data:`REVERSIBLE`) is
   undone from the image and paired with the full-size single closest to what is left (beside another mistake it can
   hide both: neither single explains anything).
5. ``diagnosis`` when the best cause explains at least :data:`NAMED_SHARE` and leaves less than a quarter of the
   error it started from beyond the noise floor, and, where the 4x4 block means alone earn it (the pixels would
   not), the image is more probable under the cause than under the reference at full resolution (``Λ > 0``, below);
   otherwise ``unexplained`` with the remaining error and the closest causes (below). Never a forced guess.
6. Partners of a named single ``a``, or of a named pair's better single (with ``-jitter``): for each :data:`SAMPLING`
   and saved-image mistake and each partner the pair search rendered, ``b``, the pair ``(a, b)`` is listed first when
   the image scores better under it by the continuous ranked probability score, each hypothesis from its renders with
   two jitter seeds (:func:`a5mi.diagnose.measure.crps`), by a paired z over 4x4 blocks above :data:`PARTNER_Z`
   (:func:`a5mi.diagnose.measure.paired_z`); the largest mean gain first. E charges each mutant its own noise and the
   pair rules above leave a second mistake under the seed noise unlisted; CRPS, a proper score, counts both
   hypotheses' noise.

Closest causes of an image without a named cause (docs/MISTAKES.md "Closest causes: the likelihood with the noise"):
those explaining :data:`LISTED_SHARE` by ``E``, then those under which the image is more probable than under the
correct renderer by the log-likelihood ratio with each mistake's own jitter noise, :data:`SHOWN` at most
(:func:`a5mi.diagnose.measure.log_likelihood`, :func:`a5mi.diagnose.causes.closest`); one more render per cause.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from a5mi.diagnose.catalogue import Mistake, applicable, option_traits, scene_traits
from a5mi.diagnose.causes import SAMPLING, Cause, Diagnosis, closest, combinable
from a5mi.diagnose.match import DETERMINISTIC_MISTAKES, hidden_in_noise
from a5mi.diagnose.measure import (
    REVERSIBLE,
    Image,
    as_levels,
    blocks,
    crps,
    evidence,
    explained,
    explained_at,
    log_likelihood,
    mse,
    paired_z,
    psnr_of,
    resample,
    sample_positions,
)
from a5mi.diagnose.renders import Renders
from a5mi.platform.errors import UserError
from a5mi.render.filters import output_size
from a5mi.render.options import FILTER_MISTAKES, IMAGE_MISTAKES, JITTER_MISTAKES, RenderOptions

if TYPE_CHECKING:
    from a5mi.converters.describe import SceneDescription
    from a5mi.render.session import RenderSession

#: Longer side of the stage-3 renders (pixels).
SMALL = 48
#: Stage-3 mutants rendered again at full size.
FINALISTS = 5
#: Images whose longer side is at most this many pixels skip stage 3: every mutant is rendered at full size (as
#: cheap as the small renders, and without their sampling mismatch).
ALL_FULL = 2 * SMALL
#: Pairs are formed from this many best singles.
PAIR_FROM = 3
#: A named cause explains at least this share of the difference.
NAMED_SHARE = 0.6
#: Causes listed (best first) in the result, each after the first explaining at least LISTED_SHARE.
SHOWN = 3
LISTED_SHARE = 0.1
#: ``match`` within this many times the seed noise σ² (two seeds differ by 2σ² on average).
MATCH_NOISE = 2.6
#: ``match`` at or above this PSNR (dB) whatever the noise (SPEC C's floor for a faithful renderer).
MATCH_PSNR = 50.0
MATCH_MSE = 10.0 ** (-MATCH_PSNR / 10.0)
#: The second jitter seed of the noise floor.
NOISE_SEED = 977
#: Mistakes whose pixels depend on the float noise of the ray origin (random speckles): scored at full size always
#: (a small render's point samples do not meet the same speckles).
SPECKLED: tuple[str, ...] = ("shadow_acne", "secondary_acne")
#: A partner is listed when the paired test's z (over 4x4 blocks) is above this: a one-sided p of about
#: 1e-4 for the 49 blocks of a 30x30 image, under a null whose mean already favours the single (CRPS is proper).
PARTNER_Z = 4.0
#: Camera mistakes that move every pixel (the view zoomed or shifted): another mistake's difference does not add to
#: theirs, so their partners are ranked by rendering each pair (small, or at full size for a small image).
MOVING: tuple[str, ...] = ("fov_full_angle", "camera_divides_by_w")

class DiagnoseError(UserError):
    """The image cannot be compared with the scene's render (a size that the flags do not give)."""


def candidates_for(desc: SceneDescription, options: RenderOptions) -> list[Mistake]:
    """The catalogued mistakes that can show with this scene and these flags."""
    return applicable(scene_traits(desc) | option_traits(options))


def diagnose(image: npt.ArrayLike, desc: SceneDescription, options: RenderOptions, *,
             session: RenderSession | None = None, candidates: list[str] | None = None,
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Diagnose ``image`` (uint8 or [0, 1] float, H x W x 3, row 0 = top) made from scene ``desc`` with the a5 flags
    ``options`` (module docstring). ``session``: a warm :class:`~a5mi.render.session.RenderSession` (one is made
    otherwise); ``candidates``: mistake names to consider (default: every applicable one); ``progress(text)``:
    called at each stage. Raises :class:`DiagnoseError` when the image has another size than the flags give."""
    from a5mi.render.session import RenderSession

    t0 = time.perf_counter()
    seconds: dict[str, float] = {}
    arr = np.asarray(image)
    img = arr[..., :3].astype(np.float64) / 255.0 if arr.dtype == np.uint8 else as_levels(arr)
    want = output_size(options.width, options.height, jitter=options.jitter, filter=options.filter)
    if img.ndim != 3 or (img.shape[1], img.shape[0]) != want:
        got = f"{img.shape[1]}x{img.shape[0]}" if img.ndim == 3 else f"shape {img.shape}"
        raise DiagnoseError(f"the image is {got}, but these flags make {want[0]}x{want[1]} images (SPEC B.5)")
    say = progress or (lambda _text: None)
    session = session if session is not None else RenderSession()
    r = Renders(session, desc, options)
    pool = candidates_for(desc, options)
    if candidates is not None:
        pool = [m for m in pool if m.name in candidates]
    names = [m.name for m in pool]
    predicted: dict[str, Image] = {}   # stage 3: M_s - R_s

    def pair(a: str, b: str) -> tuple[str, str]:
        """The key of the pair (a, b): both names in the catalogue's order."""
        return (a, b) if names.index(a) <= names.index(b) else (b, a)

    say("reference")
    ref = r.full()
    err0 = mse(img, ref)
    noise = noise_blocks = 0.0
    other = ref
    if options.jitter:
        other = r.full(seed=NOISE_SEED)
        noise, noise_blocks = mse(ref, other) / 2.0, mse(blocks(ref), blocks(other)) / 2.0
    seconds["reference"] = time.perf_counter() - t0
    result = Diagnosis("match", psnr_of(err0), err0, noise, considered=names)
    if err0 <= max(MATCH_NOISE * noise, MATCH_MSE):
        result.remaining = err0
        hidden = hidden_in_noise(img, ref, noise, noise_blocks, names, r.full)
        if hidden is not None:
            result.verdict, result.causes, result.remaining = "diagnosis", [hidden[0]], hidden[1]
        result.renders, result.seconds = dict(r.counts), seconds
        seconds["total"] = time.perf_counter() - t0
        return result

    # ---- full size for free: saved-image and blur/downsample mistakes; then the sampling ones
    scores: dict[tuple[str, ...], Cause] = {}
    images: dict[tuple[str, ...], Image] = {}

    def score_full(key: tuple[str, ...]) -> None:
        m = r.full(key)
        images[key] = m
        cause = scores.get(key) or Cause(key, None)
        cause.explained, cause.scale = explained_at(img, ref, m)
        scores[key] = cause

    t1 = time.perf_counter()
    cheap = [n for n in names if n in IMAGE_MISTAKES or (n in FILTER_MISTAKES and options.jitter and options.filter)]
    for n in cheap:
        score_full((n,))
    seconds["image"] = time.perf_counter() - t1

    # ---- stage 3: the rendered mistakes, small
    t1 = time.perf_counter()
    rendered = [n for n in names if n not in cheap and n not in JITTER_MISTAKES and n != "no_supersampling"
                and n not in SPECKLED]
    observed = np.zeros((1, 1, 3))
    all_full: list[tuple[str, ...]] = []
    if rendered and max(img.shape[:2]) <= ALL_FULL:   # small image: all at full size (stage 4 takes them)
        all_full, rendered = [(n,) for n in rendered], []
    if rendered:
        h, w = img.shape[:2]
        k = max(1, math.ceil(max(w, h) / SMALL))
        size = (max(2, w // k), max(2, h // k))
        sampled = options.jitter and options.filter
        positions = (sample_positions(size[0], w, sampled), sample_positions(size[1], h, sampled))
        at = resample(img, *positions)
        say(f"{len(rendered)} mutants at {size[0]}x{size[1]}")
        base = r.small((), size)
        observed = at - base
        total = float(np.sum(observed ** 2))
        for n in rendered:
            predicted[n] = r.small((n,), size) - base
            share = 1.0 - float(np.sum((observed - predicted[n]) ** 2)) / total if total > 0 else 0.0
            scores[(n,)] = Cause((n,), None, small=share)
    seconds["small"] = time.perf_counter() - t1

    # ---- stage 4: finalists at full size, then pairs
    t1 = time.perf_counter()
    ranked_small = sorted((c for c in scores.values() if c.small is not None), key=lambda c: -(c.small or 0.0))
    finals = all_full + [c.mistakes for c in ranked_small[:FINALISTS] if (c.small or 0.0) > 0.0]
    finals += [(n,) for n in names if n in JITTER_MISTAKES or n == "no_supersampling" or n in SPECKLED]
    say(f"{len(finals)} finalists at full size")
    for key in finals:
        score_full(key)
    singles = sorted((c for c in scores.values() if c.explained is not None), key=lambda c: -(c.explained or 0.0))
    floor_at = {"pixels": 2.0 * noise, "blocks": 2.0 * noise_blocks}
    floors: dict[tuple[tuple[str, ...], str], float] = {}
    seconds_seed: dict[tuple[str, ...], Image] = {(): other}

    def second(key: tuple[str, ...]) -> Image:
        """The mutant ``key`` rendered with the noise seed (its own jitter noise), once."""
        if key not in seconds_seed:
            seconds_seed[key] = r.full(key, seed=NOISE_SEED)
        return seconds_seed[key]

    def view(a: Image, scale: str) -> Image:
        return blocks(a) if scale == "blocks" else a

    def floor_of(key: tuple[str, ...], scale: str) -> float:
        """2σ² at ``scale``, σ² the larger of the reference's seed noise and the mutant's own (its render with
        the noise seed: a mutant that brightens or sharpens has more jitter noise than the reference)."""
        if not options.jitter:
            return 0.0
        if (key, scale) not in floors:
            own = mse(view(images[key], scale), view(second(key), scale)) / 2.0
            floors[key, scale] = 2.0 * max(own, floor_at[scale] / 2.0)
        return floors[key, scale]

    base_ll: list[float] = []

    def ratio(key: tuple[str, ...]) -> float:
        """``Λ = ℓ(I | M) - ℓ(I | R)``, each with its own seed noise (:func:`log_likelihood`)."""
        if not base_ll:
            base_ll.append(log_likelihood(img, ref, other))
        return log_likelihood(img, images[key], second(key)) - base_ll[0]

    def excess(single: tuple[str, ...], scale: str) -> tuple[float, float]:
        """What ``single`` leaves beyond its seed noise, and that noise: ``(mse(I, M) - 2σ²_M, 2σ²_M)``."""
        floor = floor_of(single, scale)
        return mse(view(img, scale), view(images[single], scale)) - floor, floor

    def halved(single: tuple[str, ...], pair: tuple[str, ...], scale: str) -> bool:
        """Whether ``pair`` removes half of what ``single`` leaves beyond its seed noise 2σ² (at ``scale``), where
        that is more than the noise again."""
        left, floor = excess(single, scale)
        return left > floor + MATCH_MSE and mse(view(img, scale), view(images[pair], scale)) - floor <= 0.5 * left

    # pairs when no single explains nearly all, or when the best leaves more than the seed noise of two images
    searched = bool(singles) and ((singles[0].explained or 0.0) < 0.98
                                  or mse(img, images[singles[0].mistakes]) > MATCH_NOISE * noise + MATCH_MSE)
    if searched:
        # no pairs with a mistake free of jitter noise: beside any mutant it removes the noise, which an image made
        # with other jitter offsets rewards by itself (named alone by the match step's deterministic test)
        tops = [c.mistakes[0] for c in singles[:PAIR_FROM]
                if (c.explained or 0.0) > 0.05 and c.mistakes[0] not in DETERMINISTIC_MISTAKES]
        pairs: set[tuple[str, ...]] = set()
        if rendered:   # full-size differences at the small render's sample positions, for the additive test
            for (n, *more), m in images.items():
                if not more and n not in predicted:
                    predicted[n] = resample(m - ref, *positions)
        # a saved-image mistake hides the other mistake from the singles (neither may explain anything alone): each
        # reversible one is undone from the image and paired with the single at full size closest to what is left
        for c in (c for c in cheap if c in REVERSIBLE):
            undone_image = REVERSIBLE[c](img)
            near = {b: mse(undone_image, m) for (b, *more), m in images.items()
                    if not more and b not in cheap and combinable(b, c)}
            if near:
                pairs.add(pair(min(near, key=lambda b: near[b]), c))
        for a in tops:
            # every saved-image and filter partner: made from a's kept render, exact at full size, no render
            pairs.update(pair(a, b) for b in cheap if b != a and combinable(a, b))
            undone = observed
            if a in REVERSIBLE and rendered:   # a saved-image mistake is undone, not subtracted
                undone = resample(REVERSIBLE[a](img), *positions) - base

            def additive(b: str, a: str = a, undone: Image = undone) -> float:
                """How well the two differences added predict the observed one (small scale, else full); for a
                :data:`MOVING` mistake, how well the pair rendered together predicts it."""
                if a in MOVING:
                    key = pair(a, b)
                    if rendered:
                        return -float(np.sum((observed - r.small(key, size) + base) ** 2))
                    return -float(np.sum((img - r.full(key)) ** 2))
                if a in REVERSIBLE and b in predicted:
                    return -float(np.sum((undone - predicted[b]) ** 2))
                if a in REVERSIBLE and (b,) in images:
                    return -float(np.sum((REVERSIBLE[a](img) - images[(b,)]) ** 2))
                if a in predicted and b in predicted:
                    return -float(np.sum((observed - predicted[a] - predicted[b]) ** 2))
                if (a,) in images and (b,) in images:
                    return -float(np.sum((img - images[(a,)] - images[(b,)] + ref) ** 2))
                return -math.inf
            fit = {b: additive(b) for b in names
                   if b != a and b not in cheap and combinable(a, b) and b not in DETERMINISTIC_MISTAKES}
            best_fit = sorted(fit, key=lambda b: -fit[b])[:2]
            pairs.update(pair(a, b) for b in best_fit if fit[b] > -math.inf)
        for key in sorted(pairs, key=lambda k: (names.index(k[0]), names.index(k[1]))):
            score_full(key)
    seconds["finalists"] = time.perf_counter() - t1

    ranked = sorted((c for c in scores.values() if c.explained is not None),
                    key=lambda c: (-(c.explained or 0.0), len(c.mistakes)))
    # a pair replaces its singles only when it explains clearly more than the better of them
    shown: list[Cause] = []
    for c in ranked:
        if len(c.mistakes) == 2:
            parts = [scores[(m,)] for m in c.mistakes if (m,) in scores and scores[(m,)].explained is not None]
            if not parts:
                continue
            part = max(parts, key=lambda p: p.explained or 0.0)
            better = part.explained or 0.0
            # clearly more: by 0.1 where the single leaves more than its seed noise again beyond it (within that, a
            # second mistake only fits the noise of another seed); or half of that excess removed (without jitter:
            # half of what it leaves; with it, the noise left aside)
            left, floor = excess(part.mistakes, c.scale)
            by_share = (c.explained or 0.0) >= better + 0.1 and left > floor + MATCH_MSE
            if not by_share and not any(halved(part.mistakes, c.mistakes, scale) for scale in ("pixels", "blocks")):
                continue
        shown.append(c)
    considered = shown
    shown = [c for k, c in enumerate(shown) if k == 0 or (c.explained or 0.0) >= LISTED_SHARE]
    best = shown[0] if shown else None
    remaining = mse(img, images[best.mistakes]) if best is not None else err0
    def earned(key: tuple[str, ...], scale: str) -> bool:
        """Whether ``key`` explains :data:`NAMED_SHARE` at ``scale`` and leaves beyond the noise floor under a
        quarter of what the image started with there."""
        v = blocks if scale == "blocks" else (lambda a: a)
        floor = 2.0 * (noise_blocks if scale == "blocks" else noise)
        before, after = mse(v(img), v(ref)), mse(v(img), v(images[key]))
        share = explained(v(img), v(ref), v(images[key]))
        return share >= NAMED_SHARE and after - floor <= 0.25 * (before - floor) + MATCH_MSE

    def members(key: tuple[str, ...]) -> list[Image]:
        """The renders of ``key`` with independent jitter seeds: one for a mutant free of jitter noise."""
        return [images[key]] if set(key) & set(DETERMINISTIC_MISTAKES) else [images[key], second(key)]

    def paired_partners(single: str) -> list[Cause]:
        """The pairs of the named ``single`` that the paired CRPS test prefers to the single alone (``z >``
        :data:`PARTNER_Z`), the largest mean gain first (docs/MISTAKES.md "Partners: the paired score"): with every
        :data:`SAMPLING` mistake (rendered here when the pair search did not), every saved-image mistake (from the
        kept render) and every partner the pair search rendered."""
        own = crps(img, members((single,)))
        found: list[tuple[float, Cause]] = []
        for s in (s for s in names if s != single and combinable(single, s)):
            key = pair(single, s)
            if s not in SAMPLING and s not in cheap and key not in images:
                continue
            if key not in images:
                score_full(key)
            gain = own - crps(img, members(key))
            z = paired_z(gain)
            if z > PARTNER_Z:
                scores[key].partner, scores[key].partner_z = s, z
                found.append((float(np.mean(gain)), scores[key]))
        return [c for _, c in sorted(found, key=lambda t: -t[0])]

    named = best is not None and earned(best.mistakes, best.scale)
    if named and best is not None and best.scale == "blocks" and options.jitter and not earned(best.mistakes,
                                                                                               "pixels"):
        # block means average each hypothesis' noise differently (one sample instead of nine: nine times the
        # block noise): a name earned by them alone must also make the pixels more probable than the reference
        best.likelihood = ratio(best.mistakes)
        named = best.likelihood > 0.0
    t1 = time.perf_counter()
    if named and best is not None and options.jitter:
        # a second mistake whose effect is mostly jitter noise (sampling) or under the noise E charges: the paired
        # score weighs both hypotheses' noise. Beside a named pair, its better single's partners are weighed (the
        # pair itself among them): a partner that only swaps one noise pattern for another does not pass
        single = best.mistakes[0]
        if len(best.mistakes) == 2:
            parts = [scores[(m,)] for m in best.mistakes if (m,) in scores and scores[(m,)].explained is not None]
            single = max(parts, key=lambda p: p.explained or 0.0).mistakes[0] if parts else single
        partnered = paired_partners(single)
        if partnered:
            shown = partnered + [c for c in shown if c not in partnered]
            best = shown[0]
            remaining = mse(img, images[best.mistakes])
    seconds["partners"] = time.perf_counter() - t1
    if not named and options.jitter:
        shown = closest(considered, ref, images, ratio, SHOWN, LISTED_SHARE)
    for c in shown[:SHOWN]:
        c.evidence = evidence(img, ref, images[c.mistakes], noise)
    result.causes = shown[:SHOWN]
    result.verdict = "diagnosis" if named else "unexplained"
    result.remaining = remaining if named else err0
    result.renders, result.seconds = dict(r.counts), seconds
    seconds["total"] = time.perf_counter() - t0
    return result

"""The catalogue of the assignment's mistakes (docs/MISTAKES.md): each an exact change to SPEC's computation.

A :class:`Mistake` names the SPEC section it changes, the change (``change``, the formula as the student computes
it), the symptom a student sees, the layer that makes it on request (:data:`a5mi.render.options.MISTAKES` by layer) and
what a render needs for it to show (:data:`NEEDS`): ``-shadows``, a bounce budget, ``-jitter -filter``, or a scene
with mirrors, glass, marble, textures, a cube map, two lights, an ambient light. :func:`applicable` is the
cheap static test ``a5mi diagnose`` uses before it renders a mutant.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from a5mi.render.options import (
    CAMERA_MISTAKES,
    FILTER_MISTAKES,
    IMAGE_MISTAKES,
    JITTER_MISTAKES,
    KERNEL_MISTAKES,
    MARBLE_MISTAKES,
    RenderOptions,
)

if TYPE_CHECKING:
    from a5mi.converters.describe import SceneDescription

#: What a render must have for a mistake to show: flags (``shadows``, ``bounces``, ``supersampling`` = -jitter
#: -filter) and scene content (``mirror``: a material with |specularColor| > 0.001, ``glass``: refractionIndex > 0,
#: ``marble``, ``texture``, ``pattern``: marble or texture, ``cubemap``, ``lights2``: two lights or more,
#: ``ambient``: a non-zero ambient light, ``narrow``: a field of view under 90 degrees).
NEEDS: tuple[str, ...] = ("shadows", "bounces", "supersampling", "mirror", "glass", "marble", "texture", "pattern",
                          "cubemap",
                          "lights2", "ambient", "narrow")


@dataclass(frozen=True)
class Mistake:
    """One catalogued mistake: ``name`` (the ``-mistake`` name), ``section`` (SPEC section changed), ``change`` (the
    student's computation, exactly), ``symptom`` (what the image shows), ``needs`` (:data:`NEEDS`)."""

    name: str
    section: str
    change: str
    symptom: str
    needs: tuple[str, ...] = ()

    @property
    def layer(self) -> str:
        """Which part of a5mi makes it: ``kernel``, ``marble``, ``camera``, ``jitter``, ``filter`` or ``image``."""
        for layer, names in LAYERS.items():
            if self.name in names:
                return layer
        raise KeyError(self.name)


LAYERS: dict[str, tuple[str, ...]] = {"kernel": KERNEL_MISTAKES, "marble": MARBLE_MISTAKES, "camera": CAMERA_MISTAKES,
                                      "jitter": JITTER_MISTAKES, "filter": FILTER_MISTAKES, "image": IMAGE_MISTAKES}

_M = Mistake
CATALOGUE: tuple[Mistake, ...] = (
    # ---- B.3 light loop and shadows
    _M("no_shadows", "B.3 S", "S = 1 always, even with -shadows",
       "no shadows anywhere; shadowed regions as bright as lit ones", ("shadows",)),
    _M("shadow_acne", "B.3 S", "shadow ray tested with 0 < t < dist (tmin 0 instead of 0.001)",
       "speckled dark dots (acne) over lit surfaces", ("shadows",)),
    _M("shadow_beyond_light", "B.3 S", "shadow ray tested with 0.001 < t < +inf (no upper bound at the light)",
       "point-lit surfaces darkened by objects behind the light", ("shadows",)),
    _M("shadow_first_light_only", "B.3 S", "S computed for the first light only; S = 1 for the others",
       "shadows of the second and later lights missing", ("shadows", "lights2")),
    _M("no_ambient", "B.3 color", "color = 0 instead of ambient ⊙ diffuseColor",
       "unlit and shadowed regions black", ("ambient",)),
    _M("ambient_uses_kd", "B.3 color", "color = ambient ⊙ kd (texture or noise colour) instead of the raw "
       "diffuseColor", "marble and textured surfaces show their pattern in shadow", ("ambient", "pattern")),
    _M("ndotl_unclamped", "B.3 light loop", "L·N instead of clamp(L·N, 0)",
       "surfaces facing away from a light darker than ambient (light subtracted)"),
    _M("light_dir_flipped", "A.3, B.3", "L negated: clamp(-L·N, 0), shadow ray cast away from the light",
       "surfaces lit from the side opposite the light"),
    _M("normal_faces_viewer", "B.3 N", "N replaced by -N where d·N > 0 before the light loop",
       "backs of surfaces (a plane seen from below) lit as if two-sided"),
    _M("light_color_ignored", "B.3 light loop", "clamp(L·N, 0) ⊙ kd, lightColor dropped",
       "light colour and point-light falloff have no effect"),
    _M("kd_ignores_texture", "B.3 kd", "kd = diffuseColor even where a texture or Noise is present",
       "marble and textures missing (flat diffuse colour)", ("pattern",)),
    _M("phong_highlight", "B.3 notes", "the a4 handout's clamp(L·R)^shininess lightColor ⊙ specularColor added",
       "white highlights on shiny materials that a5soln does not draw", ("mirror",)),
    # ---- B.3 reflection
    _M("mirror_sign", "B.3 refl", "mirror direction 2(d·N)N - d instead of d - 2(d·N)N",
       "mirrors show what is behind them (the ray goes on through the surface)", ("bounces", "mirror")),
    _M("reflection_unweighted", "B.3 color", "refl added as R·refl, not specularColor ⊙ R·refl",
       "mirrors too bright, reflections in the wrong tint", ("bounces", "mirror")),
    _M("refraction_unweighted", "B.3 color", "refr added as (1-R)·refr, not specularColor ⊙ (1-R)·refr",
       "glass too bright, what is seen through it untinted", ("bounces", "glass")),
    _M("refl_refr_added", "B.3 color", "specularColor ⊙ (refl + refr) instead of (R refl + (1-R) refr)",
       "glass too bright (reflection and refraction both at full weight)", ("bounces", "glass")),
    _M("bounces_plus_one", "B.1, B.3", "bounce budget -bounces + 1", "one more level of inter-reflection",
       ("bounces", "mirror")),
    _M("bounces_minus_one", "B.1, B.3", "bounce budget max(-bounces - 1, 0)", "one level of inter-reflection "
       "missing (the deepest reflections flat)", ("bounces", "mirror")),
    _M("no_recursion", "B.1, B.3", "bounce budget 0 whatever -bounces says (as -bounces 0)",
       "no reflection or refraction at all; mirrors and glass show only their diffuse colour", ("bounces", "mirror")),
    # ---- B.3 refraction
    _M("eta_inverted", "B.3 Snell", "Snell with n/nt replaced by nt/n", "glass bends the wrong way; total internal "
       "reflection where there should be none", ("bounces", "glass")),
    _M("eta_inside_inverted", "B.3 Snell", "leaving an object (d·N > 0): Snell with 1/nt instead of n/1",
       "wrong refraction at the exit: objects behind glass displaced; no total internal reflection",
       ("bounces", "glass")),
    _M("normal_not_flipped_inside", "B.3 Snell", "leaving an object: Snell with N instead of -N",
       "rays leaving glass turned back inside: glass dark or mirror-like inside", ("bounces", "glass")),
    _M("tir_ignored", "B.3 Snell", "under total internal reflection R = R0 + (1-R0)(1-|d·N|)^5 instead of R = 1",
       "internally reflecting parts of glass too dark", ("bounces", "glass")),
    _M("schlick_wrong_c", "B.3 Fresnel", "c = |T·N| when nt > n and |d·N| otherwise (the two swapped)",
       "Fresnel reflection at glass edges wrong (too much or too little rim reflection)", ("bounces", "glass")),
    _M("background_wrong_direction", "A.4, B.3", "background(-d) instead of background(d)",
       "the cube map seen in the opposite direction (behind the camera)", ("cubemap",)),
    _M("secondary_acne", "B.3 notes", "reflected and refracted rays start with tmin 0 instead of 0.001",
       "noisy speckles on mirrors and glass (the ray hits its own surface)", ("bounces", "mirror")),
    # ---- B.4 marble
    _M("marble_no_octaves", "B.4", "N = 0 (the octave sum left out)", "marble as straight, regular stripes",
       ("marble",)),
    _M("marble_sine_unmapped", "B.4", "t = clamp(M, 0, 1) instead of (M + 1)/2 (the handout's wording)",
       "marble's second colour dominates; half of each stripe period flat", ("marble",)),
    _M("marble_freq_amp_swapped", "B.4", "M = sin(amplitude·p.x + frequency·N)",
       "stripe spacing and turbulence exchanged", ("marble",)),
    # ---- B.2 camera, B.5 sampling
    _M("fov_full_angle", "A.2, B.2", "f = 1/tan(angle) instead of 1/tan(angle/2)",
       "the view zoomed out (twice the field of view)", ("narrow",)),
    _M("camera_divides_by_w", "B.2", "x = 2(i + jx)/W - 1 instead of /(W - 1) (likewise y with H)",
       "the image shifted and shrunk by about one pixel toward the top right"),
    _M("no_supersampling", "B.5", "-jitter -filter ignored: one ray through each pixel centre",
       "jagged edges where the reference is anti-aliased", ("supersampling",)),
    _M("no_jitter", "B.5", "offsets (jx, jy) = 0 on the 3W x 3H grid", "regular sampling: edges slightly stepped",
       ("supersampling",)),
    _M("jitter_0_1", "B.5", "offsets in [0, 1) instead of [-0.5, 0.5)",
       "the image shifted by 1/6 pixel toward the bottom left (sample positions biased)", ("supersampling",)),
    _M("blur_not_normalised", "B.5", "taps K / K[2] (peak 1, sum 3.42 per pass) instead of K",
       "image about 11.7x too bright (mostly white)", ("supersampling",)),
    _M("blur_one_direction", "B.5", "the y pass only, no x pass", "edges blurred vertically but sharp "
       "horizontally", ("supersampling",)),
    _M("blur_zero_border", "B.5", "taps outside the image read 0 instead of the clamped edge pixel",
       "a dark frame one or two pixels wide around the image", ("supersampling",)),
    _M("downsample_one_sample", "B.5", "out[y,x] = blurred[3y+1, 3x+1] instead of the mean of the 3x3 block",
       "edges a little sharper and shifted; high-frequency detail aliased", ("supersampling",)),
    _M("no_blur", "B.5", "no Gaussian blur: the 3x3 box downsample only", "edges sharper than the reference",
       ("supersampling",)),
    # ---- B.1 the saved image
    _M("upside_down", "B.1", "row 0 written as the top row (the image origin is the bottom-left pixel)",
       "the image upside down"),
    _M("mirrored", "B.2", "u = up × w (the camera's x axis negated)", "the image mirrored left to right"),
    _M("red_blue_swapped", "B.1", "channels written (B, G, R)", "red and blue exchanged"),
    _M("srgb_gamma", "B.1", "byte = int(255 · sRGB(c)) instead of int(255 · c)", "image washed out (too bright "
       "in the darks)"),
    _M("colours_wrapped", "B.1", "byte = int(255 c) mod 256 instead of clamp(int(255 c), 0, 255)",
       "over-exposed areas (c > 1) turn dark or strangely coloured"),
    _M("rounding", "B.1", "byte = round(255 c) instead of int(255 c) (truncation)",
       "half of the pixels one level brighter"),
)

#: The catalogue by name.
BY_NAME: dict[str, Mistake] = {m.name: m for m in CATALOGUE}



def scene_traits(desc: SceneDescription) -> set[str]:
    """The scene-content :data:`NEEDS` that ``desc`` has (``mirror``, ``glass``, ``marble``, ``texture``,
    ``cubemap``, ``lights2``, ``ambient``, ``narrow``)."""
    from a5mi.converters.describe import CubeMapBackground
    from a5mi.converters.files import Image
    from a5mi.converters.model import Noise

    traits: set[str] = set()
    for mat in desc.materials:
        if sum(float(c) ** 2 for c in mat.specular_color) ** 0.5 > 0.001:
            traits.add("mirror")
        if mat.refraction_index > 0.0:
            traits.add("glass")
        if isinstance(mat.kd, Noise):
            traits.update(("marble", "pattern"))
        elif isinstance(mat.kd, Image):
            traits.update(("texture", "pattern"))
    if isinstance(desc.background, CubeMapBackground):
        traits.add("cubemap")
    if len(desc.lights) >= 2:
        traits.add("lights2")
    if any(float(c) > 0.0 for c in desc.ambient):
        traits.add("ambient")
    if 0.0 < float(desc.camera.angle) < 90.0:
        traits.add("narrow")
    return traits


def option_traits(options: RenderOptions) -> set[str]:
    """The flag :data:`NEEDS` that ``options`` has (``shadows``, ``bounces``, ``supersampling``)."""
    traits = set()
    if options.shadows:
        traits.add("shadows")
    if options.bounces > 0:
        traits.add("bounces")
    if options.jitter and options.filter:
        traits.add("supersampling")
    return traits


def applicable(traits: set[str]) -> list[Mistake]:
    """The mistakes whose :attr:`Mistake.needs` are all in ``traits`` (:func:`scene_traits` |
    :func:`option_traits`), in catalogue order. ``glass`` counts as ``mirror`` too (refraction needs a non-zero
    specularColor, SPEC B.3 notes)."""
    have = set(traits)
    if "glass" in have:
        have.add("mirror")
    return [m for m in CATALOGUE if set(m.needs) <= have]

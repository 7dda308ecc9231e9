"""The ``a5_material`` BSDF: the course's Material block as a Mitsuba BSDF (SPEC A.5, B.3).

The a5 ``Material`` is not a physical BSDF: the sample solution's ``traceRay`` (SPEC B.3) reads its raw
values. This plugin therefore has two faces:

1. **The a5 channel**, read by ``a5_whitted`` through the standard vcall-able BSDF interface
   (ARCHITECTURE.md, "How the integrator reads materials"):

   * ``eval_attribute_3("diffuse_color", si)``: the raw ``diffuseColor`` (ambient term of SPEC B.3);
   * ``eval_diffuse_reflectance(si)``: ``kd``, the Lambert colour (marble, bitmap texture, or diffuseColor);
   * ``eval_attribute_3("specular_color", si)``: mirror / Fresnel weight;
   * ``eval_attribute_1("refraction_index", si)``: 0 = not transparent;
   * ``eval_attribute_1("shininess", si)``: only used by the integrator's ``phong`` option;
   * ``eval_attribute_3("shading_normal", si)``: the bump / normal-mapped shading normal (docs/EXTENSIONS.md E.7,
     :mod:`.bump`; ``si.sh_frame.n`` without maps), only read by the integrator's ``bump`` option.

2. **A sensible physical BSDF** for stock integrators (``path``, ``direct``...), a mixture of

   * Lambert ``kd/π`` on both sides (docs/EXTENSIONS.md E.13's two-sided Lambert
     ``f = kd/π · [ω on the side of N that wi is on]``: for ``cosθ_i < 0`` the local frame is mirrored,
     ``z -> −z``, as Mitsuba's ``twosided`` adapter does), and
   * when ``|specular_color| > 0.001`` or ``refraction_index > 0``, a delta lobe weighted by
     ``specular_color``: an ideal mirror if ``refraction_index == 0``, else a smooth dielectric with
     interior index ``refraction_index`` (``n(550 nm)`` if ``cauchy_b ≠ 0``) and exterior 1 (exact Fresnel
     ``mi.fresnel``, radiance scaled by ``1/η²`` on transmission, both sides).

   The lobe is chosen with probability ``p_s = mean(specular_color) / (mean(kd) + mean(specular_color))``;
   sampled weights are ``kd / (1 - p_s)`` (diffuse) and ``specular_color / p_s`` (delta), and ``pdf`` is
   ``(1 - p_s) |cosθ_o|/π`` for the diffuse lobe (0 where ``wo`` is not on ``wi``'s side). This is *not* what
   the sample solution renders (its "specular" is the recursive Whitted weight, SPEC B.3, and ``a5_whitted``
   never calls ``sample`` / ``eval`` / ``pdf`` of this BSDF); it only makes the material usable elsewhere.

Parameters (ARCHITECTURE.md):

================== ============= ========= ==================================================
name               type          default   meaning
================== ============= ========= ==================================================
diffuse_color      rgb           (1,1,1)   raw ``diffuseColor`` (ambient term)
kd                 texture/rgb   = diffuse Lambert colour: ``a5_marble``, ``a5_bitmap``, rgb
specular_color     rgb           (0,0,0)   mirror / refraction weight (``specularColor``)
shininess          float         0         Phong exponent (handout option only)
refraction_index   float         0         ``refractionIndex``; 0 = opaque; Cauchy's ``A`` if dispersive
cauchy_b           float         0         Cauchy's ``B`` (µm², docs/EXTENSIONS.md E.10); 0 = no dispersion
bump               a5_bitmap     none      height field (E.7); its grey · ``bump_scale`` = height
bump_scale         float         1         world units of height at grey 1 (E.7 ``bumpScale``)
normal_map         a5_bitmap     none      tangent-space normal map (E.7 ``normalMap``)
================== ============= ========= ==================================================

Dict form::

    {'type': 'a5_material',
     'diffuse_color': {'type': 'rgb', 'value': [1, 0, 0]},
     'specular_color': {'type': 'rgb', 'value': [0.5, 0.5, 0.5]},
     'refraction_index': 1.5}

All values are stored as opaque Dr.Jit variables, so materials with different values share compiled kernels.
"""

from __future__ import annotations

from collections.abc import Sequence

import drjit as dr
import mitsuba as mi

from a5mi.plugins.materials.bump import perturb
from a5mi.spec import CENTRE_WAVELENGTH_NM, MIRROR_THRESHOLD

#: Attributes served through ``eval_attribute_3`` / ``eval_attribute_1`` (and ``has_attribute``).
COLOR_ATTRIBUTES: tuple[str, ...] = ("diffuse_color", "specular_color", "shading_normal")
FLOAT_ATTRIBUTES: tuple[str, ...] = ("shininess", "refraction_index", "roughness", "glossy_samples", "cauchy_b",
                                     "sss_eta", "sss_g", "sss_samples")
#: docs/EXTENSIONS.md E.18: the subsurface medium's coefficients (per scene unit), served as colours.
SSS_ATTRIBUTES: tuple[str, ...] = ("sss_sigma_a", "sss_sigma_s")


def _rgb(props: mi.Properties, name: str, default: Sequence[float]) -> list[float]:
    """Read an rgb property (``ScalarColor3d``/``ScalarColor3f``/float) as three Python floats."""
    if name not in props:
        return [float(c) for c in default]
    value = props.get(name)
    if isinstance(value, (int, float)):
        return [float(value)] * 3
    try:
        return [float(value[i]) for i in range(3)]
    except (TypeError, IndexError):
        raise ValueError(f"a5_material: '{name}' must be an rgb colour, got {value!r}") from None


def constant_texture(color: Sequence[float]) -> mi.Texture:
    """An unbounded ``srgb`` texture of ``color`` (any finite colour: SPEC A.5 sets no range), made by Mitsuba's
    plugin manager. Never ``mi.load_dict`` inside a constructor: a load swaps Mitsuba's global file resolver for
    its own copy and frees that copy when it returns, while the other tasks of a parallel load read the global
    (a plugin library's first load resolves its path through it): a use after free (docs/MITSUBA.md
    "Loading in parallel")."""
    props = mi.Properties("srgb")
    props["color"] = mi.ScalarColor3f(*color)
    props["unbounded"] = True
    return mi.PluginManager.instance().create_object(props)


class A5Material(mi.BSDF):
    """The a5 ``Material`` (SPEC A.5; values consumed by ``a5_whitted`` per SPEC B.3). See the module doc."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        diffuse = _rgb(props, "diffuse_color", (1.0, 1.0, 1.0))
        specular = _rgb(props, "specular_color", (0.0, 0.0, 0.0))
        shininess = float(props.get("shininess", 0.0))
        ior = float(props.get("refraction_index", 0.0))
        if ior < 0.0:
            raise ValueError(f"a5_material: 'refraction_index' must be >= 0 (0 = opaque), got {ior}")
        if "kd" in props:
            self.kd: mi.Texture = props.get_texture("kd")
        else:  # a5soln renders a colour of 1.5 as it is
            self.kd = constant_texture(diffuse)
        self.diffuse_color = mi.Color3f(*diffuse)
        self.specular_color = mi.Color3f(*specular)
        self.shininess = mi.Float(shininess)
        self.refraction_index = mi.Float(ior)
        # docs/EXTENSIONS.md E.4: GGX alpha of the glossy lobe (0 = mirror) and children per camera hit
        roughness = float(props.get("roughness", 0.0))
        glossy_samples = int(props.get("glossy_samples", 1))
        if not 0.0 <= roughness <= 1.0 or glossy_samples < 1:
            raise ValueError(f"a5_material: need 0 <= roughness <= 1 and glossy_samples >= 1, got {roughness}, "
                             f"{glossy_samples}")
        self.roughness = mi.Float(roughness)
        self.glossy_samples = mi.Float(float(glossy_samples))
        # docs/EXTENSIONS.md E.10: n(λ) = refraction_index + cauchy_b/λ² (λ in µm) in a5_whitted's dispersion kernel
        cauchy_b = float(props.get("cauchy_b", 0.0))
        if cauchy_b != 0.0 and ior <= 0.0:
            raise ValueError(f"a5_material: 'cauchy_b' needs refraction_index > 0, got {ior}")
        self.cauchy_b = mi.Float(cauchy_b)
        self._dispersive = cauchy_b != 0.0
        # docs/EXTENSIONS.md E.7: height field and normal map (a5_bitmap textures: their A.4 texel atlas)
        self.bump = self._map(props, "bump")
        self.normal_map = self._map(props, "normal_map")
        self.bump_scale = mi.Float(float(props.get("bump_scale", 1.0)))
        # docs/EXTENSIONS.md E.18: the subsurface medium (sss_eta = 0: none), read by a5_whitted's -subsurface
        self.sss = {name: mi.Color3f(*_rgb(props, name, (0.0, 0.0, 0.0))) for name in SSS_ATTRIBUTES}
        self.sss_scalars = {name: mi.Float(float(props.get(name, 0.0))) for name in ("sss_eta", "sss_g",
                                                                                    "sss_samples")}
        for value in (*self.sss.values(), *self.sss_scalars.values()):
            dr.make_opaque(value)
        self._make_opaque()

        spec_len = sum(c * c for c in specular) ** 0.5
        self._has_delta = spec_len > MIRROR_THRESHOLD or ior > 0.0
        self._dielectric = ior > 0.0
        diffuse_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        components = [int(diffuse_flags)]
        if self._has_delta:
            if self._dielectric:
                sides = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
                components.append(int(mi.BSDFFlags.DeltaReflection | sides))
                components.append(int(mi.BSDFFlags.DeltaTransmission | sides))
            else:
                components.append(int(mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide
                                      | mi.BSDFFlags.BackSide))
        flags = 0
        for c in components:
            flags |= c
        self.m_components = components
        self.m_flags = flags

    @staticmethod
    def _map(props: mi.Properties, name: str) -> mi.Texture | None:
        """The ``bump`` / ``normal_map`` texture, which must be an ``a5_bitmap`` (its texels are read)."""
        if name not in props:
            return None
        tex = props.get_texture(name)
        if not hasattr(tex, "atlas"):
            raise ValueError(f"a5_material: '{name}' must be an a5_bitmap texture, got {tex}")
        return tex

    def _make_opaque(self) -> None:
        dr.make_opaque(self.diffuse_color, self.specular_color, self.shininess, self.refraction_index,
                       self.roughness, self.glossy_samples, self.cauchy_b, self.bump_scale)

    # ------------------------------------------------------------------ a5 channel (SPEC B.3)

    def has_attribute(self, name: str, active: mi.Bool = True) -> mi.Bool:
        """True for ``diffuse_color``, ``specular_color``, ``shininess``, ``refraction_index``."""
        return mi.Bool(name in COLOR_ATTRIBUTES or name in FLOAT_ATTRIBUTES or name in SSS_ATTRIBUTES)

    def eval_attribute_3(self, name: str, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """``diffuse_color`` or ``specular_color`` (raw, untextured), ``shading_normal`` (E.7); zero for any
        other name."""
        if name == "shading_normal":
            if self.bump is None and self.normal_map is None:
                return mi.Color3f(si.sh_frame.n)
            return mi.Color3f(perturb(si, None if self.bump is None else self.bump.atlas, self.bump_scale,
                                      None if self.normal_map is None else self.normal_map.atlas, active))
        value = {"diffuse_color": self.diffuse_color, "specular_color": self.specular_color, **self.sss}.get(name)
        return mi.Color3f(0.0) if value is None else mi.Color3f(value)

    def eval_attribute_1(self, name: str, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Float:
        """``refraction_index`` or ``shininess``; zero for any other name."""
        value = {"refraction_index": self.refraction_index, "shininess": self.shininess,
                 "roughness": self.roughness, "glossy_samples": self.glossy_samples,
                 "cauchy_b": self.cauchy_b, **self.sss_scalars}.get(name)
        return mi.Float(0.0) if value is None else mi.Float(value)

    def eval_diffuse_reflectance(self, si: mi.SurfaceInteraction3f, active: mi.Bool = True) -> mi.Color3f:
        """``kd`` at the hit (SPEC B.3: marble colour, else texture at uv, else diffuseColor)."""
        return mi.Color3f(self.kd.eval(si, active))

    # ------------------------------------------------------------------ physical BSDF (stock integrators)

    def _spec_probability(self, ctx: mi.BSDFContext, kd: mi.Color3f) -> mi.Float:
        """``p_s`` of the module doc, honouring the context's component selection."""
        if not self._has_delta:
            return mi.Float(0.0)
        use_diffuse = ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0)
        use_delta = ctx.is_enabled(mi.BSDFFlags.DeltaReflection, 1) or (
            self._dielectric and ctx.is_enabled(mi.BSDFFlags.DeltaTransmission, 2)
        )
        if not use_delta:
            return mi.Float(0.0)
        if not use_diffuse:
            return mi.Float(1.0)
        w_s = dr.mean(self.specular_color)
        w_d = dr.mean(kd)
        total = w_s + w_d
        return dr.select(total > 0.0, w_s / total, 0.0)

    def sample(
        self, ctx: mi.BSDFContext, si: mi.SurfaceInteraction3f, sample1: mi.Float, sample2: mi.Point2f,
        active: mi.Bool = True,
    ) -> tuple[mi.BSDFSample3f, mi.Color3f]:
        """Sample the Lambert + delta mixture (see the module doc for the weights)."""
        cos_i = mi.Frame3f.cos_theta(si.wi)
        kd = self.eval_diffuse_reflectance(si, active)
        p_s = self._spec_probability(ctx, kd)
        bs = dr.zeros(mi.BSDFSample3f)
        bs.eta = mi.Float(1.0)
        choose_delta = sample1 < p_s
        # Diffuse lobe (E.13, two-sided): cosine-weighted about the side of N that wi is on.
        wo_h = mi.warp.square_to_cosine_hemisphere(sample2)
        wo_d = mi.Vector3f(wo_h.x, wo_h.y, dr.mulsign(wo_h.z, cos_i))
        ok_d = active & ~choose_delta & (cos_i != 0.0)
        weight_d = kd / dr.maximum(1.0 - p_s, 1e-8)
        pdf_d = (1.0 - p_s) * mi.warp.square_to_cosine_hemisphere_pdf(wo_h)
        # Delta lobe: mirror, or dielectric with exact Fresnel.
        wo_r = mi.reflect(si.wi)
        weight_s = self.specular_color / dr.maximum(p_s, 1e-8)
        ok_s = active & choose_delta
        if self._dielectric:
            # docs/EXTENSIONS.md E.10: a dispersive material at the centre wavelength, as the stock mapping
            ior = self.refraction_index
            if self._dispersive:
                ior = ior + self.cauchy_b * (1.0 / (CENTRE_WAVELENGTH_NM * 1e-3) ** 2)
            r_i, cos_t, eta_it, eta_ti = mi.fresnel(cos_i, ior)
            u = sample1 / dr.maximum(p_s, 1e-8)
            pick_r = u <= r_i
            wo_s = dr.select(pick_r, wo_r, mi.refract(si.wi, cos_t, eta_ti))
            pdf_s = p_s * dr.select(pick_r, r_i, 1.0 - r_i)
            eta_s = dr.select(pick_r, 1.0, eta_it)
            type_s = dr.select(pick_r, mi.UInt32(int(mi.BSDFFlags.DeltaReflection)),
                               mi.UInt32(int(mi.BSDFFlags.DeltaTransmission)))
            comp_s = dr.select(pick_r, mi.UInt32(1), mi.UInt32(2))
            if ctx.mode == mi.TransportMode.Radiance:
                weight_s = weight_s * dr.select(pick_r, 1.0, eta_ti * eta_ti)
        else:
            wo_s = wo_r
            pdf_s = p_s
            eta_s = mi.Float(1.0)
            type_s = mi.UInt32(int(mi.BSDFFlags.DeltaReflection))
            comp_s = mi.UInt32(1)
        bs.wo = dr.select(choose_delta, wo_s, wo_d)
        bs.pdf = dr.select(choose_delta, pdf_s, pdf_d)
        bs.eta = dr.select(choose_delta, eta_s, 1.0)
        bs.sampled_type = dr.select(choose_delta, type_s, mi.UInt32(int(mi.BSDFFlags.DiffuseReflection)))
        bs.sampled_component = dr.select(choose_delta, comp_s, mi.UInt32(0))
        weight = dr.select(choose_delta, weight_s, weight_d)
        ok = ok_d | ok_s
        bs.pdf = dr.select(ok, bs.pdf, 0.0)
        return bs, dr.select(ok & (bs.pdf > 0.0), weight, 0.0)

    def eval(
        self, ctx: mi.BSDFContext, si: mi.SurfaceInteraction3f, wo: mi.Vector3f, active: mi.Bool = True
    ) -> mi.Color3f:
        """Lambert ``kd/π |cosθ_o|`` where ``wo`` is on ``wi``'s side (E.13); the delta lobe evaluates to 0."""
        kd, same_side = self._diffuse_lobe(ctx, si, wo, active)
        return dr.select(same_side, kd * (dr.inv_pi * dr.abs(mi.Frame3f.cos_theta(wo))), 0.0)

    def pdf(
        self, ctx: mi.BSDFContext, si: mi.SurfaceInteraction3f, wo: mi.Vector3f, active: mi.Bool = True
    ) -> mi.Float:
        """``(1 - p_s) |cosθ_o|/π`` for the diffuse lobe on ``wi``'s side (delta lobes have no density)."""
        kd, same_side = self._diffuse_lobe(ctx, si, wo, active)
        value = (1.0 - self._spec_probability(ctx, kd)) * (dr.inv_pi * dr.abs(mi.Frame3f.cos_theta(wo)))
        return dr.select(same_side, value, 0.0)

    def _diffuse_lobe(
        self, ctx: mi.BSDFContext, si: mi.SurfaceInteraction3f, wo: mi.Vector3f, active: mi.Bool
    ) -> tuple[mi.Color3f, mi.Bool]:
        """``(kd, mask)``: the Lambert colour and where the diffuse lobe exists (enabled in ``ctx``, ``wi`` and
        ``wo`` strictly on the same side of the shading frame: ``cosθ_i cosθ_o > 0``, E.13's two-sided Lambert)."""
        enabled = ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0)
        same_side = active & enabled & (mi.Frame3f.cos_theta(si.wi) * mi.Frame3f.cos_theta(wo) > 0.0)
        return self.eval_diffuse_reflectance(si, active), same_side

    # ------------------------------------------------------------------ plumbing

    def traverse(self, callback: mi.TraversalCallback) -> None:
        flags = int(mi.ParamFlags.NonDifferentiable)
        callback.put("diffuse_color", self.diffuse_color, flags)
        callback.put("specular_color", self.specular_color, flags)
        callback.put("shininess", self.shininess, flags)
        callback.put("refraction_index", self.refraction_index, flags)
        callback.put("roughness", self.roughness, flags)
        callback.put("glossy_samples", self.glossy_samples, flags)
        callback.put("cauchy_b", self.cauchy_b, flags)
        callback.put("kd", self.kd, flags)
        callback.put("bump_scale", self.bump_scale, flags)

    def parameters_changed(self, keys: list[str] | None = None) -> None:
        self._make_opaque()

    def to_string(self) -> str:
        return (
            "A5Material[\n"
            f"  diffuse_color = {self.diffuse_color},\n"
            f"  kd = {self.kd},\n"
            f"  specular_color = {self.specular_color},\n"
            f"  shininess = {self.shininess},\n"
            f"  refraction_index = {self.refraction_index}\n"
            "]"
        )


def register() -> None:
    """Register ``a5_material`` with Mitsuba for the active variant."""
    mi.register_bsdf("a5_material", lambda props: A5Material(props))

"""The a5mi Mitsuba plugins (SPEC A.3-A.5, B.2-B.4).

Each module holds one plugin and registers it at its bottom through a ``register()`` function. Import
this package only after ``mi.set_variant`` has selected a JIT variant (``llvm_ad_rgb`` or ``cuda_ad_rgb``),
then call :func:`register_all`; after that ``mi.load_dict({'type': 'a5_whitted', ...})`` and the XML form
work like any stock plugin. (``syntax.py`` is the one module that needs no variant: the ``@dr.syntax``
cache the plugins decorate with, which :func:`a5mi.runtime.variant.activate` also applies to ``mi.set_variant``.)
"""

from __future__ import annotations

import importlib

# Explicit list, in dependency order (textures before the BSDF that nests them).
PLUGIN_MODULES: tuple[str, ...] = (
    "textures.marble",           # a5_marble texture (noise functions in perlin.py)
    "textures.bitmap",           # a5_bitmap texture
    "textures.solids",           # a5_solid textures: wood, turbulence, veins (docs/EXTENSIONS.md E.6)
    "textures.btf",              # a5_btf view-dependent texture (docs/EXTENSIONS.md E.19)
    "emitters.point_light",      # a5_point emitter
    "emitters.spot_light",       # a5_spot emitter (docs/EXTENSIONS.md E.1)
    "emitters.area_light",       # a5_area emitter (docs/EXTENSIONS.md E.2)
    "emitters.cubemap",          # a5_cubemap emitter
    "sensors.camera",           # a5_camera sensor
    "materials.a5_material",      # a5_material BSDF
    "materials.milled",           # a5_milled BSDF: Ward on a milling tangent field (docs/EXTENSIONS.md E.20)
    "integrators.whitted.integrator",          # a5_whitted integrator
    "integrators.path",             # a5_path integrator (docs/EXTENSIONS.md E.13, E.14)
    "integrators.photon.integrator",           # a5_photon integrator (docs/EXTENSIONS.md E.16)
    "integrators.photon.ppm",              # a5_ppm integrator (docs/EXTENSIONS.md E.17)
    "integrators.irradiance_cache.integrator", # a5_irradiancecache integrator (docs/EXTENSIONS.md E.23)
)

def register_all() -> None:
    """Register every a5mi plugin with Mitsuba for the active variant.

    Idempotent without bookkeeping here: Mitsuba's registry maps each name to its constructor, so a second call
    (another session, a test) re-registers the same constructors (about 30 µs in all; the modules are imported
    once by Python). Mitsuba offers no query for Python-registered plugins (``PluginManager.plugin_type`` answers
    ``Unknown`` for them), and a module-level "done for variant X" flag would be state that outlives a variant
    switch's own registry."""
    import mitsuba as mi

    variant = mi.variant()
    if variant is None or variant.startswith("scalar"):
        raise RuntimeError(
            f"a5mi plugins need a JIT variant (llvm_ad_rgb or cuda_ad_rgb), not {variant!r}: "
            "Python plugins in scalar variants run once per sample"
        )
    for name in PLUGIN_MODULES:
        module = importlib.import_module(f"{__name__}.{name}")
        module.register()

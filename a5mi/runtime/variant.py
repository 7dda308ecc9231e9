"""Choose and activate the Mitsuba variant, in one place.

``llvm_ad_rgb`` (CPU) is the default; ``cuda_ad_rgb`` when asked for (``-variant cuda`` or
``A5MI_VARIANT=cuda``), or with ``A5MI_VARIANT=auto`` when a CUDA device is present. Scalar variants are
refused: Python plugins are then called once per sample (about 15x slower here).

Before an LLVM variant is loaded, :func:`a5mi.runtime.llvm.check` makes sure Dr.Jit will find LLVM >= 16, so an old
LLVM gives a one-line :class:`VariantError` instead of Dr.Jit's process abort.
"""

from __future__ import annotations

import os

from a5mi.runtime import llvm

VARIANTS = {"llvm": "llvm_ad_rgb", "cuda": "cuda_ad_rgb"}
ENV_VAR = "A5MI_VARIANT"


class VariantError(RuntimeError):
    """The requested variant cannot run on this machine (user-fixable; the message names the fix)."""


def cuda_available() -> bool:
    """True when an NVIDIA driver is visible, without initialising Dr.Jit's CUDA backend."""
    import ctypes

    for name in ("libcuda.so.1", "libcuda.so"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        count = ctypes.c_int(0)
        if lib.cuInit(0) == 0 and lib.cuDeviceGetCount(ctypes.byref(count)) == 0:
            return count.value > 0
    return False


def resolve(requested: str | None = None) -> str:
    """Map ``llvm`` / ``cuda`` / ``auto`` / a full variant name (or ``$A5MI_VARIANT``) to a variant name."""
    choice = (requested or os.environ.get(ENV_VAR) or "llvm").strip()
    if choice == "auto":
        choice = "cuda" if cuda_available() else "llvm"
    if choice in VARIANTS:
        return VARIANTS[choice]
    if choice in VARIANTS.values():
        return choice
    raise VariantError(f"unknown variant '{choice}' (expected llvm, cuda or auto)")


def activate(requested: str | None = None) -> str:
    """Check prerequisites, ``mi.set_variant`` and register the a5mi plugins. Returns the variant name."""
    name = resolve(requested)
    if name.startswith("llvm"):
        try:
            llvm.check()
        except llvm.LLVMError as exc:
            raise VariantError(str(exc)) from None
    elif name.startswith("cuda") and not cuda_available():
        raise VariantError("the cuda variant needs an NVIDIA GPU and driver; none was found (use -variant llvm)")

    import mitsuba as mi

    from a5mi.plugins.syntax import cached_drjit_syntax

    if mi.variant() != name:
        try:
            with cached_drjit_syntax():  # Mitsuba's Python integrators, transformed again by every set_variant
                mi.set_variant(name)
        except Exception as exc:  # noqa: BLE001 - Mitsuba raises plain exceptions here
            raise VariantError(f"cannot load Mitsuba variant {name}: {exc}") from None
    if name.startswith("llvm"):
        import drjit as dr

        dr.llvm.Float(0.0)  # initialises the LLVM backend (loads libLLVM) without compiling a kernel
        try:
            llvm.check_loaded()
        except llvm.LLVMError as exc:
            raise VariantError(str(exc)) from None
    from a5mi.plugins import register_all

    register_all()
    return name

"""Constants that must agree across the layers that cannot import each other (ARCHITECTURE.md: converters and
plugins are independent; a5mi avoids importing Mitsuba before parsing)."""

from __future__ import annotations


def test_mirror_threshold_and_fresnel_modes_agree(variant) -> None:
    from a5mi import crosscheck, driver
    from a5mi.converters import materials
    from a5mi.plugins import a5_material, common, whitted

    assert whitted.MIRROR_THRESHOLD == a5_material.MIRROR_THRESHOLD == materials.MIRROR_THRESHOLD == 0.001
    assert tuple(driver.FRESNEL_MODES) == tuple(crosscheck.FRESNEL_MODES) == tuple(common.FRESNEL_MODES)

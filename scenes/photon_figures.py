"""The photon-mapping figure of docs/EXTENSIONS.md E.16: scenes/caustic_sphere.txt by ``a5_photon`` (left) and
by Mitsuba's stock ``ptracer`` on the stock conversion (right), both lit by the conversion's stock point light.

    A5_DATA=... python scenes/photon_figures.py docs/photon_caustic_vs_ptracer.png [SIZE] [PTRACER_SPP]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


def main(out: str, size: int = 160, spp: int = 1024) -> None:
    from a5mi.converters.to_mitsuba import to_dict
    from a5mi.platform import imageio
    from a5mi.render.options import RenderOptions
    from a5mi.render.session import describe_file
    from a5mi.runtime.variant import activate

    activate()
    import mitsuba as mi

    desc, _ = describe_file(str(Path(__file__).with_name("caustic_sphere.txt")))
    opts = RenderOptions(width=size, height=size, shadows=True, fresnel="exact", integrator="photon",
                         photons=50000, caustic_photons=300000, photon_k=50, bounces=8)
    a5, stock = to_dict(desc, opts), to_dict(desc, opts, stock=True)
    point = {k: v for k, v in stock.items() if isinstance(v, dict) and v.get("type") == "point"}
    a5 = {k: v for k, v in a5.items() if not (isinstance(v, dict) and v.get("type") == "a5_point")} | point
    stock["integrator"] = {"type": "ptracer", "max_depth": 12}
    stock["sensor"]["sampler"] = {"type": "independent", "sample_count": spp}
    left = np.asarray(mi.render(mi.load_dict(a5)))
    right = np.asarray(mi.render(mi.load_dict(stock), seed=1))
    gap = np.ones((size, 2, 3), dtype=np.float32)
    image = np.clip(np.concatenate([left, gap, right], axis=1) * 2.0, 0.0, 1.0) ** (1.0 / 2.2)
    imageio.write_images([(out, image.astype(np.float32))])


if __name__ == "__main__":
    main(sys.argv[1], *(int(a) for a in sys.argv[2:]))

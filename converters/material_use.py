"""The materials step of the scene description: the files of each material a shape uses, read on first use.

SPEC B.3 reads a material's texture only where a hit has uv; :class:`MaterialUse` follows the scene's shapes in
order (so errors and warnings come in the order of the objects) and, for each shape's material, checks and
decodes its ``texture`` (A.4), its ``bump`` height field and ``normalMap`` with ``-bump`` (docs/EXTENSIONS.md
E.7) and its ``btf`` images (E.19), and notes what cannot show on a shape without texture coordinates. With
``stock=True`` it adds, once per material, the warnings of the stock conversion's approximations (Noise, solids
E.6, dispersion E.10, milled and btf E.19-E.20). :func:`.describe.describe` builds the
:class:`~.describe.MaterialDescription` s from what it collected.

May import the typed model, :mod:`.files` and :mod:`.surface_ext`; never :mod:`.describe` (its client).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from a5mi.converters import files
from a5mi.converters.errors import FileLoc
from a5mi.converters.files import Image
from a5mi.converters.model import Material, Scene
from a5mi.converters.surface_ext import STOCK_BTF_WARNING, STOCK_WARNING, BtfImages, describe_btf
from a5mi.spec import CENTRE_WAVELENGTH_NM

SceneWarning = tuple[FileLoc, str]


def stock_material_warnings(mat: Material) -> list[SceneWarning]:
    """The stock conversion's approximations of ``mat`` (:mod:`.to_mitsuba`): Noise by its mean colour, a solid
    (E.6) baked into an RGB grid, dispersion (E.10) by the index at the centre wavelength
    ``n_c = n + B / lambda_c^2`` (lambda in um), milled and btf (E.19, E.20) by their stock stand-ins."""
    out: list[SceneWarning] = []
    if mat.noise is not None:
        out.append((mat.noise.loc or mat.loc,  # type: ignore[arg-type]
                    "stock conversion: Noise (marble) replaced by its mean colour"))
    if mat.solid is not None:  # docs/EXTENSIONS.md E.6, stock mapping
        out.append((mat.solid.loc or mat.loc,  # type: ignore[arg-type]
                    f"stock conversion: {mat.solid.kind.capitalize()} baked into an RGB grid over "
                    "its shapes' box (stock 'volume' texture, trilinear)"))
    if mat.dispersion is not None:  # docs/EXTENSIONS.md E.10
        n_c = mat.refraction_index + mat.dispersion / (CENTRE_WAVELENGTH_NM * 1e-3) ** 2
        out.append((mat.loc,  # type: ignore[arg-type]
                    "stock conversion: dispersion replaced by the index at the centre wavelength, "
                    f"n({CENTRE_WAVELENGTH_NM:g} nm) = {n_c:.6g}"))
    out.extend((mat.loc, w) for w, on in ((STOCK_WARNING, mat.milled), (STOCK_BTF_WARNING, mat.btf))  # type: ignore[misc]
               if on is not None)  # docs/EXTENSIONS.md E.19, E.20
    return out


@dataclass
class MaterialUse:
    """The images of the materials the scene's shapes use, each file decoded once (``decoded``, by path).

    ``textures``: material -> its texture (where no Noise or solid hides it); ``maps``: ``(material, 'bump' |
    'normal_map')`` -> image (E.7, with ``bump``); ``btfs``: material -> its btf images (E.19). Warnings are
    appended to ``warnings``."""

    scene: Scene
    stock: bool
    bump: bool
    decoded: files.Decoded
    warnings: list[SceneWarning]
    used: set[int] = field(default_factory=set)
    textures: dict[int, Image] = field(default_factory=dict)
    maps: dict[tuple[int, str], Image] = field(default_factory=dict)
    btfs: dict[int, BtfImages] = field(default_factory=dict)

    def use(self, index: int, with_uv: bool, shape: object) -> None:
        """Material ``index`` used on ``shape`` (``with_uv``: the shape has texture coordinates): its files
        read and checked on first need, and what cannot show on ``shape`` warned at the shape."""
        mat = self.scene.materials[index]
        if index not in self.used:
            self.used.add(index)
            if self.stock:
                self.warnings.extend(stock_material_warnings(mat))
        if mat.btf is not None:
            self._btf(index, mat, with_uv, shape)
        self._maps(index, mat, with_uv, shape)
        if mat.texture is not None:
            self._texture(index, mat, with_uv, shape)

    def _btf(self, index: int, mat: Material, with_uv: bool, shape: object) -> None:
        """E.19: the images, read once; no texture coordinates, no lookup."""
        if index not in self.btfs:
            self.btfs[index] = describe_btf(self.scene, mat, self.decoded)
        if not with_uv:
            self.warnings.append((shape.loc, f"btf cannot show on this {type(shape).__name__}: it has no "  # type: ignore[attr-defined]
                                  "texture coordinates (SPEC B.3)"))

    def _maps(self, index: int, mat: Material, with_uv: bool, shape: object) -> None:
        """E.7 with ``bump``: the height field and normal map on shapes with uv; like a texture, a map cannot
        show without uv."""
        if not self.bump:
            return
        if with_uv:
            for which in ("bump", "normal_map"):
                if getattr(mat, which) is not None and (index, which) not in self.maps:
                    self.maps[(index, which)], warning = files.map_image(self.scene, mat, which, self.decoded)
                    if warning is not None:
                        self.warnings.append((mat.bump_loc or mat.loc, warning))  # type: ignore[arg-type]
            return
        for which, name in (("bump", mat.bump), ("normalMap", mat.normal_map)):
            if name is not None:
                self.warnings.append((shape.loc, f"{which} '{name}' cannot show on this "  # type: ignore[attr-defined]
                                      f"{type(shape).__name__}: it has no texture coordinates (EXTENSIONS E.7)"))

    def _texture(self, index: int, mat: Material, with_uv: bool, shape: object) -> None:
        """A referenced file is checked wherever it is used, even where Noise hides it (SPEC B.3 kd order)."""
        image = files.texture_image(self.scene, mat, self.decoded)
        if mat.noise is not None or mat.solid is not None:
            return
        self.textures.setdefault(index, image)
        if not with_uv:
            kind = type(shape).__name__
            # docs/FIDELITY.md "Stale texture coordinates": a5soln may show it at a mesh's uv (-quirks binary)
            stale = "; a5soln may show it at a textured mesh's stale uv (-quirks binary)" \
                if kind in ("Sphere", "Plane") else ""
            self.warnings.append((shape.loc, f"texture '{mat.texture}' cannot show on this "  # type: ignore[attr-defined]
                                  f"{kind}: it has no texture coordinates (SPEC B.3){stale}"))

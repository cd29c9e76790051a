r"""Textures: loading (PNG via Pillow, EXR via :mod:`warp_sg.core.image_io`) and sampling.

A material parameter is either a constant or a :class:`Texture` (per-texel spatially varying
reflectance, paper §7: "Textures store the BRDF parameters"). Conventions:

* UV origin at the **bottom-left** of the image (OpenGL / OBJ / trimesh): texel row
  ``y = (1 − v)·H``; the texture repeats (wraps) outside [0, 1]; bilinear filtering with texel
  centres at ``(i + ½)/W``.
* Values: ``value = offset + scale · texel``. PNG texels are ``byte/255`` (16-bit: ``/65535``);
  colour parameters (``kd``, ``ks``) read PNGs as sRGB and decode them to linear by default,
  everything else (roughness, exponents, normal and tangent maps) reads them linearly
  (``srgb = true/false`` overrides). EXR texels are linear floats.
* Scalar parameters use the first channel; colour parameters use RGB (a one-channel image is
  broadcast to grey).
* Normal maps are tangent-space RGB ``n = 2·rgb − 1`` (x = tangent, y = bitangent, z = normal),
  tangent maps store the tangent direction in the tangent plane as ``(2r − 1, 2g − 1)``.

On the kernel side all textures of a scene live in one flat ``vec4`` texel array
(:class:`TextureAtlas`), each texture described by (offset, width, height); a material slot
refers to a texture by index (−1 = constant), see :mod:`warp_sg.shading.kernel`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp

from warp_sg.core.errors import ImageError

PNG_SUFFIXES = (".png",)
EXR_SUFFIXES = (".exr",)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def read_texture_file(path, *, srgb: bool = False) -> np.ndarray:
    """Read an image file into a float32 (H, W, 4) array (RGBA; missing channels: grey/alpha 1).

    Raises :class:`~warp_sg.core.errors.ImageError` naming the file when it is missing or unreadable.
    """
    import warnings

    from warp_sg.core.image_io import check_image_file
    from warp_sg.core.watchdog import MAX_TEXTURE_TEXELS

    p = Path(path)
    if p.is_dir():
        raise ImageError("is a folder, not a texture file", where=str(p))
    if not p.is_file():
        raise ImageError("texture file not found", where=str(p))
    check_image_file(p, "texture", MAX_TEXTURE_TEXELS)  # before decoding (a 1e9-texel file is refused)
    suf = p.suffix.lower()
    if suf in EXR_SUFFIXES:
        try:
            from warp_sg.core.image_io import load_image
        except ImportError as e:  # pragma: no cover - image_io is another module of the project
            raise ImageError(f"cannot read EXR textures yet ({e})", where=str(p)) from None
        a = np.asarray(load_image(p), np.float32)
    else:
        try:
            from PIL import Image

            with warnings.catch_warnings(), Image.open(p) as im:  # size checked above: no bomb warning
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                im.load()
                if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                    a = np.asarray(im, np.float32) / 65535.0
                elif im.mode == "F":
                    a = np.asarray(im, np.float32)
                else:
                    if im.mode not in ("L", "LA", "RGB", "RGBA"):
                        im = im.convert("RGBA")
                    a = np.asarray(im, np.float32) / 255.0
        except ImageError:
            raise
        except Exception as e:  # noqa: BLE001 - Pillow raises many types for bad files
            raise ImageError(f"cannot read image ({e})", where=str(p)) from None
        if srgb:
            a = a.copy()
            nc = a.shape[-1] if a.ndim == 3 else 1
            if a.ndim == 2:
                a = srgb_to_linear(a)
            else:
                a[..., : min(nc, 3) if nc != 2 else 1] = srgb_to_linear(a[..., : min(nc, 3) if nc != 2 else 1])
    return to_rgba(a, str(p))


def to_rgba(a: np.ndarray, where: str = "texture") -> np.ndarray:
    """(H, W), (H, W, 1|2|3|4) -> float32 (H, W, 4); grey is broadcast to RGB, alpha defaults to 1."""
    a = np.asarray(a, np.float32)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1 or a.shape[2] not in (1, 2, 3, 4):
        raise ImageError(f"expected an (H, W[, C]) image with 1-4 channels, got shape {a.shape}", where=where)
    if not np.all(np.isfinite(a)):
        raise ImageError("texture has non-finite texels", where=where)
    h, w, c = a.shape
    out = np.ones((h, w, 4), np.float32)
    if c in (1, 2):
        out[..., :3] = a[..., :1]
        if c == 2:
            out[..., 3] = a[..., 1]
    else:
        out[..., :c] = a
    return out


@dataclass
class Texture:
    """A texture map for a material parameter (or a normal/tangent map).

    Give ``path`` (PNG or EXR; resolved relative to the scene file by the loader) or ``data``
    ((H, W[, C]) array, linear). ``value = offset + scale · texel``. ``srgb=None`` means "decide
    by use": colour parameters decode sRGB PNGs, others do not.
    """

    path: str | Path | None = None
    data: np.ndarray | None = None
    srgb: bool | None = None
    scale: float = 1.0
    offset: float = 0.0
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def rgba(self, *, colour: bool = False) -> np.ndarray:
        """Texel values (H, W, 4) float32 with ``offset + scale ·`` applied to RGB."""
        srgb = colour if self.srgb is None else bool(self.srgb)
        key = ("rgba", srgb)
        if key not in self._cache:
            if self.data is not None:
                raw = to_rgba(self.data)
            elif self.path is not None:
                raw = read_texture_file(self.path, srgb=srgb)
            else:
                raise ImageError("texture has neither a path nor data")
            out = raw.copy()
            out[..., :3] = self.offset + self.scale * raw[..., :3]
            self._cache[key] = out
        return self._cache[key]

    def mean(self, *, colour: bool = False) -> np.ndarray:
        """Mean RGB value (used to build the material's constant model, e.g. for its SG fit)."""
        return self.rgba(colour=colour)[..., :3].reshape(-1, 3).mean(0)

    def raw(self) -> np.ndarray:
        """Texels without scale/offset and without sRGB decoding (normal and tangent maps)."""
        key = ("raw",)
        if key not in self._cache:
            if self.data is not None:
                self._cache[key] = to_rgba(self.data)
            elif self.path is not None:
                self._cache[key] = read_texture_file(self.path, srgb=False)
            else:
                raise ImageError("texture has neither a path nor data")
        return self._cache[key]


def sample_bilinear_np(rgba: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """numpy twin of :func:`tex_sample`: bilinear, wrapping, UV origin bottom-left. uv (..., 2)."""
    h, w = rgba.shape[:2]
    x = np.asarray(uv[..., 0], np.float64) * w - 0.5
    y = (1.0 - np.asarray(uv[..., 1], np.float64)) * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    x0 %= w
    y0 %= h
    c00, c10, c01, c11 = rgba[y0, x0], rgba[y0, x1], rgba[y1, x0], rgba[y1, x1]
    return ((c00 * (1 - fx) + c10 * fx) * (1 - fy) + (c01 * (1 - fx) + c11 * fx) * fy).astype(np.float32)


# --------------------------------------------------------------------------------------------
# kernel side
# --------------------------------------------------------------------------------------------
@wp.struct
class TextureAtlas:
    """All textures of a scene: ``texels`` flat (row-major, row 0 = top of the image);
    texture ``t`` occupies ``texels[offset[t] : offset[t] + width[t]·height[t]]``."""

    texels: wp.array(dtype=wp.vec4)
    offset: wp.array(dtype=int)
    width: wp.array(dtype=int)
    height: wp.array(dtype=int)


@wp.func
def _wrap(i: int, n: int) -> int:
    r = i % n
    if r < 0:
        r = r + n
    return r


@wp.func
def tex_sample(atlas: TextureAtlas, t: int, uv: wp.vec2) -> wp.vec4:
    """Bilinear, wrapping lookup of texture ``t`` at ``uv`` (origin bottom-left)."""
    w = atlas.width[t]
    h = atlas.height[t]
    base = atlas.offset[t]
    x = uv[0] * float(w) - 0.5
    y = (1.0 - uv[1]) * float(h) - 0.5
    fx0 = wp.floor(x)
    fy0 = wp.floor(y)
    fx = x - fx0
    fy = y - fy0
    x0 = _wrap(int(fx0), w)
    y0 = _wrap(int(fy0), h)
    x1 = _wrap(x0 + 1, w)
    y1 = _wrap(y0 + 1, h)
    c00 = atlas.texels[base + y0 * w + x0]
    c10 = atlas.texels[base + y0 * w + x1]
    c01 = atlas.texels[base + y1 * w + x0]
    c11 = atlas.texels[base + y1 * w + x1]
    return (c00 * (1.0 - fx) + c10 * fx) * (1.0 - fy) + (c01 * (1.0 - fx) + c11 * fx) * fy


def build_atlas(images: list[np.ndarray], device) -> TextureAtlas:
    """Pack (H, W, 4) float32 images into one :class:`TextureAtlas` on ``device``
    (a 1×1 dummy texel when there are none, so kernels always get valid arrays)."""
    if not images:
        images = [np.zeros((1, 1, 4), np.float32)]
    sizes = [im.shape[0] * im.shape[1] for im in images]
    offs = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int32)
    flat = np.concatenate([np.ascontiguousarray(im, np.float32).reshape(-1, 4) for im in images])
    a = TextureAtlas()
    a.texels = wp.array(flat, dtype=wp.vec4, device=device)
    a.offset = wp.array(offs, dtype=int, device=device)
    a.width = wp.array(np.array([im.shape[1] for im in images], np.int32), dtype=int, device=device)
    a.height = wp.array(np.array([im.shape[0] for im in images], np.int32), dtype=int, device=device)
    return a


__all__ = ["Texture", "TextureAtlas", "tex_sample", "build_atlas", "read_texture_file", "sample_bilinear_np",
           "srgb_to_linear", "to_rgba"]

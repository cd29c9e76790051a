r"""Image files: OpenEXR and Radiance HDR (linear float) and PNG/JPEG (8-bit sRGB), docs/environment.md "Image files".

Images are ``(H, W, C)`` float32 numpy arrays of *linear* values, row 0 at the top, ``C`` in
{1, 3, 4} (a 2-D array is one channel).

* :func:`save_image` ``(path, img, exposure=0.0, half=False)``

  - ``.exr``: the values as they are (RGB, Y or RGBA channels), float32 or, with ``half=True``,
    float16, ZIP compression (OpenEXR package).
  - ``.hdr``: Radiance RGBE (OpenCV ``imwrite``): three channels with a shared 8-bit exponent,
    so each channel is stored to within ``max(R, G, B)·2⁻⁸``; negative values and NaN are written
    as 0, grey is broadcast to RGB and alpha dropped.
  - ``.png`` / ``.jpg`` / ``.jpeg``: tone-mapped 8-bit sRGB (:func:`tonemap_srgb`):
    ``x · 2^exposure``, clamped to [0, 1], then the sRGB OETF (IEC 61966-2-1)
    ``c = 12.92 x`` for ``x ≤ 0.0031308``, else ``1.055 x^{1/2.4} − 0.055``; NaN becomes 0.
    Alpha (4th channel) is stored linearly.

  Writes are **atomic**: the data go to a temporary file in the destination folder which is
  then renamed over the target (``os.replace``); on any error nothing is left behind and an
  existing file at ``path`` is untouched. A missing or non-writable folder, an unknown extension
  or an unusable array raise :class:`~warp_sg.core.errors.ImageError` naming the path.

* :func:`load_image` ``(path, *, linear=None, channels=None) -> (H, W, C) float32``

  - EXR: the stored values (half or float) as float32; channels ``R,G,B[,A]`` or ``Y[,A]``
    (layered names such as ``diffuse.R`` are accepted when the file has one layer).
  - Radiance HDR (``.hdr``, or any file starting with ``#?``): RGB float32 decoded by OpenCV
    (``cv2.imread(path, IMREAD_ANYDEPTH | IMREAD_COLOR)``, BGR reordered to RGB).
  - PNG / JPEG / other Pillow formats: 8-bit or 16-bit integers scaled to [0, 1]. ``linear=None``
    (default) or ``False`` decodes the sRGB EOTF for the colour channels (colour textures such as
    ``kd``); ``linear=True`` keeps the code values (data textures: roughness, normal maps,
    masks). Alpha is never decoded.
  - ``channels=3`` converts grey to RGB and drops alpha; ``channels=1`` accepts only
    one-channel (grey) images or converts RGB to luminance (Rec. 709) — any other mismatch is an
    :class:`ImageError` naming the file and the channels found.

* :func:`tonemap_srgb` ``(img, exposure=0.0) -> float32 in [0, 1]`` and the transfer functions
  :func:`srgb_to_linear`, :func:`linear_to_srgb`.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from warp_sg.core.errors import ImageError, reason
from warp_sg.core.files import atomic_output

EXR_EXTS = (".exr",)
HDR_EXTS = (".hdr",)
LDR_EXTS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}
#: Rec. 709 luminance weights (linear RGB).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


# --------------------------------------------------------------------------------------------
# Transfer functions
# --------------------------------------------------------------------------------------------
def linear_to_srgb(x):
    """sRGB OETF (IEC 61966-2-1) for values in [0, 1]: ``12.92 x`` or ``1.055 x^{1/2.4} − 0.055``."""
    x = np.asarray(x, dtype=np.float32)
    lo = 12.92 * x
    hi = 1.055 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4) - 0.055
    return np.where(x <= 0.0031308, lo, hi).astype(np.float32)


def srgb_to_linear(c):
    """sRGB EOTF (inverse of :func:`linear_to_srgb`): ``c/12.92`` or ``((c + 0.055)/1.055)^{2.4}``."""
    c = np.asarray(c, dtype=np.float32)
    lo = c / 12.92
    hi = np.power((np.maximum(c, 0.04045) + 0.055) / 1.055, 2.4)
    return np.where(c <= 0.04045, lo, hi).astype(np.float32)


def tonemap_srgb(img, exposure: float = 0.0):
    """Display encoding: ``srgb_oetf(clamp(img · 2^exposure, 0, 1))``, NaN → 0; float32 in [0, 1].

    ``exposure`` is in photographic stops (+1 doubles the brightness).
    """
    x = np.asarray(img, dtype=np.float32) * np.float32(2.0 ** float(exposure))
    x = np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0)
    return linear_to_srgb(np.clip(x, 0.0, 1.0))


# --------------------------------------------------------------------------------------------
# Saving
# --------------------------------------------------------------------------------------------
def _as_hwc(img, path) -> np.ndarray:
    try:
        a = np.asarray(img)
    except Exception as e:  # noqa: BLE001  pragma: no cover - exotic inputs: any failure is the input's
        raise ImageError(f"cannot convert image to an array ({e})", where=str(path)) from None
    if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer) or a.dtype == bool):
        raise ImageError(f"image array has non-numeric dtype {a.dtype}", where=str(path))
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4) or a.shape[0] < 1 or a.shape[1] < 1:
        raise ImageError(f"image must be (H, W) or (H, W, 1|3|4), got shape {a.shape}", where=str(path))
    return a.astype(np.float32, copy=False)


def _write_exr(tmp: str, a: np.ndarray, half: bool) -> None:
    import OpenEXR

    dt = np.float16 if half else np.float32
    names = {1: "Y", 3: "RGB", 4: "RGBA"}[a.shape[2]]
    channels = {n: np.ascontiguousarray(a[..., k].astype(dt)) for k, n in enumerate(names)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(tmp)


def _cv2():
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # errors are ours, one line
    return cv2


def _write_hdr(tmp: str, a: np.ndarray) -> None:
    rgb = np.repeat(a[..., :1], 3, axis=2) if a.shape[2] == 1 else a[..., :3]
    rgb = np.clip(np.nan_to_num(rgb, nan=0.0, posinf=0.0, neginf=0.0), 0.0, None)
    if not _cv2().imwrite(tmp, np.ascontiguousarray(rgb[..., ::-1], np.float32)):
        raise ImageError("OpenCV could not write the Radiance HDR file", where=tmp)


#: a Radiance resolution line: two axes, each ``[-+][XY] N`` (the first the scanlines' axis)
_HDR_RESOLUTION = re.compile(rb"\n\s*([-+])([XY])\s+(\d+)\s+([-+])([XY])\s+(\d+)[ \t]*\r?\n")


def hdr_resolution(head: bytes, where: str):
    """The resolution line of a Radiance header: ``(match, (sign, axis, n) of the scanlines' axis,
    (sign, axis, n) of the pixels' axis)`` — any of the eight orientations of the format
    (``-Y H +X W`` the usual one: rows top to bottom, pixels left to right; ``+X W -Y H`` column
    scanlines)."""
    m = _HDR_RESOLUTION.search(head)
    if m is None or m.group(2) == m.group(5):
        raise ImageError("cannot read Radiance HDR file (no resolution line such as '-Y 512 +X 1024' in its "
                         "header)", where=where)
    return m, (m.group(1), m.group(2), int(m.group(3))), (m.group(4), m.group(5), int(m.group(6)))


def read_hdr(path) -> np.ndarray:
    """A Radiance RGBE (``.hdr``) file as ``(H, W, 3)`` float32 RGB, row 0 the top, in any of the
    format's eight orientations: the pixels are decoded by OpenCV from the file with its resolution
    line rewritten to ``-Y n1 +X n2`` (scanlines in file order), then flipped and transposed here
    (``+Y``: the first scanline is the bottom; ``-X``: right to left; an ``X`` first: the scanlines
    are columns). Unreadable or truncated files raise :class:`ImageError` naming the file."""
    path = Path(path)
    cv2 = _cv2()
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise ImageError(f"cannot open Radiance HDR file ({e.strerror or e})", where=str(path)) from None
    m, (s1, a1, n1), (s2, _, n2) = hdr_resolution(raw[:1 << 16], str(path))
    std = b"-Y %d +X %d\n" % (n1, n2)
    head = raw[:m.start(1)]
    if head.startswith(b"#?") and not head.startswith((b"#?RADIANCE\n", b"#?RGBE\n")):
        head = b"#?RADIANCE" + head[head.find(b"\n"):]  # (any program name may follow "#?"; OpenCV wants these)
    buf = np.frombuffer(head + std + raw[m.end():], np.uint8)
    a = cv2.imdecode(buf, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
    del buf, raw
    if a is None or a.shape != (n1, n2, 3):
        raise ImageError("cannot read Radiance HDR file (corrupt, truncated or not RGBE)", where=str(path))
    if (s1, a1, s2) == (b"-", b"Y", b"+") and a.dtype == np.float32:  # the usual layout: no copy
        return cv2.cvtColor(a, cv2.COLOR_BGR2RGB, dst=a)
    a = a[..., ::-1]  # BGR → RGB
    if a1 == b"Y":
        a = a[::-1] if s1 == b"+" else a
        a = a[:, ::-1] if s2 == b"-" else a
    else:  # column scanlines: axis 0 runs over X, axis 1 over Y
        a = a[::-1] if s1 == b"-" else a
        a = a[:, ::-1] if s2 == b"+" else a
        a = a.transpose(1, 0, 2)
    return np.ascontiguousarray(a, np.float32)


def image_size(path) -> tuple[int | None, int | None, int]:
    """``(H, W, H·W)`` of an image file from its header alone (the OpenEXR data window, the Radiance
    resolution line, Pillow's lazy open), before any pixel is decoded; ``H``, ``W`` are None when
    Pillow refuses the file as a decompression bomb (its count is then the third value). Unreadable
    headers raise :class:`ImageError` naming the file."""
    import warnings

    path = Path(path)
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError as e:
        raise ImageError(f"cannot open image ({e.strerror or e})", where=str(path)) from None
    if head[:4] == b"\x76\x2f\x31\x01":
        import OpenEXR

        try:
            with OpenEXR.File(str(path), header_only=True) as f:
                lo, hi = f.header()["dataWindow"]
        except Exception as e:  # noqa: BLE001 - the OpenEXR binding raises many types
            raise ImageError(f"cannot read OpenEXR file ({reason(e)})", where=str(path)) from None
        h, w = int(hi[1]) - int(lo[1]) + 1, int(hi[0]) - int(lo[0]) + 1
        return h, w, h * w
    if head[:2] == b"#?":
        _, (_, a1, n1), (_, _, n2) = hdr_resolution(head, str(path))
        h, w = (n1, n2) if a1 == b"Y" else (n2, n1)
        return h, w, h * w
    from PIL import Image, UnidentifiedImageError

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our own bound decides
        try:
            with Image.open(path) as im:
                w, h = im.size
        except Image.DecompressionBombError as e:
            m = re.search(r"\((\d+) pixels\)", str(e))
            return None, None, int(m.group(1)) if m else Image.MAX_IMAGE_PIXELS * 2 + 1
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as e:
            raise ImageError(f"cannot read image ({reason(e)})", where=str(path)) from None
    return int(h), int(w), int(h) * int(w)


def check_image_file(path, what: str, bound: int) -> tuple[int | None, int | None]:
    """Refuse an image file with more than ``bound`` texels (:mod:`warp_sg.core.watchdog`) from its
    header, before decoding it; returns its ``(H, W)``."""
    from warp_sg.core.watchdog import check_size

    h, w, n = image_size(path)
    check_size(what, n, bound, f"{w}×{h} texels" if h is not None else "larger than Pillow opens (a decompression bomb)",
               "texels", where=str(path), error=ImageError)
    return h, w


def is_hdr_file(path) -> bool:
    """``.hdr`` suffix or the Radiance signature ``#?`` (``#?RADIANCE``, ``#?RGBE``)."""
    path = Path(path)
    if path.suffix.lower() in HDR_EXTS:
        return True
    try:
        with open(path, "rb") as f:
            return f.read(2) == b"#?"
    except OSError:
        return False


def _write_ldr(tmp: str, a: np.ndarray, fmt: str, exposure: float) -> None:
    from PIL import Image

    c = a.shape[2]
    enc = np.empty_like(a)
    ncol = 1 if c == 1 else 3
    enc[..., :ncol] = tonemap_srgb(a[..., :ncol], exposure)
    if c == 4:
        enc[..., 3] = np.clip(np.nan_to_num(a[..., 3], nan=0.0), 0.0, 1.0)
    q = np.round(enc * 255.0).astype(np.uint8)
    if fmt == "JPEG" and c == 4:
        q = q[..., :3]
        c = 3
    mode = {1: "L", 3: "RGB", 4: "RGBA"}[c]
    im = Image.fromarray(q[..., 0] if c == 1 else q, mode=mode)
    kw = {"quality": 95} if fmt == "JPEG" else {}
    with open(tmp, "wb") as f:
        im.save(f, format=fmt, **kw)
        f.flush()
        os.fsync(f.fileno())


def save_image(path, img, exposure: float = 0.0, half: bool = False) -> Path:
    """Write ``img`` ((H,W) or (H,W,1|3|4) linear float) to ``path`` atomically; returns the path.

    ``.exr``: values as-is (float32, or float16 with ``half=True``). ``.hdr``: Radiance RGBE.
    ``.png``/``.jpg``: 8-bit
    sRGB after :func:`tonemap_srgb` with ``exposure`` stops. Errors: :class:`ImageError`.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in EXR_EXTS and ext not in LDR_EXTS and ext not in HDR_EXTS:
        raise ImageError(f"unknown image extension '{path.suffix}' (use .exr, .hdr, .png or .jpg)", where=str(path))
    a = _as_hwc(img, path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ImageError("output path is a folder", where=str(path))
    if not folder.is_dir():
        raise ImageError(f"folder '{folder}' does not exist", where=str(path))
    try:
        with atomic_output(path, suffix=f".tmp{ext}") as tmp:
            if ext in EXR_EXTS:
                _write_exr(tmp, a, half)
            elif ext in HDR_EXTS:
                _write_hdr(tmp, a)
            else:
                _write_ldr(tmp, a, LDR_EXTS[ext], exposure)
    except ImageError:
        raise
    except PermissionError as e:
        raise ImageError(f"cannot write to folder '{folder}' ({e.strerror or e})", where=str(path)) from None
    except Exception as e:  # noqa: BLE001  (any writer failure: one line naming the file)
        raise ImageError(f"cannot write image ({reason(e)})", where=str(path)) from None
    return path


# --------------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------------
def _exr_channels(path: Path) -> tuple[dict[str, np.ndarray], tuple[int, int]]:
    import OpenEXR

    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            chans = {name: np.asarray(ch.pixels) for name, ch in f.channels().items()}
    except Exception as e:  # noqa: BLE001  (any reader failure: one line naming the file)
        raise ImageError(f"cannot read OpenEXR file ({reason(e)})", where=str(path)) from None
    if not chans:
        raise ImageError("OpenEXR file has no channels", where=str(path))
    shapes = {c.shape for c in chans.values()}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ImageError(f"OpenEXR channels have differing or subsampled shapes {sorted(shapes)}", where=str(path))
    return chans, next(iter(shapes))


def read_exr(path) -> np.ndarray:
    """An OpenEXR file's pixels as ``(H, W, C)`` float32, as stored: channels R, G, B[, A] or
    Y[, A] (a single layer prefix such as ``diffuse.`` is stripped). Unreadable files, several
    layers or no usable channel set raise :class:`ImageError` naming the file."""
    path = Path(path)
    chans, _ = _exr_channels(path)
    # Strip a single layer prefix ("diffuse.R" -> "R").
    base = {}
    for name, px in chans.items():
        short = name.rsplit(".", 1)[-1]
        if short in base:
            raise ImageError(
                f"OpenEXR file has several layers ({', '.join(sorted(chans))}); expected one R,G,B[,A] or Y set",
                where=str(path),
            )
        base[short] = px
    found = ", ".join(sorted(chans))
    if all(k in base for k in "RGB"):
        order = ["R", "G", "B"] + (["A"] if "A" in base else [])
    elif "Y" in base:
        order = ["Y"] + (["A"] if "A" in base else [])
    else:
        raise ImageError(f"OpenEXR file has channels [{found}]; need R, G, B (or Y)", where=str(path))
    out = np.stack([np.asarray(base[k], dtype=np.float32) for k in order], axis=-1)
    return out


def exr_channel_names(path) -> list[str]:
    """The channel names stored in an OpenEXR file (for error messages / validation)."""
    chans, _ = _exr_channels(Path(path))
    return sorted(chans)


def _read_ldr(path: Path, linear: bool) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            im.load()
            mode = im.mode
            if mode in ("I;16", "I;16B", "I;16L", "I"):
                a = np.asarray(im, dtype=np.float64)
                a = (a / 65535.0)[..., None]
                alpha_idx = None
            else:
                if mode == "P":
                    im = im.convert("RGBA" if "transparency" in im.info else "RGB")
                elif mode in ("1", "LA", "L", "RGB", "RGBA"):
                    pass
                elif mode == "CMYK" or mode == "YCbCr" or mode.startswith("RGB"):
                    im = im.convert("RGB")
                elif mode == "F":
                    a = np.asarray(im, dtype=np.float32)[..., None]
                    return a
                else:
                    im = im.convert("RGBA")
                a = np.asarray(im)
                if a.dtype == bool:
                    a = a.astype(np.float64)
                else:
                    a = a.astype(np.float64) / 255.0
                if a.ndim == 2:
                    a = a[..., None]
                alpha_idx = 1 if im.mode == "LA" else (3 if im.mode == "RGBA" else None)
    except FileNotFoundError:
        raise ImageError("image file not found", where=str(path)) from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as e:
        raise ImageError(f"cannot read image ({reason(e)})", where=str(path)) from None
    a = a.astype(np.float32)
    if not linear:
        ncol = a.shape[2] - (1 if alpha_idx is not None else 0)
        a[..., :ncol] = srgb_to_linear(a[..., :ncol])
    return a


def _convert_channels(a: np.ndarray, channels: int | None, path: Path) -> np.ndarray:
    c = a.shape[2]
    if c == 2:  # grey + alpha
        if channels is None:
            return a
        a = a[..., :1]
        c = 1
    if channels is None or channels == c:
        return a
    if channels == 3:
        if c == 1:
            return np.repeat(a, 3, axis=2)
        if c == 4:
            return np.ascontiguousarray(a[..., :3])
    if channels == 1 and c in (3, 4):
        return (a[..., :3] @ LUMINANCE.astype(np.float32))[..., None].astype(np.float32)
    if channels == 4 and c == 3:
        return np.concatenate([a, np.ones_like(a[..., :1])], axis=2)
    raise ImageError(f"image has {c} channel(s), expected {channels}", where=str(path))


def load_image(path, *, linear: bool | None = None, channels: int | None = None) -> np.ndarray:
    """Read an image as ``(H, W, C)`` float32 linear values.

    EXR values are returned as stored. 8/16-bit formats are scaled to [0, 1] and, unless
    ``linear=True`` (data textures), sRGB-decoded (colour textures). ``channels`` (1, 3 or 4)
    converts grey↔RGB / drops alpha as documented in the module docstring. Unreadable files,
    missing files and unusable channel sets raise :class:`ImageError` naming the file.
    """
    path = Path(path)
    if not path.exists():
        raise ImageError("image file not found", where=str(path))
    if path.is_dir():
        raise ImageError("is a folder, not an image file", where=str(path))
    is_exr = path.suffix.lower() in EXR_EXTS
    if not is_exr:
        try:
            with open(path, "rb") as f:
                is_exr = f.read(4) == b"\x76\x2f\x31\x01"
        except OSError as e:
            raise ImageError(f"cannot open image ({e.strerror or e})", where=str(path)) from None
    if is_exr:
        a = read_exr(path)
    elif is_hdr_file(path):
        a = read_hdr(path)
    else:
        a = _read_ldr(path, bool(linear))
    if channels is not None and channels not in (1, 3, 4):
        raise ValueError(f"channels must be 1, 3, 4 or None, got {channels}")
    return np.ascontiguousarray(_convert_channels(a, channels, path), dtype=np.float32)


__all__ = [
    "save_image",
    "load_image",
    "tonemap_srgb",
    "linear_to_srgb",
    "srgb_to_linear",
    "exr_channel_names",
    "read_exr",
    "read_hdr",
    "is_hdr_file",
    "image_size",
    "check_image_file",
]

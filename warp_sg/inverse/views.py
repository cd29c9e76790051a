r"""The photographs a fit matches: a views file of ``[[views]]`` tables.

::

    [[views]]
    origin = [0.0, 0.3, 2.5]    # the camera, as a scene's [camera] table
    target = [0.0, 0.0, 0.0]
    up     = [0.0, 1.0, 0.0]    # (default)
    fov    = 30.0               # vertical, degrees
    width  = 256
    height = 256
    image  = "view_0.exr"       # linear RGB (EXR or Radiance .hdr), relative to the views file
    mask   = "view_0_mask.png"  # optional: pixels to match (> 0.5); default: every pixel that sees
                                # the object, less a one-pixel band along its silhouette

Every error names the file, the view and the key: a missing key, an unknown one, a camera the
scene's ``[camera]`` rules refuse, an image that cannot be read, whose size differs from its
camera's, or that has a pixel that is not a finite number (:class:`warp_sg.core.errors.InputError`;
the CLI's one line and exit status 2).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError
from warp_sg.scene.camera import Camera

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: the keys of a [[views]] table (camera keys as in a scene's [camera] table)
CAMERA_KEYS = ("origin", "target", "up", "fov", "width", "height", "near", "far")
KEYS = CAMERA_KEYS + ("image", "mask")


@dataclass
class View:
    """One photograph: its camera, its linear image (H, W, 3) and its mask (H, W) bool or None."""

    camera: Camera
    image: np.ndarray
    mask: np.ndarray | None
    name: str


def load_views(path) -> list[View]:
    """The views of a views file (module docstring); raises :class:`InputError` naming what is wrong."""
    from warp_sg.core.image_io import load_image

    path = Path(path)
    if not path.is_file():
        raise InputError("views file not found", where=str(path))
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"not a TOML file ({e})", where=str(path)) from None
    extra = sorted(set(doc) - {"views"})
    if extra:
        raise InputError(f"unknown table '{extra[0]}' (a views file has [[views]] tables only)", where=str(path))
    tables = doc.get("views")
    if not isinstance(tables, list) or not tables or not all(isinstance(t, dict) for t in tables):
        raise InputError("needs at least one [[views]] table", where=str(path))
    out = []
    for i, t in enumerate(tables):
        where = f"{path}: [[views]] #{i + 1}"
        bad = sorted(set(t) - set(KEYS))
        if bad:
            raise InputError(f"unknown key '{bad[0]}' (keys: {', '.join(KEYS)})", where=where)
        for k in ("origin", "target", "fov", "width", "height", "image"):
            if k not in t:
                raise InputError(f"missing key '{k}'", where=where)
        try:
            cam = Camera(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in t.items() if k in CAMERA_KEYS})
        except InputError as e:
            raise InputError(str(e), where=where) from None
        if not isinstance(t["image"], str):
            raise InputError("'image' must be a file path", where=where)
        img = load_image(path.parent / t["image"], channels=3)
        _check_image(img, cam, f"{where}: image '{t['image']}'")
        mask = None
        if "mask" in t:
            if not isinstance(t["mask"], str):
                raise InputError("'mask' must be a file path", where=where)
            m = load_image(path.parent / t["mask"], linear=True, channels=1)[..., 0]
            _check_size(m, cam, f"{where}: mask '{t['mask']}'")
            mask = m > 0.5
        out.append(View(cam, img, mask, f"view {i + 1}"))
    return out


def _check_size(a: np.ndarray, cam: Camera, where: str) -> None:
    if a.shape[:2] != (cam.height, cam.width):
        raise InputError(f"is {a.shape[1]}x{a.shape[0]} pixels, its camera {cam.width}x{cam.height}", where=where)


def _check_image(img: np.ndarray, cam: Camera, where: str) -> None:
    _check_size(img, cam, where)
    bad = ~np.isfinite(img)
    if bad.any():
        r, c, _ = np.argwhere(bad)[0]
        raise InputError(f"pixel (row {r}, column {c}) is {img[r, c].tolist()}: not a finite radiance", where=where)
    if (img < 0).any():
        r, c, _ = np.argwhere(img < 0)[0]
        raise InputError(f"pixel (row {r}, column {c}) is negative: not a radiance", where=where)


__all__ = ["View", "load_views", "KEYS", "CAMERA_KEYS"]

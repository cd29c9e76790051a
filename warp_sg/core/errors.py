"""Typed exceptions for bad input.

Every error a user can cause (a bad scene file, a corrupt mesh, a missing texture, an impossible
parameter) is raised as :class:`InputError` (or a subclass) with a message that names the file,
field or element at fault. The CLI turns these into one line on stderr and exit status 2.
Input that is accepted with a change is reported as an :class:`InputWarning` (one line).
This module imports nothing from the rest of the project so that ``raster`` and ``precompute``
can raise the same types.
"""
from __future__ import annotations


class InputError(ValueError):
    """Bad user input: the message names the file, key or element at fault."""

    def __init__(self, message: str, *, where: str | None = None):
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)


class SceneError(InputError):
    """A scene file or Scene object is invalid (unknown key, wrong type, missing file ...)."""


class MeshError(InputError):
    """A mesh is unusable (unreadable, NaN vertices, out-of-range or degenerate triangles ...)."""


class ImageError(InputError):
    """An image/texture/environment map cannot be read or has the wrong shape/channels."""


def reason(e: BaseException) -> str:
    """What went wrong in a library's exception, in words for a one-line message — never the
    exception's class name (``cannot identify image file`` is "not an image format this program
    reads"; an empty message is "unreadable")."""
    name = type(e).__name__
    if name == "UnidentifiedImageError":
        return "not an image format this program reads (PNG, JPEG, TIFF, WebP, OpenEXR, Radiance .hdr)"
    if isinstance(e, OSError) and getattr(e, "strerror", None):
        return str(e.strerror)
    text = str(e).strip().splitlines()[0] if str(e).strip() else ""
    if isinstance(e, (TimeoutError,)) or name.endswith("TimeoutError"):
        return "timed out" + (f": {text}" if text else "")
    return text.rstrip(".!") or "unreadable"


class InputWarning(UserWarning):
    """Input that is accepted but changed or doubtful (an inside-out mesh flipped, a material that
    reflects more light than it receives): one line naming the element; the CLI prints it as
    ``warp-sg: warning: ...``."""


class CacheError(RuntimeError):
    """A cache file is corrupt; callers rebuild instead of trusting it (never shown to users)."""

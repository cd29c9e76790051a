"""Warp initialisation and device selection, shared by warp_sg, raster and precompute.

Warp is initialised once per process (``wp.init`` is idempotent but costs time on first use);
compiled kernels are cached by Warp in its kernel cache, so a module is compiled once per machine.
"""
from __future__ import annotations

import contextlib
import functools
import sys

import warp as wp

from warp_sg.core.errors import InputError


def quiet_warp() -> None:
    """Keep Warp's banner and module-load lines off the terminal (errors still show)."""
    wp.config.log_level = getattr(wp, "LOG_ERROR", 40)  # Warp >= 1.19 (``config.quiet`` is gone)
    wp.config.quiet = True  # older Warp


#: what Warp's native library prints on stderr when it finds no CUDA driver (``wp.init``): said
#: instead in the one error of a CUDA device asked for (:func:`resolve_device`), never on a CPU run
_NO_DRIVER = "Could not find or load the NVIDIA CUDA driver"
_DRIVER_NOTE: list = []  # the driver's line, once wp.init() printed it


@contextlib.contextmanager
def _native_stderr_without(marker: str, seen: list):
    """Hold back the lines containing ``marker`` that native code writes to file descriptor 2
    meanwhile (:func:`warp_sg.core.native_stderr.native_stderr`), appended to ``seen``; every other
    line is written through afterwards."""
    from warp_sg.core.native_stderr import native_stderr

    lines: list = []
    try:
        with native_stderr(lines):
            yield
    finally:
        kept = [ln for ln in lines if marker not in ln]
        seen.extend(ln.strip() for ln in lines if marker in ln)
        if kept:
            sys.stderr.write("".join(ln + "\n" for ln in kept))
            sys.stderr.flush()


@functools.lru_cache(maxsize=None)
def _init() -> None:
    """``wp.init()`` once, quiet: no banner, and no CUDA-driver warning on a machine without a GPU
    (a CPU user can do nothing about it; a CUDA device asked for is one error that says it)."""
    quiet_warp()
    with _native_stderr_without(_NO_DRIVER, _DRIVER_NOTE):
        wp.init()


#: The device when neither ``--device`` nor the scene's ``[render] device`` names one.
DEFAULT_DEVICE = "cpu"


def add_device_argument(parser, *, scene: bool = True) -> None:
    """``--device`` with the same default in every ``warp-sg`` subcommand: the scene's ``[render]
    device`` (itself ``cpu`` unless the scene sets it); without a scene (``bench``) ``cpu``."""
    default = ("the scene's [render] device, which is cpu unless the scene sets it" if scene
               else f"{DEFAULT_DEVICE}, the default [render] device")
    parser.add_argument("--device", default=None, help=f"cpu, cuda, cuda:N or auto (default: {default})")


def device_for(device, scene=None) -> str:
    """``device`` (a ``--device`` value) if given, else ``scene``'s ``[render] device``, else
    :data:`DEFAULT_DEVICE`."""
    if device is not None:
        return device
    name = getattr(getattr(scene, "render", None), "device", None)
    if name is None:
        return DEFAULT_DEVICE
    # the scene's choice: a refusal by resolve_device names the scene key, not --device (not given)
    return SceneDevice(name, f"{getattr(scene, 'path', None) or 'scene'}: [render] device")


class SceneDevice(str):
    """A device name chosen by a scene's ``[render] device`` (``where``: that key, for refusals)."""

    def __new__(cls, name: str, where: str = "[render] device"):
        s = super().__new__(cls, name)
        s.where = where
        return s


def cuda_available() -> bool:
    _init()
    return wp.get_cuda_device_count() > 0


def resolve_device(device: str | None = "cpu", where: str | None = None) -> str:
    """Map ``"cpu" | "cuda" | "cuda:N" | "auto" | None`` to a Warp device name.

    ``auto`` (and ``None``) picks CUDA when present, else the CPU. Asking for CUDA on a machine
    without it is an :class:`InputError` (CUDA is never required) naming ``where`` the choice came
    from (``--device``, or a scene's ``[render] device``).
    """
    _init()
    where = where or getattr(device, "where", None) or "--device"
    if device is None or device == "auto":
        return "cuda:0" if cuda_available() else "cpu"
    if isinstance(device, wp.Device):
        return device.alias
    name = str(device)
    if name == "cpu":
        return "cpu"
    if name.startswith("cuda"):
        if not cuda_available():
            why = " (the NVIDIA CUDA driver could not be loaded)" if _DRIVER_NOTE else ""
            raise InputError(f"device '{name}' requested but no CUDA device is available{why}", where=where)
        return "cuda:0" if name == "cuda" else name
    raise InputError(f"unknown device '{name}' (use cpu, cuda, cuda:N or auto)", where=where)


def device_table(cache: dict, build, device="cpu") -> wp.array:
    """A constant 2-D float table as a ``wp.array`` on ``device``, built once per device:
    ``cache`` maps device names to arrays, ``build()`` returns the numpy table."""
    dev = resolve_device(device)
    arr = cache.get(dev)
    if arr is None:
        arr = wp.array(build(), dtype=float, device=dev)
        cache[dev] = arr
    return arr

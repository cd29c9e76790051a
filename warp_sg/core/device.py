"""Warp initialisation and device selection, shared by warp_sg, raster and precompute.

Warp is initialised once per process (``wp.init`` is idempotent but costs time on first use);
compiled kernels are cached by Warp in its kernel cache, so a module is compiled once per machine.
"""
from __future__ import annotations

import functools

import warp as wp

from warp_sg.core.errors import InputError


def quiet_warp() -> None:
    """Keep Warp's banner and module-load lines off the terminal (errors still show)."""
    wp.config.log_level = getattr(wp, "LOG_ERROR", 40)  # Warp >= 1.19 (``config.quiet`` is gone)
    wp.config.quiet = True  # older Warp


@functools.lru_cache(maxsize=None)
def _init() -> None:
    quiet_warp()
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
    return getattr(getattr(scene, "render", None), "device", None) or DEFAULT_DEVICE


def cuda_available() -> bool:
    _init()
    return wp.get_cuda_device_count() > 0


def resolve_device(device: str | None = "cpu") -> str:
    """Map ``"cpu" | "cuda" | "cuda:N" | "auto" | None`` to a Warp device name.

    ``auto`` (and ``None``) picks CUDA when present, else the CPU. Asking for CUDA on a machine
    without it is an :class:`InputError` (CUDA is never required).
    """
    _init()
    if device is None or device == "auto":
        return "cuda:0" if cuda_available() else "cpu"
    if isinstance(device, wp.Device):
        return device.alias
    name = str(device)
    if name == "cpu":
        return "cpu"
    if name.startswith("cuda"):
        if not cuda_available():
            raise InputError(f"device '{name}' requested but no CUDA device is available", where="--device")
        return "cuda:0" if name == "cuda" else name
    raise InputError(f"unknown device '{name}' (use cpu, cuda, cuda:N or auto)", where="--device")


def device_table(cache: dict, build, device="cpu") -> wp.array:
    """A constant 2-D float table as a ``wp.array`` on ``device``, built once per device:
    ``cache`` maps device names to arrays, ``build()`` returns the numpy table."""
    dev = resolve_device(device)
    arr = cache.get(dev)
    if arr is None:
        arr = wp.array(build(), dtype=float, device=dev)
        cache[dev] = arr
    return arr

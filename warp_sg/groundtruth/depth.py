r"""How deep the reference's paths go, and the SG render it is compared with.

``max_depth`` counts a path's segments as Mitsuba 3's ``path`` integrator does
(:mod:`warp_sg.groundtruth.path_wp`): 1 = what the camera sees emit, 2 = direct light only (the
paper's transport, the renderer's ``[render] bounces = 0``), ``2 + n`` = n indirect bounces, −1 = no
cap; the default :data:`DEFAULT_MAX_DEPTH` is a full path tracer's.
"""
from __future__ import annotations

from warp_sg.core.errors import InputError
from warp_sg.groundtruth.path_wp import DEFAULT_MAX_DEPTH


def check_max_depth(max_depth, where: str = "max_depth") -> int:
    """``max_depth`` as an int: −1 (no cap) or ≥ 1 (1: emission and background only, 2: direct light
    only, 2 + n: n indirect bounces); anything else is an :class:`InputError`."""
    try:
        d = int(max_depth)
    except (TypeError, ValueError):
        raise InputError(f"must be an integer (-1 or >= 1), got {max_depth!r}", where=where) from None
    if d != max_depth or not (d == -1 or d >= 1):
        raise InputError(f"must be -1 (no cap) or >= 1 (2: direct light only), got {max_depth!r}", where=where)
    return d


def matching_transport(scene, max_depth):
    """``scene`` as the SG renderer should render it to be compared with a reference of paths of
    ``max_depth`` segments: at 2 (direct light only, the paper's transport) a copy with ``[render]
    bounces = 0``, otherwise ``scene`` itself (its bounces against the full path tracer)."""
    import copy

    if check_max_depth(max_depth) != 2 or scene.render.bounces == 0:
        return scene
    sc = copy.deepcopy(scene)
    sc.render.bounces = 0
    return sc


__all__ = ["check_max_depth", "matching_transport", "DEFAULT_MAX_DEPTH"]

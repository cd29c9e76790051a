"""Samples per pixel of a Monte-Carlo error curve at a target error (the equal-error benchmarks)."""
from __future__ import annotations

import math


def spp_for_error(curve, target):
    """Samples per pixel at which the MC error curve [(spp, rel_mse, seconds)] reaches ``target``
    (log-log interpolation; extrapolated with slope −1 past the last point). Returns (spp, seconds)."""
    curve = sorted(curve)
    for (s0, e0, t0), (s1, e1, t1) in zip(curve, curve[1:]):
        if e1 <= target <= e0 and e0 > e1 > 0:
            f = (math.log(e0) - math.log(target)) / (math.log(e0) - math.log(e1))
            spp = math.exp(math.log(s0) + f * (math.log(s1) - math.log(s0)))
            return spp, t0 + (t1 - t0) * (spp - s0) / (s1 - s0)
    s, e, t = curve[-1]
    if target >= curve[0][1]:
        return curve[0][0], curve[0][2]
    spp = s * e / target  # MC: error ∝ 1/spp
    return spp, t * spp / s


__all__ = ["spp_for_error"]

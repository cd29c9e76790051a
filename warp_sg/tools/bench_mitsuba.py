r"""Section 6 of ``warp-sg bench`` (:mod:`warp_sg.tools.bench`): equal error against Mitsuba 3, with the
optional ``[compare]`` extra, on the scenes and truths of the equal-error section."""
from __future__ import annotations

from warp_sg.tools.bench import _depth, _equal_error_case, _equal_error_scenes, _net_of_floor
from warp_sg.tools.spp_curve import spp_for_error


def mitsuba_section(device="cpu", quick=False, truth_spp=None, progress=False):
    """Equal error against Mitsuba 3 (``warp_sg.tools.peer_mitsuba``; optional ``[compare]`` extra) on
    the scenes of :func:`equal_error_section` that Mitsuba renders identically, with the same
    metric, one truth per scene for all three renderers, and the same SG frames. The truth has 8×
    the samples of the MC section's (our error is now close to a 1024-spp truth's own noise), and
    every error is taken net of the truth's noise floor before the log-log interpolation; Mitsuba
    renders 1, 2, 4, … spp until its error is below ours (at most 4096)."""
    from warp_sg.tools import peer_mitsuba as pm

    ok, status = pm.mitsuba_status(device)
    if not ok:
        return [{"case": "Mitsuba 3", "note": f"skipped: {status}"}]
    truth_spp = truth_spp or (256 if quick else 8192)
    rows, top = [], 1
    for label, scene, seed in _equal_error_scenes(quick, mitsuba=True):
        c = _equal_error_case(scene, label, device, quick, truth_spp, progress, seed)
        err, floor, frame = c["err"]["rel_mse"], c["floor"], c["frame"]
        curve = pm.mitsuba_curve(scene, c["truth"].image, device=device, seed=seed, repeats=1 if quick else 3,
                                 stop_below=err, max_spp=16 if quick else 4096, progress=progress,
                                 max_depth=_depth())
        top = max(top, curve[-1][0])
        row = {"case": label, "rel_mse": err, "truth_floor": floor, "frame_s": frame}
        if err - floor < 0.25 * floor:
            rows.append({**row, "note": f"our error is within the {truth_spp}-spp truth's noise: raise truth_spp"})
            continue
        m_spp, m_t = spp_for_error(_net_of_floor(curve, floor), err - floor)
        mc_spp, mc_t = spp_for_error(_net_of_floor(c["curve"], floor), err - floor)
        note = (f"Mitsuba at {curve[0][0]} spp is already below our error" if curve[0][1] <= err else
                f"extrapolated past {curve[-1][0]} spp" if curve[-1][1] > err else "")
        rows.append({**row, "mitsuba_spp": m_spp, "mitsuba_s": m_t, "mitsuba_ratio": m_t / frame, "mc_spp": mc_spp,
                     "mc_s": mc_t, "mc_ratio": mc_t / frame, "note": note})
    return rows + [{"case": "setup", "note": f"{status}; path tracer max_depth={_depth()}, box filter, "
                                             f"1–{top} spp, scene load excluded; truth {truth_spp} spp"}]


__all__ = ["mitsuba_section"]

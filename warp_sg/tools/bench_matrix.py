r"""``warp-sg bench`` section "equal error vs Mitsuba 3, every model": the warm frame of the SG renderer
against the time Mitsuba 3 needs to reach the same error, per BRDF model of the accuracy matrix.

One scene per model (:data:`MODEL_CASES`: the matrix's sphere on a two-triangle floor under its
sun-sky EXR, :mod:`warp_sg.groundtruth.accuracy_matrix`) at 512² (quick: 32², three models). Mitsuba
renders it with the independent peer (:mod:`warp_sg.tools.mitsuba`: the model from its published
formula, ``path`` with ``max_depth = 2``, box filter) in ``B`` independent batches of ``b`` samples
per pixel; no high-sample truth is needed, because Mitsuba is an unbiased estimator whose error
falls exactly as 1/spp:

* ``M`` = the batches' mean, ``σ²_b`` (per pixel) their variance, so one sample per pixel has
  variance ``b σ²_b`` and M's own noise is ``σ²_b / B``;
* our error net of M's noise: ``e = (Σ(x − M)² − Σσ²_b/B) / ΣM²`` (what ``Σ(x − truth)²/Σtruth²``
  is in expectation);
* Mitsuba reaches ``e`` at ``N = Σ b σ²_b / (e ΣM²)`` samples per pixel, in ``N · t₁`` seconds (``t₁``
  its warm time per sample per pixel, the median batch's; scene loading excluded, as our precompute
  is); ratio = ``N t₁`` / our warm frame.

More batches are rendered until our error stands out of M's noise (``e > ¼`` of it) or 4096 samples
per pixel; where it still does not, the row says so and uses that noise as an upper bound of ``e`` (a
lower bound of the ratio). Mitsuba's ``llvm_ad_rgb`` variant is used where
a system libLLVM lets it run (Debian: ``libllvm19``), else ``scalar_rgb`` at the quick size only.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

#: one matrix scene per BRDF model (medium roughness)
MODEL_CASES = ("sphere-sunsky-lambert", "sphere-sunsky-oren_nayar_0.3", "sphere-sunsky-phong_60",
               "sphere-sunsky-blinn_phong_50", "sphere-sunsky-cook_torrance_0.25",
               "sphere-sunsky-torrance_sparrow_0.35", "sphere-sunsky-ward_0.2", "sphere-sunsky-ward_aniso",
               "sphere-sunsky-ashikhmin_shirley_aniso", "sphere-sunsky-lafortune_mirror",
               "sphere-sunsky-ggx_gold_0.3", "sphere-sunsky-ggx_dielectric_0.4", "sphere-sunsky-ggx_aniso",
               "sphere-sunsky-measured")
QUICK_CASES = ("sphere-sunsky-lambert", "sphere-sunsky-blinn_phong_50", "sphere-sunsky-ggx_gold_0.3")


def _variant(quick: bool) -> str | None:
    """The Mitsuba variant to time with (None: none usable at this size)."""
    from warp_sg.tools.mitsuba.render import set_fastest_variant

    v = set_fastest_variant()  # (llvm_ad_rgb where a recent enough system libLLVM runs it)
    return v if v.startswith("llvm") or quick else None


def equal_error_row(case_name: str, size: int, batches: int, spp: int, device: str = "cpu",
                    max_spp: int = 4096) -> dict:
    """One model's row (module docstring); batches are added ``batches`` at a time until our error
    stands out of the reference's noise or ``max_spp`` samples per pixel."""
    import mitsuba as mi

    from warp_sg.core.workers import cpu_workers
    from warp_sg.groundtruth import accuracy_matrix as AM
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.tools.mitsuba.scene_dict import independent_scene_dict

    case = replace(AM.BY_NAME[case_name], size=size)
    with tempfile.TemporaryDirectory() as tmp:
        scene, _ = AM.load_case(case, Path(tmp))
        r = Renderer(scene, device=device)
        img = r.render().astype(np.float64)
        frames = []
        for _ in range(3):
            t0 = time.perf_counter()
            r.render()
            frames.append(time.perf_counter() - t0)
        frame = statistics.median(frames)
        if mi.variant().startswith("llvm"):
            import drjit as dr

            dr.set_thread_count(cpu_workers(device))
        msc = mi.load_dict(independent_scene_dict(scene, spp=spp))
    mi.render(msc, spp=1, seed=99_999)  # warm-up: kernel compilation / cache load
    imgs, secs = [], []
    while True:  # more batches until our error stands out of the mean's noise (or max_spp)
        for b in range(len(imgs), len(imgs) + batches):
            t0 = time.perf_counter()
            imgs.append(np.array(mi.render(msc, spp=spp, seed=7919 * b + 1), dtype=np.float64))
            secs.append(time.perf_counter() - t0)
        stack = np.stack(imgs)
        mean = stack.mean(0)
        var_b = stack.var(0, ddof=1)  # per pixel, one batch of spp samples
        sum_r2 = float(np.sum(mean ** 2))
        noise = float(np.sum(var_b)) / len(imgs) / sum_r2  # the mean's own rel. MSE
        e = (float(np.sum((img - mean) ** 2)) / sum_r2) - noise
        resolved = e > 0.25 * noise
        if resolved or (len(imgs) + batches) * spp > max_spp:
            break
    e_used = e if resolved else noise
    per_spp = float(np.sum(var_b)) * spp / sum_r2  # rel. MSE of one sample per pixel
    n_eq = per_spp / e_used
    t1 = statistics.median(secs) / spp
    total = len(imgs) * spp
    row = {"case": case_name.replace("sphere-sunsky-", ""), "frame_s": frame, "rel_mse": e_used,
           "reference_spp": total, "mitsuba_spp": n_eq, "mitsuba_s": n_eq * t1, "ratio": n_eq * t1 / frame,
           "note": "" if resolved else f"our error is below the {total}-spp reference's noise: ratio ≥"}
    return row


def matrix_equal_error_section(device="cpu", quick=False, progress=False):
    """The section's rows (module docstring), one per model."""
    try:
        import mitsuba as mi
    except ImportError as e:
        return [{"case": "Mitsuba 3", "note": f"skipped: mitsuba not importable ({e})"}]
    variant = _variant(quick)
    if variant is None:
        return [{"case": "Mitsuba 3", "note": "skipped: its llvm_ad_rgb variant needs a system libLLVM "
                                              "(Debian: apt install libllvm19); scalar_rgb is timed at --quick size"}]
    size, batches, spp, cap = (32, 3, 4, 12) if quick else (512, 8, 32, 4096)
    names = QUICK_CASES if quick else MODEL_CASES
    rows = []
    it = names
    if progress:
        from tqdm.auto import tqdm

        it = tqdm(names, desc="equal error vs Mitsuba", unit="model", leave=False)
    for n in it:
        rows.append(equal_error_row(n, size, batches, spp, device, max_spp=cap))
    return rows + [{"case": "setup", "note": f"mitsuba {mi.__version__} {variant}, {size}², batches of {spp} spp "
                                             f"until our error is resolved (at most {cap}), "
                                             "path max_depth=2, box filter; ratio = Mitsuba's time at our error / "
                                             "our warm frame"}]


__all__ = ["matrix_equal_error_section", "equal_error_row", "MODEL_CASES", "QUICK_CASES"]

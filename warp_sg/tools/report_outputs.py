r"""The files of the error-vs-run-time report (:mod:`warp_sg.tools.report`): the Markdown table,
the error-vs-time plot, the image comparison, the CSV of the rows and ``report.json``.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from warp_sg.core.files import atomic_output

#: the columns of the report's CSV
CSV_FIELDS = ["knob", "value", "precompute_s", "frame_s", "total_s", "rel_mse", "psnr_db", "max_err", "spp"]


def _fmt(v):
    if isinstance(v, float):
        if v == 0:
            return "0"
        if math.isinf(v):
            return "inf"
        return f"{v:.4g}"
    return str(v)


def markdown_table(rows) -> str:
    head = "| knob | value | precompute (s) | frame (s) | rel. MSE | PSNR (dB) | max err |"
    sep = "|---|---|---:|---:|---:|---:|---:|"
    lines = [head, sep]
    for r in rows:
        lines.append(f"| {r['knob']} | {r['value']} | {_fmt(r['precompute_s'])} | {_fmt(r['frame_s'])} | "
                     f"{_fmt(r['rel_mse'])} | {_fmt(r['psnr_db'])} | {_fmt(r['max_err'])} |")
    return "\n".join(lines) + "\n"


def _atomic_write_text(path: Path, text: str):
    with atomic_output(path) as tmp:
        Path(tmp).write_text(text)


def _save_figure(fig, path) -> None:
    """``fig.savefig`` atomically (the format follows ``path``'s suffix); closes the figure."""
    import matplotlib.pyplot as plt

    try:
        with atomic_output(path, suffix=Path(path).suffix) as tmp:
            fig.savefig(tmp)
    finally:
        plt.close(fig)


def plot_error_vs_time(rows, path, floor=None, metric="rel_mse", time_key=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=80)
    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(r["knob"], []).append(r)
    for knob, rs in groups.items():
        tk = time_key or "frame_s"
        xs = np.array([max(float(r[tk]), 1e-6) for r in rs])
        ys = np.array([max(float(r[metric]), 1e-12) if metric == "rel_mse" else float(r[metric]) for r in rs])
        if knob == "mc_reference":
            ax.plot(xs, ys, "k-o", lw=2, ms=4, label="MC reference (spp 1→)")
            for x, y, r in zip(xs, ys, rs):
                ax.annotate(str(r["value"]), (x, y), fontsize=6, xytext=(2, 2), textcoords="offset points")
        elif knob == "default":
            ax.plot(xs, ys, "r*", ms=12, label="renderer (scene settings)")
        else:
            ax.plot(xs, ys, "-s", ms=4, label=knob)
            for x, y, r in zip(xs, ys, rs):
                ax.annotate(str(r["value"]), (x, y), fontsize=6, xytext=(2, -7), textcoords="offset points")
    if floor and metric == "rel_mse" and floor > 0:
        ax.axhline(floor, color="gray", ls=":", lw=1, label="ground-truth noise floor")
    ax.set_xscale("log")
    if metric == "rel_mse":
        ax.set_yscale("log")
    ax.set_xlabel("time per frame (s)  [MC: total time]")
    ax.set_ylabel({"rel_mse": "relative MSE", "psnr_db": "PSNR (dB, tone-mapped)", "max_err": "max error"}[metric])
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    _save_figure(fig, path)


def plot_images(truth, img, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from warp_sg.core.image_io import tonemap_srgb

    n = 3 if img is not None else 1
    fig, axs = plt.subplots(1, n, figsize=(2.6 * n, 2.8), dpi=80)
    axs = np.atleast_1d(axs)
    axs[0].imshow(tonemap_srgb(truth))
    axs[0].set_title("MC ground truth", fontsize=8)
    if img is not None:
        axs[1].imshow(tonemap_srgb(img))
        axs[1].set_title("SG renderer", fontsize=8)
        d = np.abs(np.asarray(img, np.float64) - truth).mean(-1)
        im = axs[2].imshow(d, cmap="magma")
        axs[2].set_title("|difference|", fontsize=8)
        fig.colorbar(im, ax=axs[2], fraction=0.046)
    for a in axs:
        a.axis("off")
    fig.tight_layout()
    _save_figure(fig, path)


def write_rows_csv(out: Path, rows) -> Path:
    """``report.csv`` of the rows so far (rewritten atomically: readers see whole files)."""
    p = Path(out) / "report.csv"
    with atomic_output(p) as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in CSV_FIELDS})
    return p


def write_outputs(out: Path, rows, truth, base_img, truth_spp, floor, truth_time, scene=None, k_truth=1,
                  regions=None, truth_label: str | None = None) -> dict:
    files = {"csv": write_rows_csv(out, rows)}
    plot_error_vs_time(rows, out / "error_vs_time.png", floor)
    files["plot"] = out / "error_vs_time.png"
    plot_error_vs_time(rows, out / "psnr_vs_time.png", metric="psnr_db")
    files["plot_psnr"] = out / "psnr_vs_time.png"
    plot_images(truth, base_img, out / "images.png")
    files["images"] = out / "images.png"
    h, w = truth.shape[:2]
    mc = [r for r in rows if r["knob"] == "mc_reference"]
    base = [r for r in rows if r["knob"] == "default"]
    lines = ["# Error against run time", ""]
    name = getattr(scene, "path", None) or getattr(scene, "name", None)
    if name:
        lines += [f"Scene: `{name}`, {w}×{h} pixels.", ""]
    else:
        lines += [f"Image: {w}×{h} pixels.", ""]
    source = truth_label or (f"Monte-Carlo reference with {truth_spp} samples per pixel "
                              f"({truth_spp // (k_truth * k_truth)} per sub-pixel of a {k_truth}×{k_truth} grid)")
    lines += [
        f"Ground truth: {source} "
        f"({truth_time:.1f} s); its noise floor (Σ stderr² / Σ ref²) is {floor:.3g} in relative MSE. "
        f"The MC curve is an independent progressive run at the same supersampling.",
        "Precompute times are those of an empty cache with the stages one after the other (each stage built "
        "once and reused by the settings that do not change it, counted at its build time); frame times "
        "are the median of warm frames.",
        "",
    ]
    if base and mc:
        b = base[0]
        better = [r for r in mc if r["rel_mse"] <= b["rel_mse"]]
        if better:
            r = better[0]
            lines += [f"The renderer at the scene's settings (rel. MSE {b['rel_mse']:.3g}, {b['frame_s']:.3g} s/frame) "
                      f"is matched by the MC reference at {r['value']} spp ({r['total_s']:.3g} s): "
                      f"{r['total_s'] / max(b['frame_s'], 1e-9):.3g}× the renderer's frame time.", ""]
        else:
            r = mc[-1]
            lines += [f"The renderer at the scene's settings (rel. MSE {b['rel_mse']:.3g}, {b['frame_s']:.3g} s/frame) "
                      f"is more accurate than the MC reference at {r['value']} spp ({r['total_s']:.3g} s, "
                      f"rel. MSE {r['rel_mse']:.3g}).", ""]
    if regions:
        from warp_sg.groundtruth.region_error import format_region_table

        lines += ["## Error by region (scene's settings)", "",
                  "Bias = mean(render)/mean(reference) − 1 (worst channel); off by >3× = fraction of the "
                  "region's pixels whose luminance is off by more than 3× (`warp_sg.groundtruth.region_error`).", "",
                  format_region_table(regions), ""]
    lines += ["![error vs time](error_vs_time.png)", "", "![PSNR vs time](psnr_vs_time.png)", "",
              "![images](images.png)", "", "## All measurements", "", markdown_table(rows)]
    _atomic_write_text(out / "report.md", "\n".join(lines))
    files["markdown"] = out / "report.md"
    meta = {"truth_spp": truth_spp, "noise_floor_rel_mse": floor, "truth_seconds": truth_time,
            "width": int(w), "height": int(h), "rows": rows, "regions": regions}
    _atomic_write_text(out / "report.json", json.dumps(meta, indent=1, default=str))
    files["json"] = out / "report.json"
    return files


__all__ = ["markdown_table", "plot_error_vs_time", "plot_images", "write_rows_csv", "write_outputs", "CSV_FIELDS"]

r"""Precompute benchmark (supplement Fig. 7).

The test scenes (:func:`plane_box_scene`, :func:`bowl_scene`) and the brute-force reference of the
SSDF product (:func:`sg_visibility_reference`, :func:`product_error`) are
:mod:`precompute.visibility.reference_checks`, imported here under their old names.

* :func:`bench_mesh`: a plane-and-box mesh of a given size.
* :func:`run_bench`: precompute time vs mesh size and vs SSDF resolution with the product error of
  each setting; writes ``docs/precompute.md`` tables (between markers) and ``docs/figures/ssdf_*``.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from precompute.visibility.reference_checks import (  # noqa: F401
    bowl_scene,
    plane_box_scene,
    product_error,
    sample_sg,
    sg_visibility_reference,
)
from precompute.visibility.ssdf_wp import lookup_np

ROOT = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------------------------------------
# scenes
# ---------------------------------------------------------------------------------------------

def bench_mesh(target_vertices: int):
    """A plane-and-box scene with about ``target_vertices`` vertices."""
    n = max(4, int(round(math.sqrt(max(target_vertices - 8, 16)))))
    return plane_box_scene(n)


# ---------------------------------------------------------------------------------------------
# the benchmark
# ---------------------------------------------------------------------------------------------

def _near_box_floor_ids(V, count: int = 12, lo: float = 0.55, hi: float = 1.3):
    """Floor vertices (y = 0, normal +y) in a ring around the cube: where shadows are."""
    r = np.maximum(np.abs(V[:, 0]), np.abs(V[:, 2]))
    cand = np.flatnonzero((np.abs(V[:, 1]) < 1e-9) & (r > lo) & (r < hi))
    return cand[np.linspace(0, len(cand) - 1, min(count, len(cand))).astype(int)]


def ssdf_error(V, F, N, ids, images, truth, n_dirs: int = 4000, seed: int = 0):
    """Mean |SSDF − truth| (rad) at random upper-hemisphere directions with |truth| < 0.3 rad."""
    rng = np.random.default_rng(seed)
    z = rng.random(n_dirs)
    phi = rng.random(n_dirs) * 2 * np.pi
    r = np.sqrt(1 - z * z)
    loc = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
    errs = []
    for k in range(len(ids)):
        a = lookup_np(images[k], loc)
        b = lookup_np(truth[k], loc)
        m = np.abs(b) < 0.3
        errs.append(np.abs(a - b)[m])
    return float(np.concatenate(errs).mean())


def _time(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def run_bench(quick: bool = False, device="cpu", out_doc: str | Path | None = None,
              fig_dir: str | Path | None = None, progress: bool = True) -> dict:
    """Precompute time vs mesh size and vs SSDF resolution, with the SSDF-product error of each.

    Writes ``docs/figures/ssdf_bench.{json,png}``, ``docs/figures/ssdf_product_error.{csv,png}`` and
    the tables between the ``<!-- bench:begin -->`` / ``<!-- bench:end -->`` markers of
    ``docs/precompute.md``. ``quick`` uses small meshes (CI-sized)."""
    from precompute.visibility import ssdf as S
    from warp_sg.numeric.pca import pca

    fig_dir = Path(fig_dir) if fig_dir else ROOT / "docs" / "figures"
    out_doc = Path(out_doc) if out_doc else ROOT / "docs" / "precompute.md"
    fig_dir.mkdir(parents=True, exist_ok=True)
    lams_err = np.array([0.5, 2.0, 10.0, 100.0, 1000.0])
    sizes = [300, 1000] if quick else [1000, 10000, 50000]
    settings = [(16, 32), (32, 32), (32, 64), (64, 128)] if quick else \
        [(16, 32), (32, 32), (32, 64), (32, 128), (64, 64), (64, 128), (128, 256)]
    default = (S.DEFAULT_RESOLUTION, S.DEFAULT_RAY_RESOLUTION, S.DEFAULT_PCA_TERMS)
    n_axes, samples = (12, 256) if quick else (32, 1024)
    results = {"device": device, "quick": quick, "default": default, "sizes": [], "resolutions": [],
               "lams": lams_err.tolist()}
    S.compute_ssdf(*plane_box_scene(4), vertex_ids=[0], progress=False, device=device)  # compile first

    # 1. mesh size at default quality
    for target in sizes:
        V, F, N = bench_mesh(target)
        X, t_ssdf = _time(lambda: S.compute_ssdf(V, F, N, resolution=default[0], ray_resolution=default[1],
                                                 device=device, progress=progress))
        p, t_pca = _time(lambda: pca(X.reshape(len(V), -1), default[2]))
        ids = _near_box_floor_ids(V)
        rec = p.reconstruct(ids).reshape(len(ids), default[0], default[0])
        err = product_error(V, F, N, rec, ids, lams_err, n_axes=n_axes, samples=samples, device=device)
        row = {"vertices": len(V), "triangles": len(F), "t_ssdf": t_ssdf, "t_pca": t_pca,
               "pca_rms": float(p.rms_error[-1]), "product_err": err["mean"].tolist()}
        results["sizes"].append(row)
        print(f"[bench] {len(V)} vertices: SSDF {t_ssdf:.1f}s PCA {t_pca:.1f}s", flush=True)

    # 2. resolution on a small mesh (errors vs a 256² exhaustive-resolution truth)
    V, F, N = bench_mesh(300 if quick else 2000)
    ids = _near_box_floor_ids(V)
    truth = S.compute_ssdf(V, F, N, resolution=256, ray_resolution=256, vertex_ids=ids, device=device,
                           progress=False)
    for R, Rr in settings:
        X, t = _time(lambda: S.compute_ssdf(V, F, N, resolution=R, ray_resolution=Rr, device=device,
                                            progress=progress))
        Xf = X.reshape(len(V), -1)
        p = pca(Xf, 48)
        sub = X[ids]
        row = {"resolution": R, "ray_resolution": Rr, "vertices": len(V), "t_ssdf": t,
               "ms_per_vertex": 1e3 * t / len(V),
               "ssdf_err": ssdf_error(V, F, N, ids, sub, truth),
               "pca_rms": {str(k): float(p.rms_error[k]) for k in (8, 16, 24, 32, 48)},
               "product_err": product_error(V, F, N, sub, ids, lams_err, n_axes=n_axes, samples=samples,
                                            device=device, select_with=truth)["mean"].tolist(),
               "product_err_pca24": product_error(
                   V, F, N, (p.mean + p.weights[ids, :24] @ p.basis[:24]).reshape(len(ids), R, R),
                   ids, lams_err, n_axes=n_axes, samples=samples, device=device,
                   select_with=truth)["mean"].tolist()}
        results["resolutions"].append(row)
        print(f"[bench] {R}²/{Rr}²: {row['ms_per_vertex']:.2f} ms/vertex, SSDF err {row['ssdf_err']:.4f}", flush=True)

    # 2b. number of PCA terms at the default resolution (same mesh and axes)
    X = S.compute_ssdf(V, F, N, resolution=default[0], ray_resolution=default[1], device=device, progress=False)
    p = pca(X.reshape(len(V), -1), 96)
    results["pca_terms"] = []
    for k in (8, 16, 24, 32, 48, 64, 96):
        rec = (p.mean + p.weights[ids, :k] @ p.basis[:k]).reshape(len(ids), default[0], default[0])
        e = product_error(V, F, N, rec, ids, lams_err, n_axes=n_axes, samples=samples, device=device,
                          select_with=truth)["mean"]
        results["pca_terms"].append({"terms": k, "pca_rms": float(p.rms_error[k]), "product_err": e.tolist()})
    results["pca_terms"].append({"terms": "none", "pca_rms": 0.0, "product_err": product_error(
        V, F, N, X[ids], ids, lams_err, n_axes=n_axes, samples=samples, device=device,
        select_with=truth)["mean"].tolist()})

    # 3. product error curve (supplement Fig. 7 analogue)
    lams_curve = np.geomspace(0.5, 1000, 12)
    curve = {"lam": lams_curve}
    for R, Rr in [(16, 32), (32, 64), (64, 128)]:
        X = S.compute_ssdf(V, F, N, resolution=R, ray_resolution=Rr, vertex_ids=ids, device=device, progress=False)
        curve[f"ssdf{R}"] = product_error(V, F, N, X, ids, lams_curve, n_axes=n_axes, samples=samples,
                                          device=device, select_with=truth)["mean"]
    curve["ssdf256"] = product_error(V, F, N, truth, ids, lams_curve, n_axes=n_axes, samples=samples,
                                     device=device)["mean"]
    results["curve"] = {k: np.asarray(v).tolist() for k, v in curve.items()}

    tag = "_quick" if quick else ""
    (fig_dir / f"ssdf_bench{tag}.json").write_text(json.dumps(results, indent=1))
    cols = list(curve)
    np.savetxt(fig_dir / f"ssdf_product_error{tag}.csv", np.stack([curve[c] for c in cols], 1),
               delimiter=",", header=",".join(cols), comments="", fmt="%.6g")
    _plots(results, fig_dir, tag)
    if not quick:
        _write_doc(results, out_doc)
    return results


def _plots(res, fig_dir: Path, tag: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = res["curve"]
    fig, ax = plt.subplots(figsize=(6, 4))
    for k, lab in [("ssdf16", "SSDF 16² (32² rays)"), ("ssdf32", "SSDF 32² (64² rays, default)"),
                   ("ssdf64", "SSDF 64² (128² rays)"), ("ssdf256", "SSDF 256² (256² rays)")]:
        ax.semilogx(c["lam"], c[k], marker="o", label=lab)
    ax.set_xlabel("SG sharpness λ")
    ax.set_ylabel("mean |fh(SSDF(p), λ) − ∫G·V| / fh(π/2, λ)")
    ax.set_title("SG × visibility product error (axes near shadow boundaries)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(fig_dir / f"ssdf_product_error{tag}.png", dpi=110)
    plt.close(fig)

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    s = res["sizes"]
    a1.loglog([r["vertices"] for r in s], [r["t_ssdf"] + r["t_pca"] for r in s], marker="o")
    a1.set_xlabel("vertices")
    a1.set_ylabel("precompute time (s)")
    a1.set_title(f"default quality {res['default'][0]}²/{res['default'][1]}² rays, {res['default'][2]} PCA terms")
    a1.grid(True, which="both", alpha=0.3)
    rr = res["resolutions"]
    a2.loglog([r["ms_per_vertex"] for r in rr], [r["ssdf_err"] for r in rr], marker="o", ls="")
    for r in rr:
        a2.annotate(f"{r['resolution']}/{r['ray_resolution']}", (r["ms_per_vertex"], r["ssdf_err"]))
    a2.set_xlabel("ms per vertex")
    a2.set_ylabel("mean SSDF error near boundaries (rad)")
    a2.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(fig_dir / f"ssdf_bench{tag}.png", dpi=110)
    plt.close(fig)


def _write_doc(res, path: Path):
    lams = res["lams"]
    lines = ["<!-- bench:begin -->", "",
             f"Measured by `python -m warp_sg.tools.bench_precompute` on `{res['device']}` "
             f"({time.strftime('%Y-%m-%d')}; 2 shared CPU cores).", "",
             "**Mesh size** (default quality: "
             f"{res['default'][0]}² SSDF from {res['default'][1]}² rays, {res['default'][2]} PCA terms):", "",
             "| vertices | triangles | SSDF (s) | PCA (s) | total (s) | PCA rms (rad) | "
             + " | ".join(f"err λ={l:g}" for l in lams) + " |",
             "|---:|---:|---:|---:|---:|---:|" + "---:|" * len(lams)]
    for r in res["sizes"]:
        lines.append(f"| {r['vertices']} | {r['triangles']} | {r['t_ssdf']:.1f} | {r['t_pca']:.1f} | "
                     f"{r['t_ssdf'] + r['t_pca']:.1f} | {r['pca_rms']:.3f} | "
                     + " | ".join(f"{e:.3f}" for e in r["product_err"]) + " |")
    lines += ["", f"**SSDF resolution** ({res['resolutions'][0]['vertices']}-vertex mesh; SSDF error = mean "
              "|SSDF − SSDF₂₅₆| at directions within 0.3 rad of a boundary; product errors with the "
              "uncompressed SSDF / with 24 PCA terms):", "",
              "| SSDF | rays | ms/vertex | SSDF err (rad) | PCA rms 8/16/24/48 (rad) | "
              + " | ".join(f"err λ={l:g}" for l in lams) + " |",
              "|---|---|---:|---:|---|" + "---|" * len(lams)]
    for r in res["resolutions"]:
        pc = r["pca_rms"]
        lines.append(f"| {r['resolution']}² | {r['ray_resolution']}² | {r['ms_per_vertex']:.2f} | "
                     f"{r['ssdf_err']:.4f} | {pc['8']:.3f}/{pc['16']:.3f}/{pc['24']:.3f}/{pc['48']:.3f} | "
                     + " | ".join(f"{a:.3f} / {b:.3f}" for a, b in zip(r["product_err"], r["product_err_pca24"]))
                     + " |")
    if res.get("pca_terms"):
        lines += ["", f"**PCA terms** ({res['default'][0]}² from {res['default'][1]}² rays, same mesh and axes; "
                  "'none' = uncompressed):", "",
                  "| terms | PCA rms (rad) | " + " | ".join(f"err λ={l:g}" for l in lams) + " |",
                  "|---|---:|" + "---:|" * len(lams)]
        for r in res["pca_terms"]:
            lines.append(f"| {r['terms']} | {r['pca_rms']:.4f} | " + " | ".join(f"{e:.3f}" for e in r["product_err"])
                         + " |")
    lines += ["", "![timing and SSDF error](figures/ssdf_bench.png)",
              "![product error](figures/ssdf_product_error.png)", "", "<!-- bench:end -->"]
    block = "\n".join(lines)
    text = path.read_text() if path.exists() else ""
    if "<!-- bench:begin -->" in text and "<!-- bench:end -->" in text:
        pre = text.split("<!-- bench:begin -->")[0]
        post = text.split("<!-- bench:end -->")[1]
        text = pre + block + post
    else:
        text = text + "\n" + block + "\n"
    path.write_text(text)


if __name__ == "__main__":  # python -m warp_sg.tools.bench_precompute [--quick] [--device cuda]
    import argparse

    ap = argparse.ArgumentParser(description="SSDF precompute benchmark")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--device", default="cpu")
    a = ap.parse_args()
    run_bench(quick=a.quick, device=a.device)

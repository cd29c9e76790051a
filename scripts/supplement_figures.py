#!/usr/bin/env python
r"""Reproduce supplement figures of Wang et al. 2009 with warp-sg's fits (PNG + CSV).

* Fig. 1 — clamped-cosine SG fit error vs number of lobes (``warp_sg.sg.cosine_lobes``);
* Fig. 2 — fitted single-lobe sharpness λ vs Cook–Torrance m and Blinn–Phong n: analytic rule
  (λ = 2/m², λ = n; dashed) vs nonlinear least squares (solid);
* Fig. 3 — supplement eq. 11 error of the single-lobe fit across roughness (analytic and fit);
* Fig. 9 — eq. 11 error of the spherically warped slice (paper eq. 17–22) vs lobe sharpness.

Usage: ``python scripts/supplement_figures.py [OUT_DIR] [--quick]`` (default ``docs/figures``).
"""
from __future__ import annotations

import argparse
import csv
import os
from pathlib import Path

import numpy as np


def _write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow([f"{x:.10g}" if isinstance(x, (float, np.floating)) else x for x in r])


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def fig1(out, quick):
    from warp_sg.sg import cosine_lobes as C

    plt = _plt()
    rep = C.error_report()
    rows = [(k, rep[k][0], rep[k][1]) for k in range(1, C.MAX_LOBES + 1)]
    _write_csv(out / "fig1_clamped_cosine.csv", ["lobes", "rel_l2_error", "max_abs_error"], rows)
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    ax[0].semilogy([r[0] for r in rows], [r[1] for r in rows], "o-", label="SG (common axis)")
    ax[0].semilogy([1], [rep["paper"][0]], "x", label="paper eq. 40")
    ax[0].set_xlabel("number of lobes")
    ax[0].set_ylabel("relative L2 error")
    ax[0].legend()
    th = np.linspace(0, np.pi, 400)
    ax[1].plot(th, np.maximum(np.cos(th), 0), "k", lw=2, label="max(cos θ, 0)")
    for k in range(1, C.MAX_LOBES + 1):
        lam, mu = C.lobes(k)
        ax[1].plot(th, C.evaluate(np.cos(th), lam, mu), label=f"{k} lobe(s)")
    ax[1].set_xlabel("θ")
    ax[1].legend(fontsize=7)
    fig.suptitle("Supplement Fig. 1: clamped cosine")
    fig.tight_layout()
    fig.savefig(out / "fig1_clamped_cosine.png", dpi=110)
    plt.close(fig)
    return ["fig1_clamped_cosine.csv", "fig1_clamped_cosine.png"]


def fig2(out, quick):
    import warp_sg.brdf as B

    plt = _plt()
    ms = np.geomspace(0.02, 0.6, 6 if quick else 20)
    ns = np.geomspace(2, 2000, 6 if quick else 20)
    rows = []
    for m in ms:
        rows.append(("cook_torrance", "m", m, 2 / m**2, B.CookTorrance(m=m).ndf_sg(1, "fit")[1][0]))
    for n in ns:
        rows.append(("blinn_phong", "n", n, n, B.BlinnPhong(n=n).ndf_sg(1, "fit")[1][0]))
    _write_csv(out / "fig2_fitted_lambda.csv", ["model", "param", "value", "lambda_analytic", "lambda_fit"], rows)
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    ct = [r for r in rows if r[0] == "cook_torrance"]
    bp = [r for r in rows if r[0] == "blinn_phong"]
    for a, rr, lab in ((ax[0], ct, "Cook–Torrance m"), (ax[1], bp, "Blinn–Phong n")):
        a.loglog([r[2] for r in rr], [r[4] for r in rr], "-", label="nonlinear fit")
        a.loglog([r[2] for r in rr], [r[3] for r in rr], "--", label="analytic")
        a.set_xlabel(lab)
        a.set_ylabel("λ")
        a.legend()
    fig.suptitle("Supplement Fig. 2: single-lobe SG sharpness")
    fig.tight_layout()
    fig.savefig(out / "fig2_fitted_lambda.png", dpi=110)
    plt.close(fig)
    return ["fig2_fitted_lambda.csv", "fig2_fitted_lambda.png"]


def fig3(out, quick):
    import warp_sg.brdf as B
    from warp_sg.brdf.fitting.fit import fit_error

    plt = _plt()
    kw = dict(n_o=8, n_th=48, n_ph=32) if quick else dict(n_o=24)
    ms = np.geomspace(0.02, 0.6, 5 if quick else 14)
    ns = np.geomspace(2, 5000, 5 if quick else 14)
    rows = []
    for m in ms:
        M = B.CookTorrance(m=m)
        rows.append(("cook_torrance", "m", m, fit_error(M, 1, "analytic", **kw), fit_error(M, 1, "fit", **kw)))
    for n in ns:
        M = B.BlinnPhong(n=n)
        rows.append(("blinn_phong", "n", n, fit_error(M, 1, "analytic", **kw), fit_error(M, 1, "fit", **kw)))
    _write_csv(out / "fig3_fit_error.csv", ["model", "param", "value", "eq11_error_analytic", "eq11_error_fit"], rows)
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    for a, name, lab in ((ax[0], "cook_torrance", "Cook–Torrance m"), (ax[1], "blinn_phong", "Blinn–Phong n")):
        rr = [r for r in rows if r[0] == name]
        a.loglog([r[2] for r in rr], [r[3] for r in rr], "--", label="analytic λ")
        a.loglog([r[2] for r in rr], [r[4] for r in rr], "-", label="fitted λ")
        a.set_xlabel(lab)
        a.set_ylabel("eq. 11 error")
        a.legend()
    fig.suptitle("Supplement Fig. 3: single-lobe SG fit error")
    fig.tight_layout()
    fig.savefig(out / "fig3_fit_error.png", dpi=110)
    plt.close(fig)
    return ["fig3_fit_error.csv", "fig3_fit_error.png"]


def fig9(out, quick):
    import warp_sg.brdf as B
    from warp_sg.brdf.fitting.fit import fit_error, warp_error

    plt = _plt()
    kw = dict(n_o=8, n_th=48, n_ph=32) if quick else dict(n_o=24)
    ms = np.geomspace(0.03, 0.7, 5 if quick else 14)
    rows = []
    for m in ms:
        M = B.CookTorrance(m=m)
        rows.append((m, 2 / m**2, warp_error(M, 1, "analytic", **kw), fit_error(M, 1, "analytic", **kw)))
    _write_csv(out / "fig9_warp_error.csv", ["m", "lambda", "eq11_error_warped_slice", "eq11_error_ndf_fit_only"], rows)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.semilogx([r[1] for r in rows], [r[2] for r in rows], "o-", label="warped slice (eq. 22)")
    ax.semilogx([r[1] for r in rows], [r[3] for r in rows], "s--", label="NDF fit only")
    ax.set_yscale("log")
    ax.set_xlabel("lobe sharpness λ = 2/m²")
    ax.set_ylabel("eq. 11 error")
    ax.legend()
    ax.set_title("Supplement Fig. 9: SG warping error (Cook–Torrance)")
    fig.tight_layout()
    fig.savefig(out / "fig9_warp_error.png", dpi=110)
    plt.close(fig)
    return ["fig9_warp_error.csv", "fig9_warp_error.png"]


def make_figures(out_dir, quick=False):
    """Write the four figures (PNG + CSV) into ``out_dir``; returns the list of written paths."""
    out = Path(out_dir)
    os.makedirs(out, exist_ok=True)
    files = []
    for f in (fig1, fig2, fig3, fig9):
        files += [out / name for name in f(out, quick)]
    return files


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir", nargs="?", default=str(Path(__file__).resolve().parents[1] / "docs" / "figures"))
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    for p in make_figures(args.out_dir, quick=args.quick):
        print(p)


if __name__ == "__main__":
    main()

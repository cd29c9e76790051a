"""GGX NDF SG fits: error against lobe count for α ∈ [0.01, 1] (supplement Fig. 3 style).

For each α and K = 1..4 lobes — ``fit``: the least-squares fit of :mod:`warp_sg.brdf.fitting.fit` at that α
(non-negative amplitudes; K = 1: λ with μ = 1); ``table``: the shipped node fits interpolated at α
(:func:`warp_sg.brdf.models.ggx.table_lobes`, what the renderer uses); ``taylor``: the single lobe
λ = 4/α² − 4 — two errors:

* ``ndf_l2``: relative L2 error of the NDF over the hemisphere, ``∫ (D̂ − D*)² dω / ∫ D̂² dω``;
* ``eq11``: supplement eq. 11 error of ``Mo(o, i) · D*(h)`` against ``ρs`` over all (o, i) with the
  θh quadrature over the whole hemisphere (the tail matters for GGX);

and, for anisotropic GGX (αx, αy) = (0.3, 0.06), the eq. 11 error of the Ashikhmin–Shirley N-lobe
layout (N = 1, 3, ..., 9; supplement eq. 14). Writes ``docs/figures/ggx_fit_error.csv``,
``ggx_fit_error.md`` (the table of docs/ggx.md) and ``ggx_fit_error.png``.

    python scripts/ggx_fit_error.py [--quick]
"""
from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from tqdm import tqdm

from warp_sg.brdf import GGX
from warp_sg.brdf.fitting.fit import eq11_error
from warp_sg.brdf.helpers import half_vector
from warp_sg.core.files import atomic_output

ROOT = Path(__file__).resolve().parents[1]
QUAD = dict(n_o=24, n_th=256, n_ph=48, theta_max=np.pi / 2)


def sg_lobes(model, k, method):
    if method == "taylor":
        return np.array([[0.0, 0.0, 1.0]]), np.array([model.ndf_analytic_lambda()]), np.ones(1)
    return model.ndf_sg(k, "analytic" if method == "table" else method)


def eq11(model, axes, lam, mu, **quad):
    def approx(o, i):
        hh = half_vector(o, i)
        return model.mo(o, i) * (mu * np.exp(-lam * (1.0 - hh @ axes.T))).sum(-1)[..., None]

    return eq11_error(model, approx, **quad)


def ndf_l2(model, axes, lam, mu):
    t = (np.arange(20000) + 0.5) / 20000
    th = np.pi / 2 * t * t
    w = np.sin(th) * t
    h = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    d = model.ndf(h)
    approx = (mu * np.exp(-lam * (1 - np.cos(th))[:, None])).sum(-1)
    return float(np.sum(w * (d - approx) ** 2) / np.sum(w * d * d))


def study(alphas, lobes=(1, 2, 3, 4), aniso_lobes=(1, 3, 5, 7, 9)):
    rows = []
    jobs = [(a, k, m) for a in alphas for k in lobes for m in (("taylor", "fit", "table") if k == 1 else ("fit", "table"))]
    for a, k, method in tqdm(jobs, desc="GGX fits"):
        model = GGX(ks=1.0, alpha=float(a), lobes=k)
        lb = sg_lobes(model, k, method)
        rows.append(dict(kind="isotropic", alpha_x=float(a), alpha_y=float(a), lobes=k, method=method,
                         ndf_l2=ndf_l2(model, *lb), eq11=eq11(model, *lb, **QUAD)))
    for n in tqdm(aniso_lobes, desc="anisotropic GGX"):
        model = GGX(ks=1.0, alpha_x=0.3, alpha_y=0.06, lobes=n)
        rows.append(dict(kind="anisotropic", alpha_x=0.3, alpha_y=0.06, lobes=n, method="analytic",
                         ndf_l2=float("nan"), eq11=eq11(model, *model.ndf_sg(n, "analytic"), n_phi_o=8, **QUAD)))
    return rows


def write(rows, out: Path):
    out.mkdir(parents=True, exist_ok=True)
    keys = list(rows[0])
    with atomic_output(out / "ggx_fit_error.csv") as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    iso = [r for r in rows if r["kind"] == "isotropic"]
    alphas = sorted({r["alpha_x"] for r in iso})
    cols = [(1, "taylor"), (1, "fit"), (2, "fit"), (3, "fit"), (4, "fit"), (1, "table"), (2, "table"), (3, "table"),
            (4, "table")]
    lines = ["| α | " + " | ".join(f"K={k} {m}" for k, m in cols) + " |",
             "|---" * (len(cols) + 1) + "|"]
    for a in alphas:
        cells = []
        for k, m in cols:
            r = next(r for r in iso if r["alpha_x"] == a and r["lobes"] == k and r["method"] == m)
            cells.append(f"{r['eq11']:.1e} / {r['ndf_l2']:.1e}")
        lines.append(f"| {a:.3g} | " + " | ".join(cells) + " |")
    an = [r for r in rows if r["kind"] == "anisotropic"]
    lines += ["", "| anisotropic (αx, αy) = (0.3, 0.06) | " + " | ".join(f"N={r['lobes']}" for r in an) + " |",
              "|---" * (len(an) + 1) + "|", "| eq. 11 | " + " | ".join(f"{r['eq11']:.1e}" for r in an) + " |"]
    with atomic_output(out / "ggx_fit_error.md") as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(8, 3.2))
    for k, m in cols:
        if m == "table":
            continue
        rr = [next(r for r in iso if r["alpha_x"] == a and r["lobes"] == k and r["method"] == m) for a in alphas]
        label = f"K={k}" + (" (Taylor)" if m == "taylor" else "")
        style = "--" if m == "taylor" else "-"
        axs[0].loglog(alphas, [r["eq11"] for r in rr], style, marker="o", ms=3, label=label)
        axs[1].loglog(alphas, [r["ndf_l2"] for r in rr], style, marker="o", ms=3, label=label)
    axs[0].set_title("supplement eq. 11 error", fontsize=9)
    axs[1].set_title("NDF relative L2 error", fontsize=9)
    for ax in axs:
        ax.set_ylim(1e-8, 1.0)  # (α = 1: D̂ is constant, every fit is exact to rounding)
        ax.set_xlabel("α")
        ax.grid(True, which="both", alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.tight_layout()
    with atomic_output(out / "ggx_fit_error.png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="three α values only")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    a = ap.parse_args()
    # off the table's nodes (multiples of 0.025) on purpose, except α = 1
    alphas = [0.03, 0.33, 1.0] if a.quick else [0.01, 0.02, 0.04, 0.11, 0.21, 0.33, 0.51, 0.71, 0.89, 1.0]
    rows = study(alphas)
    write(rows, Path(a.out))
    print((Path(a.out) / "ggx_fit_error.md").read_text())


if __name__ == "__main__":
    main()

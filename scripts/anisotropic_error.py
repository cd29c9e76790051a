"""Anisotropic reflectance: error vs number of SG lobes N (supplement Fig. 5-6 style).

Writes docs/figures/aniso_error.csv, aniso_error.png (error vs N for Ashikhmin-Shirley and
anisotropic Ward, NDF / warped-slice / rendered-sphere errors, analytic construction of supplement
eq. 14 and L-BFGS-B fit) and aniso_spheres.png (exact vs N-lobe renders). See warp_sg/sg/anisotropy.py.

    python scripts/anisotropic_error.py [--quick]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from warp_sg.sg import anisotropy as A

ROOT = Path(__file__).resolve().parents[1]


def spheres(path, res=96):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = [None, 1, 3, 7, 15]
    fig, axs = plt.subplots(2, len(cols), figsize=(2.2 * len(cols), 4.6))
    for r, name in enumerate(("ashikhmin_shirley", "ward")):
        ref = A.render_sphere(A.make(name, 1), None, res=res)
        vmax = ref.max()
        for c, n in enumerate(cols):
            img = ref if n is None else A.render_sphere(A.make(name, n), n, "fit", res=res)
            axs[r, c].imshow(np.clip(img / vmax, 0, 1) ** (1 / 2.2), cmap="gray", vmin=0, vmax=1)
            axs[r, c].set_xticks([])
            axs[r, c].set_yticks([])
            title = "exact" if n is None else f"N={n}: {np.sum((img - ref) ** 2) / np.sum(ref ** 2):.1e}"
            axs[r, c].set_title(title, fontsize=8)
        axs[r, 0].set_ylabel(name.replace("_", "-"), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="N = 1, 3, 5 only")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    lobes = (1, 3, 5) if a.quick else range(1, 16, 2)
    t = time.perf_counter()
    rows = A.study(lobes=lobes)
    A.write_csv(rows, out / "aniso_error.csv")
    A.plot(rows, out / "aniso_error.png")
    spheres(out / "aniso_spheres.png")
    print(f"wrote {out}/aniso_error.csv, aniso_error.png, aniso_spheres.png in {time.perf_counter() - t:.1f} s")


if __name__ == "__main__":
    main()

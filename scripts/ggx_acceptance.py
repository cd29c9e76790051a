"""GGX acceptance (issue 15): a gold GGX sphere (α = 0.1, 0.3, 0.6) on a floor under the sun-sky and
under a point light; the SG renderer against the Monte-Carlo reference.

    python scripts/ggx_acceptance.py [--size 64] [--spp 256] [--alphas 0.1,0.3,0.6] [--lobes 1,3]

Scenes come from :func:`warp_sg.scene.plain_scenes.write_plain_scene` (2-triangle floor, icosphere,
sky EXR with a sun, or one spherical point light) with the material
``{model = "ggx", ks = 1, alpha = α, fresnel = "gold"}`` and ``lobes`` NDF lobes. Errors are the
image-wide relative MSE ``Σ(x − r)²/Σr²`` and that of the ``object`` region
(:mod:`warp_sg.groundtruth.region_error`). Writes ``docs/figures/ggx_acceptance.md`` (the table of docs/ggx.md) and
``ggx_acceptance.png`` (reference above, SG renderer below, default lobe count).
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from tqdm import tqdm

import warp_sg as ws
from warp_sg.brdf.models.ggx import DEFAULT_LOBES
from warp_sg.core.files import atomic_output
from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions
from warp_sg.scene.plain_scenes import write_plain_scene

ROOT = Path(__file__).resolve().parents[1]


def material(alpha, lobes):
    return {"model": "ggx", "kd": [0.0, 0.0, 0.0], "ks": [1.0, 1.0, 1.0], "alpha": float(alpha),
            "fresnel": "gold", "lobes": int(lobes)}


def run(alphas, lights, lobes, size, spp):
    rows, images = [], {}
    jobs = [(a, li) for li in lights for a in alphas]
    for a, li in tqdm(jobs, desc="GGX acceptance"):
        with tempfile.TemporaryDirectory() as d:
            ref = regs = se = None
            for k in lobes:
                path = write_plain_scene(Path(d) / f"k{k}", obj="sphere", light=li, material=material(a, k), size=size)
                if ref is None:
                    ref, se = box_reference(ws.load_scene(path), spp=spp, return_stderr=True)
                    regs = scene_regions(ws.load_scene(path))
                img = ws.Renderer(ws.load_scene(path), device="cpu").render()
                errs = region_errors(img, ref, regs, stderr=se)
                rel = float(np.sum((img - ref) ** 2) / np.sum(ref ** 2))
                rows.append(dict(alpha=a, light=li, lobes=k, image_rel_mse=rel, object_rel_mse=errs["object"]["rel_mse"],
                                 object_bias=errs["object"]["bias"]))
                if k == DEFAULT_LOBES or len(lobes) == 1:
                    images[(a, li)] = (ref, img)
    return rows, images


def write(rows, images, out: Path, spp, size):
    out.mkdir(parents=True, exist_ok=True)
    lines = [f"{size}×{size} pixels, reference {spp} spp per pixel (box-filtered), gold GGX sphere, kd = 0.", "",
             "| light | α | lobes | image rel. MSE | object rel. MSE | object bias |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['light']} | {r['alpha']:g} | {r['lobes']} | {r['image_rel_mse']:.4f} | "
                     f"{r['object_rel_mse']:.4f} | {r['object_bias']:+.3f} |")
    with atomic_output(out / "ggx_acceptance.md") as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(images)
    fig, axs = plt.subplots(2, len(keys), figsize=(1.8 * len(keys), 3.9), squeeze=False)
    for c, key in enumerate(keys):
        ref, img = images[key]
        scale = np.percentile(ref, 99.5) or 1.0
        for r, im in enumerate((ref, img)):
            axs[r, c].imshow(np.clip(im / scale, 0, 1) ** (1 / 2.2))
            axs[r, c].set_xticks([])
            axs[r, c].set_yticks([])
        axs[0, c].set_title(f"{key[1]}, α={key[0]:g}", fontsize=8)
    axs[0, 0].set_ylabel("MC reference", fontsize=8)
    axs[1, 0].set_ylabel(f"SG, {DEFAULT_LOBES} lobes", fontsize=8)
    fig.tight_layout()
    with atomic_output(out / "ggx_acceptance.png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--alphas", default="0.1,0.3,0.6")
    ap.add_argument("--lights", default="sky,point")
    ap.add_argument("--lobes", default=f"1,{DEFAULT_LOBES}")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    a = ap.parse_args()
    rows, images = run([float(x) for x in a.alphas.split(",")], a.lights.split(","),
                       [int(x) for x in a.lobes.split(",")], a.size, a.spp)
    write(rows, images, Path(a.out), a.spp, a.size)
    print((Path(a.out) / "ggx_acceptance.md").read_text())


if __name__ == "__main__":
    main()

"""SSDF error at vertices that are not representatives (docs/precompute.md, "Representative vertices").

    python scripts/representative_accuracy.py ASSET [--budget 20000] [--samples 96]
    python scripts/representative_accuracy.py helmet --budget 5000   # the generated helmet (refined to 20 k)
    python scripts/representative_accuracy.py plane-box --budget 2000   # plane and box, 14.4 k vertices

Computes ``ssdf_for_mesh(representatives=BUDGET)`` of the asset's SSDF mesh (the renderer's: refined
to ``[render] visibility_budget`` when it has fewer vertices; ``WARP_SG_CACHE_DIR`` as it is),
picks ``--samples`` vertices that are not representatives (seeded), and compares at them, with
``warp_sg.tools.bench_precompute.ssdf_error`` (mean |error| at random directions where the truth is
within 0.3 rad of a boundary; the bench's "SSDF error vs ray budget" measure), against each
vertex's own 256² ray-cast map: (1) its own default map (64² adaptive rays → 32²), uncompressed,
(2) the same projected on the representatives' PCA basis, (3) its transferred, blended map from
the representatives (PCA weights of the result). Also (3) against (1).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _mesh(name, out):
    if name == "plane-box":
        from precompute.visibility.reference_checks import plane_box_scene

        return plane_box_scene(120)
    from precompute.visibility.refine import refine_cached
    from warp_sg.scene.importers.asset import asset_scene

    if name == "helmet":
        from warp_sg.tools.bench_assets import textured_helmet

        name = str(textured_helmet(Path(out) / "helmet.glb"))
    scene, _ = asset_scene(name)
    g = scene.geometry()
    budget = scene.render.visibility_budget
    if budget > len(g.vertices):
        r = refine_cached(g.vertices, g.triangles, g.normals, budget=budget, device="cpu")
        return r.vertices, r.triangles, r.normals
    return g.vertices, g.triangles, g.normals


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("asset")
    ap.add_argument("--budget", type=int, default=20000)
    ap.add_argument("--samples", type=int, default=96)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    from warp_sg.core.device import resolve_device

    resolve_device("cpu")
    from precompute.visibility import ssdf as S
    from warp_sg.tools.bench_precompute import ssdf_error

    V, F, N = _mesh(a.asset, tempfile.mkdtemp(prefix="wsg-repacc-"))
    c0 = time.process_time()
    d = S.ssdf_for_mesh(V, F, N, representatives=a.budget, progress=False)
    cpu = time.process_time() - c0
    if not len(d.representative):
        print(f"{len(V)} vertices: within the budget, every vertex has its own map")
        return 0
    isrep = np.zeros(len(V), bool)
    isrep[d.representative] = True
    rng = np.random.default_rng(0)
    ids = np.sort(rng.choice(np.flatnonzero(~isrep), min(a.samples, int((~isrep).sum())), replace=False))
    truth = S.compute_ssdf(V, F, N, resolution=256, ray_resolution=256, vertex_ids=ids, progress=False, rays="full")
    own = S.compute_ssdf(V, F, N, vertex_ids=ids, progress=False)
    R = d.resolution
    B = d.basis.reshape(d.pca_terms, -1)
    own_pca = ((own.reshape(len(ids), -1) - d.mean.reshape(1, -1)) @ B.T @ B + d.mean.reshape(1, -1)).reshape(-1, R, R)
    rep = d.reconstruct(ids)
    k = np.arange(len(ids))
    dist = np.linalg.norm(np.asarray(V)[ids] - np.asarray(V)[d.representative[ids]], axis=1)
    ext = float(np.max(np.ptp(np.asarray(V), axis=0)))
    res = {"asset": a.asset, "vertices": int(len(V)), "representatives": int(isrep.sum()), "samples": int(len(ids)),
           "build_cpu_s": cpu if d.stats else None, "mean_dist_to_rep_rel_extent": float(dist.mean() / ext),
           "own_vs_256": ssdf_error(V, F, N, k, own, truth), "own_pca_vs_256": ssdf_error(V, F, N, k, own_pca, truth),
           "reps_vs_256": ssdf_error(V, F, N, k, rep, truth), "reps_vs_own": ssdf_error(V, F, N, k, rep, own),
           "stats": {k2: v for k2, v in d.stats.items()}}
    print(json.dumps(res, indent=1, default=float))
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Memory and time of the SSDF compression at large vertex counts (docs/benchmarks.md, "Scale").

    python scripts/ssdf_memory.py --vertices 250000 500000 1000000 [--resolution 32]

For each count V: V rows of synthetic SSDF maps (a smooth field plus per-vertex noise; the PCA and
the occluder cones do not care what the rows mean) are written batch by batch into the
out-of-core row file ``precompute.ssdf_for_mesh`` uses beyond ``WARP_SG_SSDF_MEMORY_MB``
(``precompute.visibility.ssdf._disk_rows``), then PCA (32 terms) and the occluder cones run on it, as in
``ssdf_for_mesh``. Printed per V: the peak of numpy's heap allocations (``tracemalloc``, which numpy
reports to), the process's peak resident memory (``ru_maxrss``, monotone over the run; file pages
of the row file count while mapped) and the CPU seconds of each step. The ray casting itself works
on 256-vertex batches (a few tens of MB whatever V) and is measured by ``scripts/profile_cold.py``.
"""
from __future__ import annotations

import argparse
import resource
import time
import tracemalloc

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vertices", type=int, nargs="+", default=[250_000, 500_000, 1_000_000])
    ap.add_argument("--resolution", type=int, default=32)
    ap.add_argument("--terms", type=int, default=32)
    a = ap.parse_args(argv)
    from precompute.visibility.occluder_cone import occluder_cones
    from precompute.visibility.ssdf import _disk_rows
    from warp_sg.numeric.pca import pca

    R = a.resolution
    D = R * R
    yy, xx = np.mgrid[0:R, 0:R] / R
    base = (np.sin(3 * xx) * np.cos(2 * yy)).ravel().astype(np.float32)
    print("| vertices | rows on disk (GiB) | write CPU (s) | PCA CPU (s) | cones CPU (s) | numpy heap peak (GiB) | peak RSS (GiB) |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for V in a.vertices:
        rng = np.random.default_rng(0)
        normals = rng.standard_normal((V, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        tracemalloc.start()
        with _disk_rows(V, D) as X:
            c0 = time.process_time()
            for s in range(0, V, 4096):  # batch by batch, as compute_ssdf writes them
                e = min(s + 4096, V)
                w = rng.standard_normal((e - s, 4)).astype(np.float32)
                X[s:e] = base[None] * w[:, :1] + 0.3 * np.roll(base, 7)[None] * w[:, 1:2] \
                    + 0.05 * rng.standard_normal((e - s, D)).astype(np.float32) - 0.2
            c1 = time.process_time()
            p = pca(X, a.terms)
            c2 = time.process_time()
            occluder_cones(X, normals, R)
            c3 = time.process_time()
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / (1 << 20)
        print(f"| {V} | {V * D * 4 / 2**30:.2f} | {c1 - c0:.1f} | {c2 - c1:.1f} | {c3 - c2:.1f} | "
              f"{peak / 2**30:.2f} | {rss:.2f} |", flush=True)
        del p
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

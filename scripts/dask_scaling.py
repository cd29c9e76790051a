"""SSDF precompute on a Dask LocalCluster: 1 vs N worker processes (docs/benchmarks.md, issue 16).

The mesh: the Stanford bunny of pymeshlab's wheel (28 k vertices, 56 k triangles; offline: ``pip
download pymeshlab --no-deps`` and ``unzip -p pymeshlab-*.whl '*/sample_meshes/bunny.obj' >
bunny.obj``) standing on a floor grid (``--floor K``: K×K vertices), so the scene has ~50 k vertices
and real shadows. Any mesh trimesh reads works (``--mesh``).

Per worker count: a LocalCluster of single-threaded worker processes (``warp_sg.distributed.cluster``), one
warm-up run on a few vertices (each worker loads its kernels and builds the BVH), then ``--repeats``
timed runs (interleaved between the worker counts) of
:class:`warp_sg.distributed.precompute.DaskSSDF` on the whole mesh (the distributed part) and the
client's own part, PCA + atomic cache write (``ssdf_for_mesh`` with the SSDFs already computed).
The workers' CPU seconds (``getrusage`` in each worker) and their share of the wall time show how
much of a core each worker really got; the load average of the machine (``os.getloadavg``) is
printed with every timing: other jobs on a shared machine slow the runs down.

    python scripts/dask_scaling.py --mesh bunny.obj --workers 1 2 --repeats 2 -o scaling.md
"""
from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import time
from pathlib import Path

import numpy as np


def scene_mesh(path, floor: int):
    """(V, F, N) float64/int64: the mesh scaled to unit height on a ``floor``×``floor`` grid."""
    import trimesh

    from warp_sg.scene.primitives import plane

    m = trimesh.load(path, process=True, force="mesh")
    v = np.asarray(m.vertices, np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    s = 1.0 / (hi[1] - lo[1])
    v = (v - [(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2]) * s
    n = np.asarray(m.vertex_normals, np.float64)
    f = np.asarray(m.faces, np.int64)
    if floor > 1:
        p = plane(center=(0.0, 0.0, 0.0), size=(3.0, 3.0), resolution=(floor - 1, floor - 1))
        pv, pn = np.asarray(p.vertices, np.float64), np.asarray(p.normals, np.float64)
        pf = np.asarray(p.triangles, np.int64) + len(v)
        v, n, f = np.vstack([v, pv]), np.vstack([n, pn]), np.vstack([f, pf])
    return v, f, n


def _cpu_seconds() -> float:
    """User + system CPU seconds of this (worker) process so far."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _na(v, fmt):
    return "–" if v != v else format(v, fmt)


def _worker_cpu(client) -> float:
    return float(sum(client.run(_cpu_seconds).values()))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", required=True, help="mesh file (e.g. bunny.obj from pymeshlab's wheel)")
    ap.add_argument("--floor", type=int, default=150, help="floor grid vertices per side (0 = none)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--resolution", type=int, default=32)
    ap.add_argument("--pca-terms", type=int, default=32)
    ap.add_argument("--chunk", type=int, default=256)
    ap.add_argument("--local", action="store_true", help="also time the local thread-pool path (no Dask)")
    ap.add_argument("-o", "--output", default=None, help="also write the markdown table here")
    args = ap.parse_args(argv)

    from precompute.visibility.ssdf import ssdf_for_mesh
    from warp_sg.core.cache import fresh_cache
    from warp_sg.distributed.cluster import connect
    from warp_sg.distributed.precompute import DaskSSDF

    V, F, N = scene_mesh(args.mesh, args.floor)
    R, Rr = args.resolution, 2 * args.resolution
    print(f"mesh: {len(V)} vertices, {len(F)} triangles; SSDF {R}² from {Rr}² rays, chunk {args.chunk}")
    rows, X = [], None
    with contextlib.ExitStack() as stack:
        clients = {w: stack.enter_context(connect(f"local:{w}", timeout=60)) for w in args.workers}
        for w, client in clients.items():
            # warm-up: every worker loads its kernels and builds the mesh's BVH (kept for the timed runs)
            DaskSSDF(client, chunk=4)(V, F, N, resolution=R, ray_resolution=Rr, progress=False,
                                      vertex_ids=np.arange(0, len(V), max(1, len(V) // (8 * w)))[: 8 * w])
        times = {w: [] for w in args.workers}
        loads = {w: [] for w in args.workers}
        stats, cpu = {}, {}
        for _ in range(args.repeats):  # interleaved, so a change of the machine's load hits every count
            for w, client in clients.items():
                dask = DaskSSDF(client, chunk=args.chunk)
                l0 = os.getloadavg()[0]
                c0 = _worker_cpu(client)
                t0 = time.perf_counter()
                X = dask(V, F, N, resolution=R, ray_resolution=Rr, progress=False)
                times[w].append(time.perf_counter() - t0)
                cpu.setdefault(w, []).append(_worker_cpu(client) - c0)
                loads[w].append(max(l0, os.getloadavg()[0]))
                stats[w] = dict(dask.stats)
                print(f"{w} worker(s): {times[w][-1]:.2f} s, workers' CPU {cpu[w][-1]:.1f} s "
                      f"(load average {loads[w][-1]:.2f})", flush=True)
            if args.local:  # today's local path: one process, Warp launches from a thread pool over the cores
                from precompute.visibility.ssdf import compute_ssdf

                l0 = os.getloadavg()[0]
                t0 = time.perf_counter()
                compute_ssdf(V, F, N, resolution=R, ray_resolution=Rr, progress=False)
                times.setdefault("local", []).append(time.perf_counter() - t0)
                loads.setdefault("local", []).append(max(l0, os.getloadavg()[0]))
                print(f"local threads: {times['local'][-1]:.2f} s (load average {loads['local'][-1]:.2f})", flush=True)
        for w in args.workers + (["local"] if args.local else []):
            ts = times[w]
            rows.append({"workers": w, "best_s": min(ts), "median_s": statistics.median(ts), "load": max(loads[w]),
                         "ms_per_vertex": 1e3 * min(ts) / len(V), "stats": stats.get(w),
                         "cpu_s": min(cpu[w]) if w in cpu else float("nan"),
                         "cpu_share": (cpu[w][ts.index(min(ts))] / (min(ts) * w)) if w in cpu else float("nan")})
    # the client's own part: PCA + the atomic cache write, on the SSDFs just computed
    with fresh_cache():
        t0 = time.perf_counter()
        ssdf_for_mesh(V, F, N, resolution=R, ray_resolution=Rr, pca_terms=args.pca_terms, progress=False,
                      compute=lambda *a, **k: X)
        t_client = time.perf_counter() - t0
    base = rows[0]["best_s"]
    st = rows[len(args.workers) - 1]["stats"]
    lines = [f"SSDF precompute of {len(V)} vertices ({len(F)} triangles), SSDF {R}² from {Rr}² rays, "
             f"{args.chunk} vertices per task ({st['tasks']} tasks); best of {args.repeats}.", "",
             "| workers | best s | median s | speed-up | ms/vertex | workers' CPU s | CPU share per worker | max load avg |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        name = "local (threads, no Dask)" if r["workers"] == "local" else r["workers"]
        lines.append(f"| {name} | {r['best_s']:.2f} | {r['median_s']:.2f} | {base / r['best_s']:.2f}× | "
                     f"{r['ms_per_vertex']:.3f} | {_na(r['cpu_s'], '.1f')} | {_na(r['cpu_share'], '.0%')} | {r['load']:.2f} |")
    lines += ["", f"Client part (PCA to {args.pca_terms} terms + atomic cache write): {t_client:.2f} s "
              f"({1e3 * t_client / len(V):.3f} ms/vertex).",
              f"Data per task: {st['bytes_per_chunk'] / 1024:.0f} KiB back (float32 SSDFs), < 1 KiB of arguments; "
              f"the mesh once per worker: {st['mesh_bytes_per_worker'] / 2**20:.2f} MiB."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output:
        Path(args.output).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

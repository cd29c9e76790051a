"""Every target of a new user's first image, measured in one command (docs/benchmarks.md, "First run").

    python scripts/first_run.py                       # the generated 17 k-triangle textured helmet, the sky
    python scripts/first_run.py ASSET [--env MAP] [--size 512 384] [--repo PATH] [--no-viewer] [--json OUT]

Each run is a fresh ``warp-sg`` process with a fresh precompute cache (``WARP_SG_CACHE_DIR``; after
the first-ever runs it holds the asset-independent tables they built, as on any machine that has
rendered before):

1. ``render ASSET`` with an empty Warp kernel cache (``WARP_CACHE_PATH``): the first-ever render;
2. ``render ASSET --first-frame`` with another empty kernel cache: the progressive first frame of
   a first-ever run (the time its first-frame file appears) and its final frame;
3. ``render ASSET`` with the kernels run 1 compiled: a new asset on a machine that has rendered;
4. ``render ASSET --first-frame`` with those kernels;
5. the warm frame (a renderer's third to fifth frames, median) with those kernels;
6. the viewer (``open_viewer``, progressive; off screen, or in the window of ``$DISPLAY``) until it
   shows the shadowed frame, left alone and while a drag goes round in circles, against run 3's
   precompute time (``--timings``).

Wall seconds and CPU seconds (the child processes' user + system time) per run, the machine's load
average before each, and every stderr line of runs 1–4 that is neither a progress bar nor one of
our own (``warp-sg: ...``, the first frame's notice). ``--repo PATH`` runs another checkout's code
(PYTHONPATH), for an A/B comparison on the same machine. Accuracy is not measured here:
``python scripts/plain_accuracy.py`` (docs/report/plain_inputs.md holds its rows).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_PROGRESS = re.compile(r"\d+%\|.*\|")  # a tqdm bar

VIEWER = r"""
import json, os, sys, time
import numpy as np
from warp_sg.scene.importers.asset import asset_scene
from warp_sg.tools.preview import open_viewer
asset, env, w, h, drag = sys.argv[1], sys.argv[2] or None, int(sys.argv[3]), int(sys.argv[4]), sys.argv[5] == "1"
sc, _ = asset_scene(asset, env=env, width=w, height=h)
t0, c0 = time.perf_counter(), time.process_time()
on_screen = bool(os.environ.get("DISPLAY"))
v = open_viewer(sc, off_screen=not on_screen, progressive=True, progress=False, widgets=False)
opened = time.perf_counter() - t0
if on_screen:
    v.plotter.show(interactive_update=True, auto_close=False)
it = v.plotter.iren.interactor
it.Initialize()
step = [0]
def between():
    if drag:
        a = 0.05 * step[0]
        it.SetEventPosition(int(w / 2 + 0.2 * w * np.cos(a)), int(h / 2 + 0.2 * h * np.sin(a)))
        it.LeftButtonPressEvent() if step[0] == 0 else it.MouseMoveEvent()
        step[0] += 1
ok = v.run(until=lambda: not v.viewport._awaiting, timeout=900, between=between)
print(json.dumps({"opened_s": opened, "shadows_s": time.perf_counter() - t0 if ok else None,
                  "cpu_s": time.process_time() - c0, "frames": v.viewport.frames, "window": on_screen}))
v.close()
"""


def _load() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:  # pragma: no cover
        return float("nan")


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _env(repo, kernels, cache):
    env = {**os.environ, "WARP_SG_CACHE_DIR": str(cache), "WARP_CACHE_PATH": str(kernels)}
    env["PYTHONPATH"] = str(repo) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def _cache(tables):
    """A fresh precompute cache folder holding only ``tables`` (the asset-independent tables a first
    run built, which any earlier render leaves on a machine), or nothing."""
    d = tempfile.TemporaryDirectory()
    if tables is not None and Path(tables).is_dir():
        shutil.copytree(tables, Path(d.name) / "tables")
    return d


def cli_run(a, kernels, tmp, first_frame: bool, tables=None) -> dict:
    """One ``warp-sg render`` (module docstring): wall, CPU, first frame, stray stderr lines; the
    tables a first run built are kept in ``tmp/tables`` (``tables``: start from them)."""
    out, first = Path(tmp) / "out.png", Path(tmp) / "first.png"
    for p in (out, first):
        p.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "warp_sg.tools.cli", "render", a.asset, "-o", str(out), "--width", str(a.size[0]),
           "--height", str(a.size[1]), "--timings"] + (["--env", a.env] if a.env else []) + \
          (["--first-frame", str(first)] if first_frame else [])
    with _cache(tables) as cache:
        load, c0, t0 = _load(), _child_cpu(), time.perf_counter()
        proc = subprocess.Popen(cmd, env=_env(a.repo, kernels, cache), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        t_first = None
        while proc.poll() is None:
            if first_frame and t_first is None and first.exists():
                t_first = time.perf_counter() - t0
            time.sleep(0.01)
        wall = time.perf_counter() - t0
        stdout, stderr = proc.communicate()
        if tables is None and (Path(cache) / "tables").is_dir() and not (Path(tmp) / "tables").exists():
            shutil.copytree(Path(cache) / "tables", Path(tmp) / "tables")
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{stderr}")
    if first_frame and t_first is None:
        t_first = wall
    pre = re.search(r"precompute ([0-9.]+) s", stdout)
    stray = [ln for ln in stderr.replace("\r", "\n").splitlines() if ln.strip() and not _PROGRESS.search(ln)
             and not ln.startswith("warp-sg: ") and not ln.startswith("first frame written to")
             and not ln.strip().startswith("\x1b[A")]
    return {"wall_s": wall, "cpu_s": _child_cpu() - c0, "first_frame_s": t_first, "load": load,
            "precompute_s": float(pre.group(1)) if pre else None, "stray_stderr": stray}


def warm_frame(a, kernels, tables) -> dict:
    code = ("import statistics, sys, time; from warp_sg.scene.importers.asset import asset_scene; "
            "from warp_sg.renderer.renderer import Renderer; "
            "sc, _ = asset_scene(sys.argv[1], env=sys.argv[2] or None, width=int(sys.argv[3]), height=int(sys.argv[4])); "
            "r = Renderer(sc); r.render(); r.render(); ts = []\n"
            "for _ in range(3):\n t = time.perf_counter(); c = time.process_time(); r.render(); "
            "ts.append((time.perf_counter() - t, time.process_time() - c))\n"
            "print(statistics.median(x[0] for x in ts), statistics.median(x[1] for x in ts))")
    with _cache(tables) as cache:
        r = subprocess.run([sys.executable, "-c", code, a.asset, a.env or "", *map(str, a.size)],
                           env=_env(a.repo, kernels, cache), capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    wall, cpu = map(float, r.stdout.split()[-2:])
    return {"wall_s": wall, "cpu_s": cpu}


def viewer_run(a, kernels, drag: bool, tables) -> dict:
    with _cache(tables) as cache:
        load, c0 = _load(), _child_cpu()
        r = subprocess.run([sys.executable, "-c", VIEWER, a.asset, a.env or "", *map(str, a.size), "1" if drag else "0"],
                           env=_env(a.repo, kernels, cache), capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    return {**json.loads(r.stdout.strip().splitlines()[-1]), "load": load, "child_cpu_s": _child_cpu() - c0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("asset", nargs="?", default=None, help="asset file (default: the generated textured helmet)")
    ap.add_argument("--env", default=None, help="environment map (default: the procedural sky)")
    ap.add_argument("--size", type=int, nargs=2, default=(512, 384), metavar=("W", "H"))
    ap.add_argument("--repo", default=str(Path(__file__).resolve().parents[1]), help="checkout whose code runs")
    ap.add_argument("--no-viewer", action="store_true", help="skip the viewer's runs")
    ap.add_argument("--json", default=None, help="also write the results here")
    a = ap.parse_args(argv)
    res: dict = {}
    with tempfile.TemporaryDirectory(prefix="wsg-first-run-") as tmp:
        if a.asset is None:
            sys.path.insert(0, a.repo)
            from warp_sg.tools.bench_assets import textured_helmet

            a.asset = str(textured_helmet(Path(tmp) / "helmet.glb", triangles=16000))
        k1, k2 = Path(tmp) / "kernels1", Path(tmp) / "kernels2"
        res["first-ever render"] = cli_run(a, k1, tmp, first_frame=False)
        res["first-ever progressive"] = cli_run(a, k2, tmp, first_frame=True)
        tables = Path(tmp) / "tables"
        res["kernels compiled, cold precompute"] = cli_run(a, k1, tmp, first_frame=False, tables=tables)
        res["kernels compiled, progressive"] = cli_run(a, k1, tmp, first_frame=True, tables=tables)
        res["warm frame"] = warm_frame(a, k1, tables)
        if not a.no_viewer:
            res["viewer, idle"] = viewer_run(a, k1, False, tables)
            res["viewer, dragging"] = viewer_run(a, k1, True, tables)
    pre = res["kernels compiled, cold precompute"]["precompute_s"]
    rows = [("first-ever render", res["first-ever render"]["wall_s"], res["first-ever render"]["cpu_s"], 25.0),
            ("first-ever progressive first frame", res["first-ever progressive"]["first_frame_s"], None, 3.0),
            ("first-ever progressive final frame", res["first-ever progressive"]["wall_s"],
             res["first-ever progressive"]["cpu_s"], None),
            ("kernels compiled, cold precompute", res["kernels compiled, cold precompute"]["wall_s"],
             res["kernels compiled, cold precompute"]["cpu_s"], 15.0),
            ("kernels compiled, progressive first frame", res["kernels compiled, progressive"]["first_frame_s"], None,
             3.0),
            ("warm frame", res["warm frame"]["wall_s"], res["warm frame"]["cpu_s"], None)]
    for k in ("viewer, idle", "viewer, dragging"):
        if k in res:
            rows.append((f"{k}: shadows shown", res[k]["shadows_s"], res[k]["cpu_s"], (pre or 0.0) + 3.0))
    print(f"asset {Path(a.asset).name}, {a.size[0]}x{a.size[1]}, env {a.env or 'procedural sky'}, code {a.repo}, "
          f"{os.cpu_count()} cores; load average before the runs: "
          + ", ".join(f"{v['load']:.1f}" for v in res.values() if "load" in v))
    print("| run | wall (s) | CPU (s) | target (s) | met |\n|---|---:|---:|---:|---|")
    for name, wall, cpu, target in rows:
        met = "" if target is None or wall is None else ("yes" if wall <= target else "no")
        print(f"| {name} | {'—' if wall is None else f'{wall:.2f}'} | {'' if cpu is None else f'{cpu:.1f}'} | "
              f"{'' if target is None else f'{target:.1f}'} | {met} |")
    stray = [ln for k, v in res.items() for ln in v.get("stray_stderr", [])]
    print(f"CLI precompute (kernels compiled): {pre} s; stray stderr lines: {len(stray)}")
    for ln in stray[:20]:
        print("  " + ln)
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

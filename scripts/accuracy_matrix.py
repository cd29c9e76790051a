"""The renderer against the stored Mitsuba references of the accuracy matrix, per region.

    python scripts/accuracy_matrix.py [--only NAME ...] [--write-baseline] [--json OUT]

Prints, per case, each region's bias and rel. MSE against tests/data/mitsuba/NAME.npz, the targets
it misses and the regions worse than tests/data/accuracy_baseline.json; ``--write-baseline`` writes
the figures measured as the new baseline (do it in the commit that improves them).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from tqdm import tqdm

from warp_sg.groundtruth import accuracy_matrix as AM


def measure(cases, tmp) -> dict:
    out = {}
    todo = [c for c in cases if AM.reference_path(c).is_file()]
    bar = tqdm(total=len(todo), desc="renderer", unit="scene")
    for key, group in AM.groups(todo).items():
        imgs = AM.render_group(group, tmp)
        for c in group:
            out[c.name] = AM.errors(c, imgs[c.name])
            bar.update(1)
    bar.close()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--write-baseline", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    cases = [AM.BY_NAME[n] for n in a.only] if a.only else list(AM.CASES)
    with tempfile.TemporaryDirectory() as tmp:
        res = measure(cases, Path(tmp))
    base = AM.load_baseline()
    fails, worse = [], []
    print(f"{'case':44s} " + " ".join(f"{r:>22s}" for r in AM.REGIONS))
    for c in cases:
        if c.name not in res:
            continue
        e = res[c.name]
        cells = [f"{e[r]['bias']:+7.1%} {e[r]['rel_mse']:8.4f} ({e[r]['pixels']:4d})" if r in e else " " * 22
                 for r in AM.REGIONS]
        print(f"{c.name:44s} " + " ".join(cells))
        fails += AM.target_failures(c, e)
        worse += AM.gate_failures(c, e, base)
    print(f"\n{len(res)} cases; targets missed: {len(fails)}")
    for f in fails:
        print("  " + f)
    print(f"worse than the baseline: {len(worse)}")
    for w in worse:
        print("  " + w)
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    if a.write_baseline:
        merged = {**base, **{k: {r: {"bias": round(v["bias"], 5), "rel_mse": round(v["rel_mse"], 6)}
                                 for r, v in e.items()} for k, e in res.items()}}
        AM.BASELINE.write_text(json.dumps(dict(sorted(merged.items())), indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

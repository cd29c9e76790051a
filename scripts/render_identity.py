"""Render the examples small and compare the images bit for bit with an earlier run.

A restructuring (modules moved, files split) must not change a single pixel. This script renders
every scene of ``examples/*.toml`` (the batch jobs and the fit's views aside) and the example asset
``examples/assets/still_life.glb`` with the command line at a small size into EXR (linear HDR,
float32, so every bit survives), and with ``--compare DIR`` checks each image against the one of
the same name in ``DIR`` (an earlier run of this script):

    python scripts/render_identity.py /tmp/before                 # before the change
    python scripts/render_identity.py /tmp/after --compare /tmp/before

Exit status 0 when every image is bit-identical, 1 otherwise (the differing images are named, with
the largest absolute difference and the number of differing pixels).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def jobs() -> list[tuple[str, list[str]]]:
    """(image name, command-line arguments after ``render``) for every example."""
    out = []
    for toml in sorted((ROOT / "examples").glob("*.toml")):
        if toml.stem.endswith(("_job", "_views")):
            continue  # a batch job (``warp-sg batch``) or a fit's photographs (``warp-sg fit``), not a scene
        out.append((toml.stem, [str(toml)]))
    out.append(("still_life_glb", [str(ROOT / "examples" / "assets" / "still_life.glb")]))
    return out


def render_all(dest: Path, width: int, height: int) -> list[Path]:
    dest.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, args in jobs():
        path = dest / f"{name}.exr"
        cmd = [str(Path(sys.executable).with_name("warp-sg")), "render", *args,
               "--width", str(width), "--height", str(height), "--no-progress", "-o", str(path)]
        subprocess.run(cmd, check=True, cwd=ROOT)
        paths.append(path)
    return paths


def read_exr(path: Path) -> np.ndarray:
    """Every channel of an EXR file, stacked in name order (read with OpenEXR, not the package)."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        chans = {name: np.asarray(ch.pixels) for name, ch in f.channels().items()}
    return np.stack([chans[k] for k in sorted(chans)], axis=-1)


def compare(paths: list[Path], reference: Path) -> list[str]:
    bad = []
    for path in paths:
        ref = reference / path.name
        if not ref.exists():
            bad.append(f"{path.name}: no image of that name in {reference}")
            continue
        a, b = read_exr(path), read_exr(ref)
        if a.shape != b.shape:
            bad.append(f"{path.name}: shape {a.shape} != {b.shape}")
        elif not np.array_equal(a.view(np.uint8), b.view(np.uint8)):
            diff = np.abs(a.astype(np.float64) - b)
            bad.append(f"{path.name}: max |diff| {diff.max():.3g}, {int((diff > 0).any(axis=-1).sum())} pixels differ")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dest", type=Path, help="folder for the images")
    ap.add_argument("--compare", type=Path, metavar="DIR", help="an earlier run's folder to compare with")
    ap.add_argument("--width", type=int, default=96)
    ap.add_argument("--height", type=int, default=72)
    a = ap.parse_args(argv)
    paths = render_all(a.dest, a.width, a.height)
    if a.compare is None:
        print(f"{len(paths)} images in {a.dest}")
        return 0
    bad = compare(paths, a.compare)
    for line in bad:
        print(line)
    print(f"{len(paths) - len(bad)} of {len(paths)} images bit-identical to {a.compare}")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())

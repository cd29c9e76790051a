"""Generate the small assets of the example scenes into ``examples/assets/`` (committed; rerun to rebuild).

* ``albedo.png``    sRGB colour tiles with thin grout lines (a spatially varying ``kd``/``ks``)
* ``roughness.png`` linear grey: smooth tiles, rough grout and a radial gradient (mapped to ``m``)
* ``normal.png``    tangent-space normal map of rounded tile bumps (``2·rgb − 1``, z up)
* ``tangent.png``   tangent map: a swirl of tangent directions (``(2r − 1, 2g − 1)`` in the tangent plane)
* ``blob.obj``      a lumpy sphere (icosphere with a smooth radial displacement), to show mesh loading

Usage: ``python examples/make_assets.py``. Pure numpy + Pillow + trimesh, deterministic.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

OUT = Path(__file__).resolve().parent / "assets"
N = 128  # texture size
TILES = 4  # tiles per side


def _uv(n=N):
    """Texel-centre UVs, row 0 at the top of the image (v = 1)."""
    c = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(c, 1.0 - c)
    return u, v


def _tiles():
    u, v = _uv()
    fu, fv = (u * TILES) % 1.0, (v * TILES) % 1.0
    iu, iv = np.floor(u * TILES).astype(int), np.floor(v * TILES).astype(int)
    edge = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv))  # distance to the tile border
    return u, v, fu, fv, iu, iv, edge


def albedo():
    _, _, _, _, iu, iv, edge = _tiles()
    palette = np.array([[0.80, 0.25, 0.15], [0.90, 0.75, 0.30], [0.20, 0.45, 0.75], [0.30, 0.65, 0.35],
                        [0.85, 0.85, 0.80], [0.55, 0.30, 0.60]])
    col = palette[(iu * 3 + iv * 5) % len(palette)]
    grout = (edge < 0.04)[..., None]
    col = np.where(grout, [0.12, 0.11, 0.10], col)
    return (np.clip(col, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)  # ~sRGB encode


def roughness():
    u, v, _, _, _, _, edge = _tiles()
    r = 0.25 + 0.5 * np.hypot(u - 0.5, v - 0.5)  # smoother in the middle
    r = np.where(edge < 0.04, 1.0, r)
    return (np.clip(r, 0, 1) * 255 + 0.5).astype(np.uint8)


def normal():
    _, _, fu, fv, _, _, edge = _tiles()
    # height: rounded tile tops, falling off within 0.15 of the border
    h = np.clip(edge / 0.15, 0, 1)
    h = h * h * (3 - 2 * h)
    step = 1.0 / N
    dhdu = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) / (2 * step)
    dhdv = -(np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) / (2 * step)  # rows go down in v
    amp = 0.02
    n = np.stack([-amp * dhdu, -amp * dhdv, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return ((n * 0.5 + 0.5) * 255 + 0.5).astype(np.uint8)


def tangent():
    u, v = _uv()
    a = np.arctan2(v - 0.5, u - 0.5) + np.pi / 2 + 3.0 * np.hypot(u - 0.5, v - 0.5)  # swirl
    t = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], -1)
    return ((t * 0.5 + 0.5) * 255 + 0.5).astype(np.uint8)


def blob():
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    d = m.vertices
    r = 1.0 + 0.12 * np.sin(3 * d[:, 0]) * np.sin(3 * d[:, 1] + 1.0) * np.sin(3 * d[:, 2] + 2.0) \
        + 0.08 * np.sin(5 * d[:, 1])
    m = trimesh.Trimesh(vertices=d * r[:, None], faces=m.faces, process=False)
    return m


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    Image.fromarray(albedo(), "RGB").save(OUT / "albedo.png", optimize=True)
    Image.fromarray(roughness(), "L").save(OUT / "roughness.png", optimize=True)
    Image.fromarray(normal(), "RGB").save(OUT / "normal.png", optimize=True)
    Image.fromarray(tangent(), "RGB").save(OUT / "tangent.png", optimize=True)
    blob().export(OUT / "blob.obj", include_normals=True)
    for f in sorted(OUT.iterdir()):
        print(f"{f.relative_to(OUT.parent.parent)}  {f.stat().st_size / 1024:.1f} KiB")


if __name__ == "__main__":
    main()

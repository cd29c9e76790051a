r"""What a fit writes: the scene file with the fitted values, its textures and environment map as
EXR beside it, and the loss-against-iteration plot.

* The scene file is the input document with every fitted key replaced (constants by their values,
  textures by ``{ texture = "STEM_NAME_PARAM.exr" }``, an environment light by its mixture on a
  64 × 128 map, ``file = "STEM_env.exr"``, its rotation and scale kept) and every file path of the
  document (meshes, textures, maps) re-expressed relative to the output's folder, so that
  ``warp-sg render`` reads it as it is.
* Every file is written atomically (:func:`warp_sg.core.files.atomic_output`): a stopped fit leaves
  the last complete files, never half of one.
"""
from __future__ import annotations

import copy
import os
from pathlib import Path

import numpy as np

from warp_sg.core.files import atomic_output

#: keys whose string values are file paths (relative to the scene file)
PATH_KEYS = ("mesh", "file", "texture", "normal_map", "tangent_map")
_FILE_SUFFIXES = (".png", ".exr", ".hdr", ".jpg", ".jpeg", ".tif", ".tiff", ".binary", ".obj", ".ply", ".glb",
                  ".gltf", ".stl", ".off", ".usd", ".usda", ".usdc", ".usdz")


def resize(a: np.ndarray, h: int, w: int) -> np.ndarray:
    """(H, W, C) resampled to (h, w, C): area average when shrinking, bilinear when growing."""
    import cv2

    a = np.asarray(a, np.float32)
    if a.shape[:2] == (h, w):
        return a.astype(np.float64)
    interp = cv2.INTER_AREA if h < a.shape[0] else cv2.INTER_LINEAR
    out = cv2.resize(a, (int(w), int(h)), interpolation=interp)
    return out.reshape(h, w, a.shape[2]).astype(np.float64)


def _is_path(key: str, v) -> bool:
    return isinstance(v, str) and (key in PATH_KEYS or key.endswith("_map") or Path(v).suffix.lower() in _FILE_SUFFIXES)


def rebase_paths(node, src: Path, dst: Path, key: str = ""):
    """A copy of the document ``node`` with every file path that exists relative to folder ``src``
    re-expressed relative to folder ``dst``."""
    if isinstance(node, dict):
        return {k: rebase_paths(v, src, dst, k) for k, v in node.items()}
    if isinstance(node, list):
        return [rebase_paths(v, src, dst, key) for v in node]
    if _is_path(key, node) and not Path(node).is_absolute() and (src / node).exists():
        return os.path.relpath(src / node, dst)
    return node


def write_scene(out: Path, doc: dict, scene_dir: Path, frees, stem: str) -> list[Path]:
    """Write the fitted scene file ``out`` and its EXR files (module docstring); returns the files."""
    from warp_sg.core.image_io import save_image
    from warp_sg.inverse.env_basis import basis_map
    from warp_sg.renderer.gradient_keys import set_leaf
    from warp_sg.scene.importers.asset import scene_toml

    folder = out.parent
    d = rebase_paths(copy.deepcopy(doc), scene_dir, folder)
    files = []
    for f in frees:
        v = f.value
        if f.kind == "constant":
            d["materials"][f.owner] = set_leaf(d["materials"][f.owner], f.leaf, v.tolist() if v.ndim else float(v))
        elif f.kind == "texture":
            name = f"{stem}_{f.owner}_{f.leaf}.exr"
            h, w = f.extra["size"]
            img = resize(v, h, w)
            save_image(folder / name, np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img)
            d["materials"][f.owner][f.leaf] = {"texture": name}
            files.append(folder / name)
        elif f.kind == "environment":
            name = f"{stem}_env.exr"
            save_image(folder / name, basis_map(f.extra["axes"], f.extra["lam"], v))
            old = d["lights"][f.owner]
            d["lights"][f.owner] = {"type": "environment", "file": name,
                                    **{k: old[k] for k in ("scale", "rotation") if k in old}}
            files.append(folder / name)
        else:
            d["lights"][f.owner][f.leaf] = v.tolist()
    text = scene_toml(d, header=f"fitted by `warp-sg fit` ({', '.join(f.key for f in frees)})")
    with atomic_output(out) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return [out, *files]


def plot_loss(path: Path, losses) -> Path:
    """The loss against the iteration (log scale), a PNG written atomically."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.2), dpi=120)
    ax.semilogy(np.arange(1, len(losses) + 1), np.maximum(np.asarray(losses, np.float64), 1e-30))
    ax.set_xlabel("iteration")
    ax.set_ylabel("loss (relative squared error)")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path


__all__ = ["write_scene", "plot_loss", "rebase_paths", "resize", "PATH_KEYS"]

"""Accuracy on real inputs: the SG renderer against our Monte-Carlo reference, per region, on the
HDRIs and glTF assets a user brings (Poly Haven maps and three.js's glTF examples).

    python scripts/real_assets.py [--assets ../shared/assets] [--size 256] [--spp 1024] [--max-depth 8]
                                  [--cases sphere:ggx0.2:pedestrian_overpass_1k,...] [--out docs/report]

Each case puts one object on a 2-triangle floor (the floor is named ``floor``: the lit floor and
the shadow are regions of :mod:`warp_sg.groundtruth.region_error`) under one HDRI, frames it as ``warp-sg render
ASSET --env SKY`` does (:mod:`warp_sg.scene.importers.asset`) and compares the default render with the
box-filtered reference (:func:`warp_sg.groundtruth.region_error.box_reference`): a full path tracer by default
(``--max-depth 2``: direct light only, against renders with ``[render] bounces = 0``, the paper's part alone).
Objects: ``sphere`` (a 1280-triangle
icosphere, written by the script) or a file of the assets folder by its stem (``LeePerrySmith``,
``ShaderBall``, ...). Materials: a key of :data:`MATERIALS` overrides the file's (``own`` keeps a
glTF's own materials). It writes ``real_assets.md`` with the per-region table (bias, relative MSE)
of every case and, per case, ours / the reference / a heat map of the signed relative luminance
error side by side (``real_assets/<case>.png``). With the ``[compare]`` extra installed the table
also gives Mitsuba 3's error and time at the same spp (``warp_sg.tools.peer_mitsuba``).

The files are not shipped with the repository (their licences differ): the script reads them from
``--assets`` (default ``../shared/assets`` beside the checkout) and skips the cases whose files are
missing, saying so.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from warp_sg.scene.plain_scenes import MATERIALS as PLAIN_MATERIALS  # noqa: E402

#: materials of the object (TOML tables), by name: the plain scenes' glossy models and GGX
MATERIALS = {
    **PLAIN_MATERIALS,
    "ggx0.05": {"model": "ggx", "alpha": 0.05, "fresnel": "gold"},
    "ggx0.2": {"model": "ggx", "alpha": 0.2, "fresnel": "gold"},
    "ggx0.5": {"model": "ggx", "alpha": 0.5, "fresnel": "gold"},
    "ggx_aniso": {"model": "ggx", "alpha_x": 0.3, "alpha_y": 0.08, "fresnel": "gold"},
}
FLOOR = {"model": "lambert", "kd": [0.45, 0.45, 0.45]}
HDRIS = ("pedestrian_overpass_1k", "venice_sunset_1k", "moonless_golf_1k", "blouberg_sunrise_2_1k", "spot1Lux")
#: the default matrix: every glossy model and GGX at three roughnesses under the stiff sun, Lambert
#: under every map, and the scanned head, Lambert and gold GGX, under every map
DEFAULT_CASES = (
    [f"sphere:lambert:{h}" for h in HDRIS]
    + [f"sphere:{m}:pedestrian_overpass_1k" for m in ("ggx0.05", "ggx0.2", "ggx0.5", "blinn_phong",
                                                      "cook_torrance", "ward", "ggx_aniso")]
    + ["sphere:ggx0.2:venice_sunset_1k", "sphere:ggx0.2:moonless_golf_1k"]
    + [f"LeePerrySmith:{m}:{h}" for m in ("lambert", "ggx0.2") for h in HDRIS]
)
VIEW = (30.0, 25.0)


def _sphere_file(folder: Path) -> Path:
    from warp_sg.scene.plain_scenes import write_sphere_ply

    return write_sphere_ply(folder / "sphere.ply")


def case_scene(case: str, assets: Path, folder: Path, size: int):
    """The :class:`~warp_sg.scene.Scene` of ``object:material:hdri`` (module docstring), or None with
    the reason when a file is missing."""
    from warp_sg.scene.importers.asset import asset_scene_dict, scene_from_dict

    obj, mat, hdri = case.split(":")
    sky = assets / f"{hdri}.hdr"
    if not sky.is_file():
        return None, f"{sky} not found"
    if obj == "sphere":
        path = _sphere_file(folder)
    else:
        found = sorted(assets.glob(f"{obj}.*"))
        if not found:
            return None, f"{obj}.* not found in {assets}"
        path = found[0]
    doc = asset_scene_dict(path, env=sky, view=VIEW, width=size, height=size)
    ob, ground = doc["objects"]
    if mat != "own":
        ob["material"] = "object"
        doc["materials"]["object"] = dict(MATERIALS[mat])
    ground.update(name="floor", material="floor", resolution=[1, 1])  # two triangles, as exported
    doc["materials"]["floor"] = dict(FLOOR)
    doc["materials"].pop("ground", None)
    return scene_from_dict(doc), ""


def heat_map(img, ref, lim: float = 0.25):
    """(H, W, 3) uint8: the signed relative luminance error ``img/ref − 1`` in a diverging map
    (blue dark, red bright, ±``lim`` saturated); pixels whose reference is below 1 % of the image's
    mean luminance are grey."""
    import matplotlib

    from warp_sg.core.image_io import LUMINANCE as LUMA

    li, lr = np.asarray(img) @ LUMA, np.asarray(ref) @ LUMA
    rel = np.where(lr > 0.01 * lr.mean(), li / np.maximum(lr, 1e-30) - 1.0, 0.0)
    cm = matplotlib.colormaps["RdBu_r"]
    out = (cm(np.clip(rel / (2 * lim) + 0.5, 0.0, 1.0))[..., :3] * 255).astype(np.uint8)
    out[lr <= 0.01 * lr.mean()] = 128
    return out


def side_by_side(path: Path, img, ref, exposure: float):
    from PIL import Image

    from warp_sg.core.image_io import tonemap_srgb

    a = (tonemap_srgb(img, exposure) * 255).astype(np.uint8)
    b = (tonemap_srgb(ref, exposure) * 255).astype(np.uint8)
    gap = np.full((a.shape[0], 4, 3), 255, np.uint8)
    Image.fromarray(np.concatenate([a, gap, b, gap, heat_map(img, ref)], axis=1)).save(path)


def run_case(case: str, assets: Path, size: int, spp: int, figures: Path | None, mitsuba: bool, max_depth: int = 8):
    import warp_sg as ws
    from warp_sg.groundtruth.reference import matching_transport
    from warp_sg.groundtruth.region_error import box_reference, region_errors, scene_regions

    with tempfile.TemporaryDirectory() as tmp:
        scene, why = case_scene(case, assets, Path(tmp), size)
        if scene is None:
            return {"case": case, "skipped": why}
        scene = matching_transport(scene, max_depth)
        t = time.perf_counter()
        r = ws.Renderer(scene, device="cpu")
        t_pre = time.perf_counter() - t
        r.render()
        img = r.render()
        t_frame = r.timings["frame"]
        t = time.perf_counter()
        ref, se = box_reference(scene, spp=spp, return_stderr=True, max_depth=max_depth)
        t_ref = time.perf_counter() - t
        errs = region_errors(img, ref, scene_regions(scene), stderr=se)
        row = {"case": case, "precompute_s": t_pre, "frame_s": t_frame, "reference_s": t_ref, "spp": spp,
               "max_depth": max_depth, "bounces": int(scene.render.bounces),
               "peaks": len(r.env_peaks), "vertices": int(len(r.geometry.vertices)), "regions": errs,
               "image_rel_mse": float(np.sum((img - ref) ** 2) / max(np.sum(ref ** 2), 1e-300))}
        if mitsuba:
            from warp_sg.tools import peer_mitsuba

            ok, why = peer_mitsuba.mitsuba_status()
            if ok:
                mi, row["mitsuba_s"] = peer_mitsuba.mitsuba_render(
                    peer_mitsuba.mitsuba_scene(scene, approximate=True, max_depth=max_depth), spp)
                row["mitsuba_regions"] = region_errors(mi, ref, scene_regions(scene))
            else:
                row["mitsuba"] = why
        if figures is not None:
            from warp_sg.core.image_io import LUMINANCE as LUMA

            mean = float(np.mean(ref @ LUMA))
            exposure = math.log2(0.18 / mean) if mean > 0 else 0.0
            side_by_side(figures / f"{case.replace(':', '_')}.png", img, ref, exposure)
        return row


def _pct(e, key="bias"):
    v = e.get(key, float("nan"))
    return "–" if e.get("pixels", 0) == 0 or not np.isfinite(v) else f"{100 * v:+.1f} %"


def write_markdown(rows, path: Path, size: int, spp: int, figures_rel: str, max_depth: int = 8):
    lines = [
        "# Accuracy on real inputs",
        "",
        "Poly Haven HDRIs (1024×512 Radiance files: a stiff clear-day sun with its halo, a low sunset sun, a",
        "night map of lamps, a soft sunrise, a black map with one spot) and glTF assets from three.js's examples,",
        "each object on a 2-triangle floor, framed as `warp-sg render ASSET --env SKY` frames it. Default render",
        f"settings, {size}×{size} pixels, against our Monte-Carlo reference box-filtered over each pixel ({spp} samples",
        "per pixel, exact BRDFs and ray-traced visibility, "
        + ("a full path tracer: paths of up to 8 segments with Russian roulette; the renders with their "
           "default `bounces`" if max_depth != 2 else "direct light only; the renders with `bounces = 0`")
        + "). Bias = mean(render)/mean(reference) − 1, worst",
        "channel; relative MSE net of the reference's own noise. Regions: `warp_sg.groundtruth.region_error`.",
        "",
        "Reproduce: `python scripts/real_assets.py` (the assets are read from `../shared/assets`; they are not",
        "shipped). Figures: ours | reference | signed relative luminance error (blue: ours darker, red: brighter,",
        "±25 % saturated).",
        "",
        "| case | peaks | object bias | object rel. MSE | lit floor bias | shadow bias (leak of lit) | silhouette bias |"
        " precompute | frame |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        if "skipped" in row:
            lines.append(f"| {row['case']} | skipped: {row['skipped']} | | | | | | | |")
            continue
        e = row["regions"]
        sh = e["shadow"]
        leak = f" ({100 * sh['leak']:+.1f} %)" if "leak" in sh and sh.get("pixels", 0) else ""
        lines.append(f"| {row['case']} | {row['peaks']} | {_pct(e['object'])} | {e['object']['rel_mse']:.4f} | "
                     f"{_pct(e['lit_floor'])} | {_pct(sh)}{leak} | {_pct(e['silhouette'])} | "
                     f"{row['precompute_s']:.1f} s | {1000 * row['frame_s']:.0f} ms |")
    if any("mitsuba_regions" in r for r in rows):
        lines += ["", "Mitsuba 3 (`roughconductor` for GGX: the same NDF with a separable Smith term, a peer, not a",
                  "twin) at the same spp against the same reference:", "",
                  "| case | object bias | object rel. MSE | lit floor bias | time |", "|---|---|---|---|---|"]
        for row in rows:
            if "mitsuba_regions" in row:
                e = row["mitsuba_regions"]
                lines.append(f"| {row['case']} | {_pct(e['object'])} | {e['object']['rel_mse']:.4f} | "
                             f"{_pct(e['lit_floor'])} | {row['mitsuba_s']:.1f} s |")
    lines += ["", "## Images", ""]
    for row in rows:
        if "skipped" not in row:
            lines += [f"### {row['case']}", "", f"![{row['case']}]({figures_rel}/{row['case'].replace(':', '_')}.png)", ""]
    path.write_text("\n".join(lines) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--assets", type=Path, default=ROOT.parent / "shared" / "assets")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--cases", default=",".join(DEFAULT_CASES))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "report")
    ap.add_argument("--mitsuba", action="store_true", help="also render with Mitsuba 3 ([compare] extra)")
    ap.add_argument("--max-depth", type=int, default=8,
                    help="the reference's path segments (default 8: a full path tracer; 2: direct light only, "
                         "against renders with bounces = 0)")
    a = ap.parse_args(argv)
    figures = a.out / "real_assets"
    figures.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in a.cases.split(","):
        row = run_case(case, a.assets, a.size, a.spp, figures, a.mitsuba, a.max_depth)
        rows.append(row)
        if "skipped" in row:
            print(f"{case}: skipped ({row['skipped']})", flush=True)
        else:
            e = row["regions"]
            print(f"{case}: object {_pct(e['object'])}, lit floor {_pct(e['lit_floor'])}, shadow {_pct(e['shadow'])}"
                  f" ({row['precompute_s']:.1f} s precompute, {row['reference_s']:.0f} s reference)", flush=True)
        write_markdown(rows, a.out / "real_assets.md", a.size, a.spp, "real_assets", a.max_depth)  # rows as they finish
        (a.out / "real_assets.json").write_text(json.dumps(rows, indent=1, default=float))
    return rows


if __name__ == "__main__":
    main()

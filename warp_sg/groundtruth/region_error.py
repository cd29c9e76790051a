r"""Error per image region and as bias (issue 11; docs/rendering.md "Error per region and as bias").

One image-wide relative MSE hides a 15 % dark floor behind a correct sky. :func:`scene_regions`
splits a scene's pixels into

* ``object`` — pixels whose every sub-sample sees an object other than the floor;
* ``lit_floor`` / ``shadow`` — pixels whose every sub-sample sees the floor, split by an exact
  ``wp.Mesh`` shadow ray (through the holes of alpha cut-outs, :mod:`warp_sg.shading.cutout`) from the
  pixel centre's surface point towards the scene's key light
  (the brightest point/directional light, else the environment's brightest texel);
* ``silhouette`` — pixels whose sub-samples see different objects or the background (the band
  where antialiasing and grazing shading matter);

from a 4×4-supersampled rasterisation of the scene's own geometry (samples that see the hole of an
alpha cut-out see what is behind it, :func:`warp_sg.shading.cutout.see_through`). "The floor" is the object
named ``floor`` (else none: every object pixel is ``object``; ``scene_regions(floor=...)`` names
others, e.g. ``("ground",)`` for the ground plane an asset scene adds).

:func:`image_errors` gives the image-wide errors (relative MSE, PSNR of the tone-mapped images,
max error); :func:`region_errors` then gives, per region: ``rel_mse`` = Σ(x − r)²/Σr², ``bias`` = the
worst channel (by magnitude) of mean(x)/mean(r) − 1, and ``off3`` = the fraction of pixels whose
luminance is off by more than 3× either way (the "sparkle" count, with a floor of 1 % of the
region's mean so near-black pixels do not count). The shadow also gets ``leak``: its mean error
as a fraction of the lit floor's mean (a shadow lit by nothing else is black, and a relative
bias of a black region says little).
"""
from __future__ import annotations

import math

import numpy as np

REGIONS = ("object", "lit_floor", "shadow", "silhouette")
from warp_sg.core.image_io import LUMINANCE as LUMA  # noqa: E402


def _key_light(scene):
    """(kind, vector) of the key light: ("directional", towards-light) or ("point", position)."""
    from warp_sg.scene.lights import DirectionalLight, PointLight

    best, score = None, -1.0
    for li in scene.local_lights:
        if isinstance(li, DirectionalLight):
            s = float(LUMA @ li.intensity)
            cand = ("directional", np.asarray(li.direction, np.float64))
        elif isinstance(li, PointLight):
            s = float(LUMA @ li.intensity) / max(float(np.sum(np.asarray(li.position) ** 2)), 1e-9)
            cand = ("point", np.asarray(li.position, np.float64))
        else:
            continue
        if s > score:
            best, score = cand, s
    if best is None and scene.environment is not None:
        from warp_sg.scene.envmap import texel_directions

        env = scene.environment
        base = env.base_radiance()
        lum = base @ LUMA
        j = np.unravel_index(int(np.argmax(lum)), lum.shape)
        d = texel_directions(*lum.shape)[j]
        best = ("directional", env.rotation_matrix() @ d)
    return best


def scene_regions(scene, supersample: int = 4, device: str = "cpu", floor=("floor",)) -> dict[str, np.ndarray]:
    """Boolean (H, W) masks of :data:`REGIONS` for ``scene``'s camera (see the module docstring);
    ``floor``: the names (any case) of the objects that are the floor."""
    import raster
    from precompute.visibility.rays import ray_visibility

    g = scene.geometry()
    cam = scene.camera
    k = int(supersample)
    from warp_sg.shading.cutout import cutout_data, see_through

    cut = cutout_data(g, scene.materials)
    vb = raster.rasterize(g.vertices, g.triangles, cam, device=device, supersample=k)
    if cut is not None:  # samples that see a hole see what is behind it
        see_through(vb, g.vertices, g.triangles, cut, cam.origin, device)
    tri = vb.tri_id.numpy()
    H, W = cam.height, cam.width
    names = {str(x).lower() for x in ((floor,) if isinstance(floor, str) else floor)}
    floor_ids = [i for i, n in enumerate(g.object_names) if str(n).lower() in names]
    obj = np.where(tri >= 0, g.tri_object[np.maximum(tri, 0)], -1)
    blocks = obj.reshape(H, k, W, k).transpose(0, 2, 1, 3).reshape(H, W, k * k)
    same = np.all(blocks == blocks[..., :1], axis=-1)
    is_floor = np.isin(blocks[..., 0], floor_ids) & same
    is_object = (blocks[..., 0] >= 0) & ~np.isin(blocks[..., 0], floor_ids) & same
    silhouette = ~same
    # surface points of floor pixels: the sub-sample nearest the pixel centre
    c = k // 2
    t = tri[c::k, c::k]
    bc = vb.bary.numpy()[c::k, c::k]
    sel = is_floor & (t >= 0)
    lit = np.zeros((H, W), bool)
    key = _key_light(scene)
    if key is not None and np.any(sel):
        f = g.triangles[t[sel]]
        b1, b2 = bc[sel, 0:1], bc[sel, 1:2]
        P = g.vertices[f[:, 0]] * (1 - b1 - b2) + g.vertices[f[:, 1]] * b1 + g.vertices[f[:, 2]] * b2
        N = g.normals[f[:, 0]] * (1 - b1 - b2) + g.normals[f[:, 1]] * b1 + g.normals[f[:, 2]] * b2
        N /= np.linalg.norm(N, axis=-1, keepdims=True)
        if key[0] == "directional":
            D = np.broadcast_to(key[1], P.shape)
        else:
            D = key[1][None, :] - P
            D = D / np.linalg.norm(D, axis=-1, keepdims=True)
        vis = ray_visibility(g.vertices, g.triangles, P, N, D, device=device, cutouts=cut).astype(bool)
        lit[sel] = vis
    else:
        lit = sel
    return {"object": is_object, "lit_floor": sel & lit, "shadow": sel & ~lit, "silhouette": silhouette}


def box_reference(scene, spp: int = 1024, supersample: int = 8, device: str = "cpu", seed: int = 0,
                  return_stderr: bool = False, max_depth: int | None = None):
    """The Monte-Carlo reference box-filtered over each pixel: ``supersample``² point-sampled
    sub-pixels (``spp / supersample²`` samples each), averaged — what an antialiased image is
    compared with (the renderer's own supersampling does not matter to it). With
    ``return_stderr``: ``(image, per-pixel standard error)``. ``max_depth``: the paths' most
    segments (:func:`warp_sg.groundtruth.reference.reference`; default a full path tracer, 2:
    direct light only)."""
    import copy

    from warp_sg.groundtruth.reference import DEFAULT_MAX_DEPTH, reference

    max_depth = DEFAULT_MAX_DEPTH if max_depth is None else max_depth

    sc = copy.deepcopy(scene)
    sc.render.supersampling = int(supersample)
    return reference(sc, spp=max(1, int(round(spp / supersample ** 2))), device=device, progress=False, seed=seed,
                     return_stderr=return_stderr, max_depth=max_depth)


def image_errors(img, ref) -> dict:
    """``rel_mse`` (linear), ``psnr_db`` (tone-mapped sRGB in [0,1]) and ``max_err`` (linear)."""
    from warp_sg.core.errors import InputError
    from warp_sg.core.image_io import tonemap_srgb

    img = np.asarray(img, np.float64)
    ref = np.asarray(ref, np.float64)
    if img.shape != ref.shape:
        raise InputError(f"image shape {img.shape} does not match the reference {ref.shape}", where="report")
    diff = img - ref
    denom = float(np.sum(ref * ref))
    rel = float(np.sum(diff * diff) / denom) if denom > 0 else float(np.sum(diff * diff))
    a = tonemap_srgb(img).astype(np.float64)
    b = tonemap_srgb(ref).astype(np.float64)
    mse = float(np.mean((a - b) ** 2))
    psnr = 10.0 * math.log10(1.0 / mse) if mse > 0 else float("inf")
    return {"rel_mse": rel, "psnr_db": psnr, "max_err": float(np.max(np.abs(diff))) if diff.size else 0.0}


def region_errors(img, ref, regions: dict[str, np.ndarray], stderr=None) -> dict[str, dict]:
    """Per region: ``pixels``, ``rel_mse``, ``bias`` (worst channel, signed), ``bias_rgb`` and
    ``off3`` (fraction of pixels off by more than 3× in luminance). With the reference's per-pixel
    standard error ``stderr``, ``rel_mse`` is corrected for the reference's own noise
    (E[(x − r)²] = (x − E r)² + se², so Σ se² is subtracted; ``noise`` reports Σ se² / Σ r²)."""
    img = np.asarray(img, np.float64)
    ref = np.asarray(ref, np.float64)
    se = None if stderr is None else np.asarray(stderr, np.float64)
    out = {}
    for name, m in regions.items():
        n = int(np.count_nonzero(m))
        if n == 0:
            out[name] = {"pixels": 0, "rel_mse": float("nan"), "bias": float("nan"), "bias_rgb": [float("nan")] * 3,
                         "off3": float("nan")}
            continue
        x, r = img[m], ref[m]
        denom = float(np.sum(r * r))
        sq = float(np.sum((x - r) ** 2))
        noise = float(np.sum(se[m] ** 2)) if se is not None else 0.0
        rel = max(sq - noise, 0.0) / denom if denom > 0 else float("nan")
        mr = r.mean(0)
        bias_rgb = np.where(mr > 0, x.mean(0) / np.maximum(mr, 1e-30) - 1.0, np.nan)
        worst = float(bias_rgb[np.nanargmax(np.abs(bias_rgb))]) if np.any(np.isfinite(bias_rgb)) else float("nan")
        lx, lr = x @ LUMA, r @ LUMA
        eps = 0.01 * max(float(lr.mean()), 1e-12)
        ratio = (lx + eps) / (lr + eps)
        off3 = float(np.mean((ratio > 3.0) | (ratio < 1.0 / 3.0)))
        out[name] = {"pixels": n, "rel_mse": rel, "bias": worst, "bias_rgb": bias_rgb.tolist(), "off3": off3}
        if se is not None:
            out[name]["noise"] = noise / denom if denom > 0 else float("nan")
    if out.get("shadow", {}).get("pixels") and out.get("lit_floor", {}).get("pixels"):
        # a shadow lit by nothing else is ~black: its relative bias is ill-conditioned, so also
        # give the shadow's error as a fraction of the lit floor's level
        m, lit = regions["shadow"], regions["lit_floor"]
        leak = (img[m].mean(0) - ref[m].mean(0)) / np.maximum(ref[lit].mean(0), 1e-30)
        out["shadow"]["leak"] = float(leak[np.argmax(np.abs(leak))])
    return out


def shadow_centroid(img, unoccluded, floor) -> np.ndarray:
    """``(row, column)`` of the centroid of the darkening ``max(L(U) − L(I), 0)`` (luminance) over
    the ``floor`` pixels, where ``U`` is the same view with the occluder taken away: where a moved
    object's shadow lies (compare ours with the reference's, each with its own ``U``). Pixels
    darkened by less than 20 % of ``U`` do not count (the reference's noise, the faint penumbra of
    the sky)."""
    dark = np.maximum(np.asarray(unoccluded, np.float64) @ LUMA - np.asarray(img, np.float64) @ LUMA, 0.0)
    u = np.asarray(unoccluded, np.float64) @ LUMA
    w = np.where(floor & (dark > 0.2 * u), dark, 0.0)
    if w.sum() <= 0:
        return np.array([np.nan, np.nan])
    yy, xx = np.mgrid[:w.shape[0], :w.shape[1]]
    return np.array([float((w * yy).sum() / w.sum()), float((w * xx).sum() / w.sum())])


def format_region_table(errs: dict[str, dict]) -> str:
    """Markdown table of :func:`region_errors`."""
    rows = ["| region | pixels | rel. MSE | bias | off by >3× |", "|---|---|---|---|---|"]
    for name, e in errs.items():
        leak = f" (leak {100 * e['leak']:+.1f} % of lit)" if "leak" in e else ""
        rows.append(f"| {name} | {e['pixels']} | {e['rel_mse']:.4g} | {100 * e['bias']:+.1f} %{leak} | "
                    f"{100 * e['off3']:.1f} % |")
    return "\n".join(rows)


__all__ = ["REGIONS", "scene_regions", "box_reference", "image_errors", "region_errors", "format_region_table",
           "shadow_centroid"]

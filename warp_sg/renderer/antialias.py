r"""Edge- and contrast-adaptive antialiasing on the device (``[render] antialias = a``).

Every pixel is first shaded once, at its centre, from the 1× visibility buffer (the frame without
antialiasing). Sub-pixel coverage is then found only where it can matter, and those pixels are
shaded again from their a×a sub-pixels and filtered. All in Warp kernels (no per-frame host round
trip, and no a²-sized buffer at all):

1. :func:`~warp_sg.renderer.antialias_candidates.candidates_kernel` flags the pixels that may need
   sub-pixels (:mod:`warp_sg.renderer.antialias_candidates`):

   * **contours** — pixels that a silhouette or boundary edge of the mesh crosses, as seen from
     the eye (:mod:`warp_sg.shading.silhouette`): where a surface passes in front of another, the
     boundary lies on one, also for geometry thinner than a pixel that the pixel centres miss;
   * **object changes** — a 4-neighbour in the 1× buffer sees another object or the background
     (intersections of two objects, which are edges of neither; a mesh passing through itself
     and near/far-plane cuts are flagged only by this or the contrast test);
   * **contrast** — the luminance of the 1× image differs from a 4-neighbour's by more than
     ``CONTRAST`` of the larger one (shadow edges, glints, texture edges).

2. The a×a sub-pixels of the flagged pixels come from the 1× raster itself
   (``raster.rasterize(subsamples=a)`` keeps the triangles that cover only sub-samples, and its
   tile queues; :func:`raster.subsample.subsample` tests just those pixels' sub-samples, with the
   fine raster's exact coverage and depth test): on the frame-scaling scene (100 k triangles,
   512²) 4.5 k pixels in 15 % of the tiles, 2–3 ms, where a second raster of the a×-sized grid
   on the flagged tiles took about 9 ms. A re-shade whose candidates did not change reuses them
   (:class:`AntialiasCache`).
3. :func:`classify_kernel` decides for each flagged pixel: an **edge** when its sub-pixels see
   different objects (or the background), or one object in front of itself — the inverse depths
   ``1/z`` of the block leave the least-squares plane fitted to them by more than
   ``EDGE_DEPTH_RESIDUAL`` of their maximum (1/z is affine in screen space across a flat
   triangle, and nearly so across one pixel of a smooth surface, however grazing). Edge and
   contrast pixels are shaded again (4.); the others keep their centre sample.
4. The second pass takes coverage from all a² sub-pixels and shades only what differs
   (:func:`gather_kernel`): an **edge** pixel once per triangle its sub-pixels see, at the mean of
   their barycentrics and weighted by their share (as MSAA shades once per triangle), and once per
   sub-pixel that sees the background; a **contrast** pixel (one surface whose shading varies)
   first at 4 **probes** (a ≥ 3; for a = 2 at its 4 sub-pixels): the sub-pixels that hold the
   points of Direct3D's standard 4× MSAA pattern, a rotated grid. A glint smaller than a pixel
   needs every sub-pixel, but a shadow edge or a highlight's flank mostly does not:
   :func:`refine_kernel` keeps the probes' mean where they and the centre sample agree within
   ``PROBE_CONTRAST`` (the contrast that flagged the pixel) and shades the other a² − 4
   sub-pixels of the rest in a third pass (:func:`gather_rest_kernel`; the pixel is then the mean
   of all a²). On the frame-scaling scene (100 k triangles, 512²) a quarter of the 3.1 k contrast
   pixels are refined: 30 k samples after the 1× pass where shading every sub-pixel of the
   contrast pixels was 58 k, and the frame's mean error against shading every sub-pixel of the
   image (``supersampling = 4``) is 6.3e-5 instead of 6.2e-5 (the 1× frame's: 1.5e-3; on the sun
   glints of ``tests/test_antialias.py`` 0.0037 of point sampling's error instead of 0.0034).
   A glint that only a sub-pixel off the group's centroid sees is lost at an edge pixel, as with
   MSAA, and one that no probe sees at a contrast pixel. Fewer samples without the refinement
   were tried and dropped: the checkerboard half of the sub-pixels raised the mean error of the
   sun glints 30-fold, the 4 probes alone the plain inputs' shadow-region error by 60 %.

Every kernel is 1-D with a leading ``base`` offset and is launched through
``raster.parallel.launch`` (CPU launches are split over a thread pool): the candidate test over
every pixel (row-major), the rest over the list of candidates (:meth:`Candidates.indices`). The second
pass: per-candidate sample counts → exclusive scan (``wp.utils.array_scan``) → a gather of the
samples' (triangle, barycentrics, background, weight) into a 1 × N list that the ordinary shading
kernel shades → :func:`resolve_kernel` sums each pixel's weighted samples back into the image;
then the contrast pixels whose probes disagree (:func:`refine_kernel`) → scan → their other
sub-pixels (:func:`gather_rest_kernel`) → shading → :func:`resolve_kernel` adds them to 4/a² of
the probes' mean.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import numpy as np
import warp as wp

from warp_sg.brdf.kernel.material_wp import lum
from warp_sg.renderer.antialias_cache import AntialiasCache, same_list
from warp_sg.renderer.antialias_candidates import CAND_CONTRAST, LIST_MIN_CHUNK, Candidates, object_of
from warp_sg.shading.background import Background, background_at

#: relative residual of a block's 1/depth off its fitted plane that makes it an edge
EDGE_DEPTH_RESIDUAL = 0.01
#: relative luminance spread of a contrast pixel's probes (and its centre) that makes it shaded
#: at all its a×a sub-pixels (:func:`refine_kernel`)
PROBE_CONTRAST = 0.2
#: the probes of a contrast pixel, in eighths of a pixel: the rotated grid of 4× MSAA (Direct3D's
#: standard 4-sample pattern), each moved to the a×a sub-pixel that contains it
PROBES_X = wp.constant(wp.vec4i(3, 7, 1, 5))
PROBES_Y = wp.constant(wp.vec4i(1, 3, 5, 7))


@wp.func
def probe_subpixel(j: int, a: int) -> int:
    """Sub-pixel index (row-major in the a×a block) of probe j < 4 of a contrast pixel (a ≥ 3):
    the sub-pixel containing the point (PROBES_X[j], PROBES_Y[j])/8 of the pixel."""
    return (PROBES_Y[j] * a / 8) * a + PROBES_X[j] * a / 8


@wp.func
def _is_probe(q: int, a: int) -> int:
    r = int(0)
    for j in range(4):
        if probe_subpixel(j, a) == q:
            r = 1
    return r


@wp.func
def _first_of_group(sub_tri: wp.array2d(dtype=int), i: int, q: int) -> int:
    """1 when sub-pixel q of listed pixel i (row i of ``raster.subsample``) sees the background or
    is the first of the pixel's sub-pixels to see its triangle."""
    t = sub_tri[i, q]
    first = int(1)
    if t >= 0:
        for p in range(q):
            if sub_tri[i, p] == t:
                first = 0
    return first


@wp.func
def _group_count(sub_tri: wp.array2d(dtype=int), i: int, a: int) -> int:
    """Samples of an edge pixel: one per triangle its sub-pixels see, plus each background one."""
    n = int(0)
    for q in range(a * a):
        n += _first_of_group(sub_tri, i, q)
    return n


@wp.kernel(enable_backward=False)
def classify_kernel(base: int, idx: wp.array(dtype=int), cand: wp.array(dtype=int), sub_tri: wp.array2d(dtype=int),
                    sub_invw: wp.array2d(dtype=float), tri_object: wp.array(dtype=int), a: int, resid_tol: float,
                    edge: wp.array(dtype=int), count: wp.array(dtype=int)):
    """For listed pixel k = ``idx[i]`` (entry i of ``edge`` and ``count``), whether its a×a block
    (row i of ``sub_tri``, ``sub_invw``: the sub-samples' triangles and 1/z, 0 where empty, of
    ``raster.subsample``) is an edge, and its
    second-pass sample count (:func:`gather_kernel`): for an edge one per triangle its sub-pixels
    see plus one per sub-pixel that sees no object, for a contrast pixel its 4 probes (a² for
    a = 2), else 0 (it keeps its
    centre sample). A block that one triangle covers is no edge (1/z is affine across a
    triangle)."""
    i = base + wp.tid()
    k = idx[i]
    edge[i] = 0
    count[i] = 0
    f = cand[k]
    if f == 0:
        return
    t0 = sub_tri[i, 0]
    one = int(1)
    for q in range(a * a):
        if sub_tri[i, q] != t0:
            one = 0
    is_edge = int(0)
    if one == 0:
        o0 = object_of(tri_object, t0)
        # least-squares plane of 1/z over the a×a grid (centred coordinates u, v)
        c = 0.5 * float(a - 1)
        n = float(a * a)
        s = float(0.0)
        su = float(0.0)
        sv = float(0.0)
        wmax = float(0.0)
        for j in range(a):
            for u in range(a):
                if object_of(tri_object, sub_tri[i, j * a + u]) != o0:
                    is_edge = 1
                w = sub_invw[i, j * a + u]
                s += w
                su += w * (float(u) - c)
                sv += w * (float(j) - c)
                wmax = wp.max(wmax, w)
        if is_edge == 0 and wmax > 0.0:
            suu = n * float(a * a - 1) / 12.0  # Σ (i − c)² over the a×a block (a > 1)
            m = s / n
            gu = su / suu
            gv = sv / suu
            for j in range(a):
                for u in range(a):
                    r = sub_invw[i, j * a + u] - (m + gu * (float(u) - c) + gv * (float(j) - c))
                    if wp.abs(r) > resid_tol * wmax:
                        is_edge = 1
    edge[i] = is_edge
    if is_edge == 1:
        count[i] = _group_count(sub_tri, i, a)
    elif (f & CAND_CONTRAST) != 0:
        count[i] = a * a
        if a >= 3:
            count[i] = 4  # its probes first (refine_kernel)


@wp.func
def _gather_one(sub_tri: wp.array2d(dtype=int), sub_bary: wp.array2d(dtype=wp.vec2), background: Background,
                i: int, p: int, sy: int, sx: int, q: int, tri_s: wp.array2d(dtype=int),
                bary_s: wp.array2d(dtype=wp.vec2), bg_s: wp.array2d(dtype=wp.vec3)):
    """Sample list entry q ← sub-pixel p of listed pixel i, at (sy, sx) of the a× grid; the
    environment along its ray if it sees no object."""
    t = sub_tri[i, p]
    tri_s[0, q] = t
    bary_s[0, q] = sub_bary[i, p]
    if t < 0:
        bg_s[0, q] = background_at(background, sy, sx)


@wp.kernel(enable_backward=False)
def gather_kernel(base: int, idx: wp.array(dtype=int), sub_tri: wp.array2d(dtype=int),
                  sub_bary: wp.array2d(dtype=wp.vec2), background: Background, count: wp.array(dtype=int), offset: wp.array(dtype=int),
                  edge: wp.array(dtype=int), a: int, W: int, tri_s: wp.array2d(dtype=int),
                  bary_s: wp.array2d(dtype=wp.vec2), bg_s: wp.array2d(dtype=wp.vec3), weight_s: wp.array(dtype=float)):
    """Write the second-pass samples of listed pixel k = ``idx[i]`` at ``offset[i]`` (nothing for
    ``count[i]`` = 0; ``edge[i]``: whether it is an edge), each with its share of the pixel
    (``weight_s``, the pixel's weights sum to 1):

    * an **edge** pixel: one sample per triangle its a×a sub-pixels see, at the mean of their
      barycentrics (the centroid of the points they see on it), weighted by their number / a² —
      coverage from all a² sub-pixels, shading once per triangle as in MSAA; each sub-pixel that
      sees no object is its own sample (the environment along its ray, computed here);
    * a **contrast** pixel (one surface, shading that varies): its ``count[i]`` probes (a ≥ 3:
      :func:`probe_subpixel`; a = 2: its 4 sub-pixels), equally weighted; where they disagree,
      :func:`gather_rest_kernel` adds the other sub-pixels later."""
    i = base + wp.tid()
    n = count[i]
    if n == 0:
        return
    k = idx[i]
    y = k / W
    x = k - y * W
    o = offset[i]
    if edge[i] == 0:
        for j in range(n):
            q = j
            if a >= 3:
                q = probe_subpixel(j, a)
            _gather_one(sub_tri, sub_bary, background, i, q, y * a + q / a, x * a + q % a, o + j, tri_s, bary_s, bg_s)
            weight_s[o + j] = 1.0 / float(n)
        return
    m = int(0)
    for q in range(a * a):
        if _first_of_group(sub_tri, i, q) == 1:
            _gather_one(sub_tri, sub_bary, background, i, q, y * a + q / a, x * a + q % a, o + m, tri_s, bary_s,
                        bg_s)
            t = sub_tri[i, q]
            c = float(1.0)
            if t >= 0:  # the whole group: mean barycentrics, share of the sub-pixels
                b = wp.vec2(0.0, 0.0)
                c = float(0.0)
                for p in range(q, a * a):
                    if sub_tri[i, p] == t:
                        b += sub_bary[i, p]
                        c += 1.0
                bary_s[0, o + m] = b / c
            weight_s[o + m] = c / float(a * a)
            m += 1


@wp.kernel(enable_backward=False)
def refine_kernel(base: int, idx: wp.array(dtype=int), edge: wp.array(dtype=int), count: wp.array(dtype=int),
                  offset: wp.array(dtype=int), shaded: wp.array2d(dtype=wp.vec3), img: wp.array2d(dtype=wp.vec3),
                  a: int, tol: float, W: int, rest: wp.array(dtype=int)):
    """``rest[i]`` = a² − 4 where listed pixel k = ``idx[i]`` is a contrast pixel whose 4 probes
    (``shaded`` from ``offset[i]``) and centre sample (``img``, before the resolve) differ in
    luminance by more than ``tol`` of the largest: it is shaded at its other sub-pixels too
    (:func:`gather_rest_kernel`); else 0 and the probes' mean stands for the pixel."""
    i = base + wp.tid()
    rest[i] = 0
    if edge[i] != 0 or count[i] != 4 or a < 3:
        return
    k = idx[i]
    y = k / W
    x = k - y * W
    lo = lum(img[y, x])
    hi = lo
    for j in range(4):
        l = lum(shaded[0, offset[i] + j])
        lo = wp.min(lo, l)
        hi = wp.max(hi, l)
    if hi - lo > tol * wp.max(hi, 1.0e-30):
        rest[i] = a * a - 4


@wp.kernel(enable_backward=False)
def gather_rest_kernel(base: int, idx: wp.array(dtype=int), sub_tri: wp.array2d(dtype=int),
                       sub_bary: wp.array2d(dtype=wp.vec2), background: Background, rest: wp.array(dtype=int),
                       offset: wp.array(dtype=int), a: int, W: int, tri_s: wp.array2d(dtype=int),
                       bary_s: wp.array2d(dtype=wp.vec2), bg_s: wp.array2d(dtype=wp.vec3), weight_s: wp.array(dtype=float)):
    """The sub-pixels of a refined contrast pixel (``rest[i]`` > 0) other than its probes, each
    weighted 1/a², at ``offset[i]``."""
    i = base + wp.tid()
    if rest[i] == 0:
        return
    k = idx[i]
    y = k / W
    x = k - y * W
    m = offset[i]
    for q in range(a * a):
        if _is_probe(q, a) == 0:
            _gather_one(sub_tri, sub_bary, background, i, q, y * a + q / a, x * a + q % a, m, tri_s, bary_s, bg_s)
            weight_s[m] = 1.0 / float(a * a)
            m += 1


@wp.kernel(enable_backward=False)
def resolve_kernel(base: int, idx: wp.array(dtype=int), shaded: wp.array2d(dtype=wp.vec3),
                   weight: wp.array(dtype=float), count: wp.array(dtype=int), offset: wp.array(dtype=int), W: int,
                   keep: float, img: wp.array2d(dtype=wp.vec3)):
    """img[pixel ``idx[i]``] = ``keep`` · img + the weighted sum of its shaded samples (pixels with
    no sample in this pass keep theirs). The second pass: keep = 0 and weights summing to 1; the
    rest of a refined contrast pixel: keep = 4/a² (img holds its probes' mean), weights 1/a²."""
    i = base + wp.tid()
    n = count[i]
    if n == 0:
        return
    k = idx[i]
    y = k / W
    x = k - y * W
    acc = wp.vec3(0.0, 0.0, 0.0)
    if keep != 0.0:
        acc = img[y, x] * keep
    for q in range(n):
        acc += shaded[0, offset[i] + q] * weight[offset[i] + q]
    img[y, x] = acc


@wp.kernel(enable_backward=False)
def _counts_kernel(idx: wp.array(dtype=int), cand: wp.array(dtype=int), edge: wp.array(dtype=int),
                   out: wp.array(dtype=int)):
    """(candidates, edges, contrast pixels) of the listed pixels ``idx`` by atomics (one CUDA
    launch)."""
    k = wp.tid()
    c = cand[idx[k]]
    if c != 0:
        wp.atomic_add(out, 0, 1)
    if edge[k] != 0:
        wp.atomic_add(out, 1, 1)
    if (c & CAND_CONTRAST) != 0:
        wp.atomic_add(out, 2, 1)


def _counts(idx, cand, edge, device) -> dict:
    """The frame's pixel counts (``idx``: the listed pixels, ``edge`` per list entry): numpy views
    on the CPU; on CUDA a reduction on the device, so that only three integers come back (not the
    per-pixel arrays)."""
    if str(device).startswith("cpu"):
        c = cand.numpy()[idx.numpy()]
        n = (np.count_nonzero(c), int(edge.numpy().sum()), np.count_nonzero(c & CAND_CONTRAST))
    else:
        out = wp.zeros(3, dtype=int, device=device)
        wp.launch(_counts_kernel, dim=idx.shape[0], inputs=[idx, cand, edge, out], device=device)
        n = out.numpy()
    return {"candidate_pixels": int(n[0]), "edge_pixels": int(n[1]), "contrast_pixels": int(n[2])}


def _sample_list(n: int, device):
    """Storage of a 1 × n sample list for the shading kernel: (triangle, barycentrics, background)
    per sample, and its weight in its pixel."""
    return (wp.empty((1, n), dtype=int, device=device), wp.empty((1, n), dtype=wp.vec2, device=device),
            wp.empty((1, n), dtype=wp.vec3, device=device), wp.empty(n, dtype=float, device=device))


def render_adaptive(vb1, img, cache: AntialiasCache, camera, tri_object: wp.array, background: Background, a: int,
                    H: int, W: int, shade, device):
    """Antialias ``img`` (H, W) ``wp.array(dtype=vec3)``, the frame shaded once per pixel centre
    from the 1× visibility buffer ``vb1`` (``raster.rasterize(..., subsamples=a)``: it keeps the
    tile queues that :func:`raster.subsample.subsample` reads the candidates' sub-pixels from), in
    place (module docstring). ``cache``: the renderer's :class:`AntialiasCache` (the contours of
    ``camera``, :func:`warp_sg.shading.silhouette.mark_contours`, and the last sub-pixel coverage);
    ``shade(tri_s, bary_s, bg_s, out)`` shades a 1 × N
    sample list; ``background``: the camera rays and environment of the a×a grid
    (:func:`warp_sg.shading.background.background_params`). Returns ``(image, stats)``: candidate, edge and
    contrast pixel counts, the fraction of raster tiles that hold candidates, the samples of the
    second pass and the seconds the sub-pixel coverage took."""
    import time

    from raster import parallel

    n_pix = H * W
    contours = cache.contours(camera, vb1)
    flags = Candidates(vb1.tri_id, tri_object, contours, img, device)
    cand, idx = flags.cand, flags.indices()
    n_c = len(idx)
    if n_c == 0:  # nothing to antialias
        return img, {"candidate_pixels": 0, "edge_pixels": 0, "contrast_pixels": 0, "tile_fraction": 0.0,
                     "pass1_samples": n_pix, "pass2_samples": 0, "refined_pixels": 0, "raster_seconds": 0.0}
    t = time.perf_counter()
    sub_tri, sub_bary, sub_invw, n_tiles = cache.subsamples(vb1, idx)
    raster_seconds = time.perf_counter() - t
    edge = wp.empty(n_c, dtype=int, device=device)
    count = wp.empty(n_c, dtype=int, device=device)
    parallel.launch(classify_kernel, n_c, [idx, cand, sub_tri, sub_invw, tri_object, a, EDGE_DEPTH_RESIDUAL, edge,
                                           count], device)
    offset, n = parallel.exclusive_scan(count)  # per-candidate sample counts → list offsets
    from raster.rasterize import tile_grid

    tx, ty = tile_grid(W, H)
    stats = {**_counts(idx, cand, edge, device), "tile_fraction": n_tiles / (tx * ty), "pass1_samples": n_pix,
             "pass2_samples": n, "refined_pixels": 0, "raster_seconds": raster_seconds}
    if n > 0:
        tri_s, bary_s, bg_s, weight_s = _sample_list(n, device)
        parallel.launch(gather_kernel, n_c, [idx, sub_tri, sub_bary, background, count, offset, edge, a, W, tri_s,
                                             bary_s, bg_s, weight_s], device)
        out = wp.empty((1, n), dtype=wp.vec3, device=device)
        shade(tri_s, bary_s, bg_s, out)
        n3, rest, offset3 = 0, None, None
        if a >= 3 and stats["contrast_pixels"] > 0:  # contrast pixels whose probes disagree: the rest
            rest = wp.empty(n_c, dtype=int, device=device)
            parallel.launch(refine_kernel, n_c, [idx, edge, count, offset, out, img, a, PROBE_CONTRAST, W, rest], device,
                            min_chunk=LIST_MIN_CHUNK)
            offset3, n3 = parallel.exclusive_scan(rest)
        parallel.launch(resolve_kernel, n_c, [idx, out, weight_s, count, offset, W, 0.0, img], device,
                        min_chunk=LIST_MIN_CHUNK)
        if n3 > 0:
            tri_s, bary_s, bg_s, weight_s = _sample_list(n3, device)
            parallel.launch(gather_rest_kernel, n_c, [idx, sub_tri, sub_bary, background, rest, offset3, a, W, tri_s,
                                                      bary_s, bg_s, weight_s], device, min_chunk=LIST_MIN_CHUNK)
            out = wp.empty((1, n3), dtype=wp.vec3, device=device)
            shade(tri_s, bary_s, bg_s, out)
            parallel.launch(resolve_kernel, n_c, [idx, out, weight_s, rest, offset3, W, 4.0 / (a * a), img], device,
                            min_chunk=LIST_MIN_CHUNK)
        stats.update(pass2_samples=n + n3, refined_pixels=n3 // max(a * a - 4, 1))
    return img, stats


__all__ = ["render_adaptive", "AntialiasCache", "EDGE_DEPTH_RESIDUAL", "PROBE_CONTRAST", "same_list"]

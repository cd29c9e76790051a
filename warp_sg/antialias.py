r"""Edge- and contrast-adaptive antialiasing on the device (``[render] antialias = a``).

Coverage is rasterised at a×a sub-pixels; shading is adaptive, in two passes, all in Warp kernels
(no per-frame host round trip of the a²-sized buffers):

1. :func:`classify_kernel` marks a pixel as an **edge** when its sub-pixels see different objects
   (or the background), or one object in front of itself: the inverse depths ``1/z`` of the block
   leave the least-squares plane fitted to them by more than ``EDGE_DEPTH_RESIDUAL`` of their
   maximum (1/z is affine in screen space across a flat triangle, and nearly so across one pixel
   of a smooth surface, however grazing). An interior pixel is shaded once, at its central
   sub-pixel; an edge pixel at all a² sub-pixels.
2. :func:`contrast_kernel` marks the interior pixels whose luminance differs from a 4-neighbour's
   by more than ``CONTRAST`` of the larger one (shadow edges, glints, texture edges); they are
   shaded again at all a² sub-pixels.

Every kernel is 1-D over row-major pixels with a leading ``base`` offset and is launched through
``raster.parallel.launch`` (CPU launches are split over a thread pool). Each pass: per-pixel sample counts → exclusive scan (``wp.utils.array_scan``) → a gather of the
samples' (triangle, barycentrics, background) into a 1 × N list that the ordinary shading kernel
shades → :func:`resolve_kernel` box-filters each pixel's samples back into the image.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import warp as wp

from .background import Background, background_at

#: relative residual of a block's 1/depth off its fitted plane that makes it an edge
EDGE_DEPTH_RESIDUAL = 0.01
#: relative luminance difference to a neighbour that makes an interior pixel supersampled
CONTRAST = 0.2


@wp.kernel(enable_backward=False)
def classify_kernel(base: int, tri_id: wp.array2d(dtype=int), inv_depth: wp.array2d(dtype=float),
                    tri_object: wp.array(dtype=int), a: int, resid_tol: float,
                    edge: wp.array2d(dtype=int), count: wp.array(dtype=int)):
    """edge[y, x] (0/1) and the pixel's sample count (1 or a²) for pass 1. ``inv_depth``: the
    raster's 1/z (0 where empty). A block that one triangle covers is interior at once (1/z is
    affine across a triangle)."""
    W = edge.shape[1]
    k = base + wp.tid()
    y = k / W
    x = k - y * W
    t0 = tri_id[y * a, x * a]
    one = int(1)
    for j in range(a):
        for i in range(a):
            if tri_id[y * a + j, x * a + i] != t0:
                one = 0
    is_edge = int(0)
    if one == 0:
        o0 = int(-1)
        if t0 >= 0:
            o0 = tri_object[t0]
        # least-squares plane of 1/z over the a×a grid (centred coordinates u, v)
        c = 0.5 * float(a - 1)
        n = float(a * a)
        s = float(0.0)
        su = float(0.0)
        sv = float(0.0)
        wmax = float(0.0)
        for j in range(a):
            for i in range(a):
                t = tri_id[y * a + j, x * a + i]
                o = int(-1)
                if t >= 0:
                    o = tri_object[t]
                if o != o0:
                    is_edge = 1
                w = inv_depth[y * a + j, x * a + i]
                s += w
                su += w * (float(i) - c)
                sv += w * (float(j) - c)
                wmax = wp.max(wmax, w)
        if is_edge == 0 and wmax > 0.0:
            suu = n * float(a * a - 1) / 12.0  # Σ (i − c)² over the a×a block (a > 1)
            m = s / n
            gu = su / suu
            gv = sv / suu
            for j in range(a):
                for i in range(a):
                    r = inv_depth[y * a + j, x * a + i] - (m + gu * (float(i) - c) + gv * (float(j) - c))
                    if wp.abs(r) > resid_tol * wmax:
                        is_edge = 1
    edge[y, x] = is_edge
    if is_edge == 1:
        count[y * W + x] = a * a
    else:
        count[y * W + x] = 1


@wp.kernel(enable_backward=False)
def contrast_kernel(base: int, img: wp.array2d(dtype=wp.vec3), edge: wp.array2d(dtype=int), a: int,
                    contrast: float, count: wp.array(dtype=int)):
    """Sample count of pass 2: a² for an interior pixel that contrasts with a 4-neighbour, else 0."""
    H = img.shape[0]
    W = img.shape[1]
    k = base + wp.tid()
    y = k / W
    x = k - y * W
    count[k] = 0
    if edge[y, x] == 1:
        return
    lum = wp.vec3(0.2126, 0.7152, 0.0722)
    l0 = wp.dot(img[y, x], lum)
    hit = int(0)
    for d in range(4):
        yy = y
        xx = x
        if d == 0:
            xx = x - 1
        elif d == 1:
            xx = x + 1
        elif d == 2:
            yy = y - 1
        else:
            yy = y + 1
        if yy >= 0 and yy < H and xx >= 0 and xx < W:
            l1 = wp.dot(img[yy, xx], lum)
            if wp.abs(l0 - l1) > contrast * wp.max(wp.max(l0, l1), 1.0e-30):
                hit = 1
    if hit == 1:
        count[k] = a * a


@wp.func
def _gather_one(tri_id: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2), background: Background,
                sy: int, sx: int, q: int, tri_s: wp.array2d(dtype=int), bary_s: wp.array2d(dtype=wp.vec2),
                bg_s: wp.array2d(dtype=wp.vec3)):
    """Sample list entry q ← sub-pixel (sy, sx); the environment along its ray if it sees no object."""
    t = tri_id[sy, sx]
    tri_s[0, q] = t
    bary_s[0, q] = bary[sy, sx]
    if t < 0:
        bg_s[0, q] = background_at(background, sy, sx)


@wp.kernel(enable_backward=False)
def gather_kernel(base: int, tri_id: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2),
                  background: Background, count: wp.array(dtype=int), offset: wp.array(dtype=int),
                  a: int, W: int, tri_s: wp.array2d(dtype=int), bary_s: wp.array2d(dtype=wp.vec2),
                  bg_s: wp.array2d(dtype=wp.vec3)):
    """Write pixel k's samples at ``offset[k]``: its central sub-pixel (count 1) or all a² (count a²);
    a sample that sees no object gets the environment along its ray (computed here, for the
    gathered samples only)."""
    k = base + wp.tid()
    n = count[k]
    if n == 0:
        return
    y = k / W
    x = k - y * W
    o0 = offset[k]
    if n == 1:
        c = a / 2
        _gather_one(tri_id, bary, background, y * a + c, x * a + c, o0, tri_s, bary_s, bg_s)
        return
    for j in range(a):
        for i in range(a):
            _gather_one(tri_id, bary, background, y * a + j, x * a + i, o0 + j * a + i, tri_s, bary_s, bg_s)


@wp.kernel(enable_backward=False)
def resolve_kernel(base: int, shaded: wp.array2d(dtype=wp.vec3), count: wp.array(dtype=int), offset: wp.array(dtype=int),
                   W: int, img: wp.array2d(dtype=wp.vec3)):
    """img[pixel] = the mean of its shaded samples (pixels with no sample in this pass keep theirs)."""
    k = base + wp.tid()
    n = count[k]
    if n == 0:
        return
    y = k / W
    x = k - y * W
    acc = wp.vec3(0.0, 0.0, 0.0)
    for q in range(n):
        acc += shaded[0, offset[k] + q]
    img[y, x] = acc / float(n)


def _plan(count: wp.array) -> tuple[wp.array, int]:
    """Exclusive scan of the per-pixel counts and the total number of samples."""
    offset = wp.empty_like(count)
    wp.utils.array_scan(count, offset, inclusive=False)
    n = len(count)
    total = int(offset[n - 1: n].numpy()[0] + count[n - 1: n].numpy()[0]) if n else 0
    return offset, total


def render_adaptive(vb, tri_object: wp.array, background: Background, a: int, H: int, W: int, shade, device):
    """The antialiased (H, W) ``wp.array(dtype=vec3)`` image of a visibility buffer ``vb`` rasterised
    at a×a (``shade(tri_s, bary_s, bg_s, out)`` shades a 1 × N sample list; ``background``: the
    camera rays and environment of the a×a grid, :func:`warp_sg.background.background_params`). Returns
    ``(image, stats)`` with the sample and pixel counts of each pass."""
    from raster import parallel

    edge = wp.empty((H, W), dtype=int, device=device)
    count = wp.empty(H * W, dtype=int, device=device)
    img = wp.empty((H, W), dtype=wp.vec3, device=device)
    parallel.launch(classify_kernel, H * W, [vb.tri_id, vb.inv_depth, tri_object, a, EDGE_DEPTH_RESIDUAL, edge, count],
                    device)
    stats = {}
    for p in (1, 2):
        if p == 2:
            parallel.launch(contrast_kernel, H * W, [img, edge, a, CONTRAST, count], device)
        offset, n = _plan(count)
        stats[f"pass{p}_samples"] = n
        if n == 0:
            continue
        tri_s = wp.empty((1, n), dtype=int, device=device)
        bary_s = wp.empty((1, n), dtype=wp.vec2, device=device)
        bg_s = wp.empty((1, n), dtype=wp.vec3, device=device)
        parallel.launch(gather_kernel, H * W, [vb.tri_id, vb.bary, background, count, offset, a, W, tri_s, bary_s,
                                               bg_s], device)
        out = wp.empty((1, n), dtype=wp.vec3, device=device)
        shade(tri_s, bary_s, bg_s, out)
        parallel.launch(resolve_kernel, H * W, [out, count, offset, W, img], device)
    # pass 1 shades 1 sample per interior pixel and a² per edge pixel: the edge count follows
    stats["edge_pixels"] = (stats["pass1_samples"] - H * W) // (a * a - 1)
    return img, stats


__all__ = ["render_adaptive", "EDGE_DEPTH_RESIDUAL", "CONTRAST"]

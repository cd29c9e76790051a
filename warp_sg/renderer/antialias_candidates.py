r"""Which pixels antialiasing looks at again (step 1 of :mod:`warp_sg.renderer.antialias`).

:func:`candidates_kernel` flags, per pixel of the 1× frame, the **contours** (a silhouette or
boundary edge of the mesh crosses the pixel, :mod:`warp_sg.shading.silhouette`), the **object
changes** (a 4-neighbour sees another object or the background) and the **contrast** pixels (a
4-neighbour's luminance differs by more than :data:`CONTRAST` relative); :class:`Candidates` keeps
the flags and lists the flagged pixels (a scan of per-run counts), so the later kernels run over
the few candidates only.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import warp as wp

from warp_sg.brdf.kernel.material_wp import lum

#: relative luminance difference to a neighbour that makes an interior pixel supersampled
CONTRAST = 0.2

#: a kernel over the candidate list whose elements cost well under a µs (the refinement, the
#: resolves): below this many candidates it runs as one launch on the calling thread, where the
#: CPU pool's hand-off (~90 µs per range) would cost more than the work
LIST_MIN_CHUNK = 16384

#: candidate flags (bits of ``cand``)
CAND_GEOMETRY = wp.constant(1)
CAND_CONTRAST = wp.constant(2)


@wp.func
def object_of(tri_object: wp.array(dtype=int), t: int) -> int:
    o = int(-1)
    if t >= 0:
        o = tri_object[t]
    return o


@wp.func
def _neighbour_flags(tri_id: wp.array2d(dtype=int), tri_object: wp.array(dtype=int), img: wp.array2d(dtype=wp.vec3),
                     contrast: float, t0: int, o0: int, l0: float, yy: int, xx: int) -> int:
    """The candidate flags that neighbour (yy, xx) raises for a pixel seeing triangle ``t0`` of
    object ``o0`` with luminance ``l0`` (the same triangle is the same object: no lookup)."""
    f = int(0)
    t1 = tri_id[yy, xx]
    if t1 != t0:
        if object_of(tri_object, t1) != o0:
            f = CAND_GEOMETRY
    l1 = lum(img[yy, xx])
    if wp.abs(l0 - l1) > contrast * wp.max(wp.max(l0, l1), 1.0e-30):
        f = f | CAND_CONTRAST
    return f


#: pixels of a row one CPU thread tests in :func:`candidates_kernel` (one integer division per
#: thread, not per pixel, and a plain loop along the row: −28 % of its time on the frame-scaling
#: frame); 1 on CUDA (a thread per pixel)
CANDIDATES_PER_THREAD = 64


@wp.kernel(enable_backward=False)
def candidates_kernel(base: int, seg: int, tri_id: wp.array2d(dtype=int), tri_object: wp.array(dtype=int),
                      contours: wp.array2d(dtype=wp.uint8), img: wp.array2d(dtype=wp.vec3), contrast: float,
                      cand: wp.array(dtype=int), run_count: wp.array(dtype=int), run_list: wp.array(dtype=int)):
    """``cand[k]``: ``CAND_GEOMETRY`` where the pixel is on a contour or a 4-neighbour sees another
    object (1× buffer), plus ``CAND_CONTRAST`` where the 1× image's luminance differs from a
    4-neighbour's by more than ``contrast`` of the larger one (0: not a candidate). Element
    ``base + tid`` is the run of ``seg`` pixels of one row (the last of a row shorter): ``⌈W/seg⌉``
    runs per row; ``run_count[r]``: its candidates, whose indices it writes at ``run_list[r·seg]``
    on (for the list, :meth:`Candidates.indices`)."""
    H = img.shape[0]
    W = img.shape[1]
    runs = (W + seg - 1) / seg
    r = base + wp.tid()
    y = r / runs
    x0 = (r - y * runs) * seg
    n = int(0)
    for x in range(x0, wp.min(x0 + seg, W)):
        t0 = tri_id[y, x]
        o0 = object_of(tri_object, t0)
        l0 = lum(img[y, x])
        f = int(0)
        if contours[y, x] != wp.uint8(0):
            f = CAND_GEOMETRY
        if x > 0:
            f = f | _neighbour_flags(tri_id, tri_object, img, contrast, t0, o0, l0, y, x - 1)
        if x + 1 < W:
            f = f | _neighbour_flags(tri_id, tri_object, img, contrast, t0, o0, l0, y, x + 1)
        if y > 0:
            f = f | _neighbour_flags(tri_id, tri_object, img, contrast, t0, o0, l0, y - 1, x)
        if y + 1 < H:
            f = f | _neighbour_flags(tri_id, tri_object, img, contrast, t0, o0, l0, y + 1, x)
        cand[y * W + x] = f
        if f != 0:
            run_list[r * seg + n] = y * W + x
            n += 1
    run_count[r] = n


@wp.kernel(enable_backward=False)
def _list_runs_kernel(base: int, seg: int, run_count: wp.array(dtype=int), run_list: wp.array(dtype=int),
                      offset: wp.array(dtype=int), idx: wp.array(dtype=int)):
    """The candidates of run ``r = base + tid`` (``run_list[r·seg]`` on, :func:`candidates_kernel`)
    at ``idx[offset[r]]`` on."""
    r = base + wp.tid()
    for j in range(run_count[r]):
        idx[offset[r] + j] = run_list[r * seg + j]


class Candidates:
    """Every pixel's candidate flags ``cand`` (H·W,) (:func:`candidates_kernel`), and per run of
    ``seg`` pixels of a row its number of candidates, ``run_count``."""

    def __init__(self, tri_id: wp.array, tri_object: wp.array, contours: wp.array, img: wp.array, device):
        from raster import parallel

        H, W = int(img.shape[0]), int(img.shape[1])
        self.seg = CANDIDATES_PER_THREAD if str(device).startswith("cpu") else 1
        self.device = device
        self.cand = wp.empty(H * W, dtype=int, device=device)
        n_runs = H * (-(-W // self.seg))
        self.run_count = wp.empty(n_runs, dtype=int, device=device)
        self.run_list = wp.empty(n_runs * self.seg, dtype=int, device=device)
        parallel.launch(candidates_kernel, n_runs, [self.seg, tri_id, tri_object, contours, img, CONTRAST, self.cand,
                                                    self.run_count, self.run_list], device,
                        min_chunk=max(4096 // self.seg, 1))

    def indices(self) -> wp.array:
        """The indices k with ``cand[k]`` ≠ 0, ascending: a scan of the runs' counts, then each run
        copies the indices it listed (on the CPU 4 k runs of 64 pixels at 512², instead of a scan
        and a scatter over every pixel): the later kernels run over the few candidates."""
        from raster import parallel

        offset, total = parallel.exclusive_scan(self.run_count)
        idx = wp.empty(total, dtype=int, device=self.device)
        if total > 0:
            parallel.launch(_list_runs_kernel, int(self.run_count.shape[0]),
                            [self.seg, self.run_count, self.run_list, offset, idx], self.device,
                            min_chunk=LIST_MIN_CHUNK)
        return idx


__all__ = ["Candidates", "candidates_kernel", "CONTRAST", "CAND_GEOMETRY", "CAND_CONTRAST", "LIST_MIN_CHUNK"]

r"""The visible sky of a moving object's vertices: their weights kept, the sky turned into the object.

The visible fraction of a vertex's diffuse environment irradiance
(:func:`warp_sg.shading.vertex_visibility.env_vertex_visible_kernel`) is, with ``O`` and ``S``
the occluded and visible parts of the cone's quadrature::

    O = Σ_t (1 − s_t) c_t L̄(d_t),   S = Σ_t s_t c_t L̄(d_t),   c_t = (n·d_t) Ω_t,

over the texels ``t`` of the vertex's SSDF map inside its occluder cone (``s_t`` the texel's visible
share from its SSDF value, ``L̄`` the residual map box-filtered to 64 × 128,
``precompute.environment.irradiance.cell_radiance``). A static vertex computes it when the
environment turns; a vertex of a dynamic object (:mod:`warp_sg.renderer.dynamic_objects`) each
time its object turns. But under the object's rigid motion ``R`` its map, its cone and its
texels' directions turn together — ``d_t = R·D_t`` with ``D_t`` the direction in the pose the
geometry was built in — so which texels the cone holds, their shares and weights do not change:
only the sky does, and a rotation of the object is a rotation of the sky in the object's frame::

    L̄(d_t) = L̄(R·D_t) = L'(D_t),   L' = L̄ ∘ R    (the sky seen from the object's own frame).

So, once per vertex (:class:`MovingSky`, in the rest pose): the texels inside the cone, each
with its weights ``(1 − s_t) c_t``, ``s_t c_t`` and where ``D_t`` falls on a cube of :data:`FACE`
texels per face edge (a one-texel border, as the irradiance table's,
``precompute.environment.irradiance``). Once per frame and object (:func:`turn_sky_kernel`):
``L'`` on that cube, each texel ``L̄`` read bilinearly at ``R·`` its direction — 6·34² = 6936
reads instead of one per texel of every vertex. Then per vertex (:func:`moving_visible_kernel`):
the two weighted sums of bilinear cube reads, and ``F`` as before. On the turning blob (384
self-shadowed vertices, 352 of their 1024 texels in the cone on average) the frame's share drops
from ≈ 21 ms of CPU (every texel, the map read by longitude and latitude) to ≈ 2 ms (0.4 ms of it
turning the sky).

The cube's second interpolation smooths ``L̄`` by a fraction of its own cell (2.8° cube texels at
the face centres against 2.8° cells). Against the map-read quadrature at the same pose
(:func:`~warp_sg.shading.vertex_visibility.env_vertex_visible`, ``tests/test_moving_caches.py``,
four poses each): the blob's visible fraction (32² maps, F ≥ 0.98) within 1.0e-4 (mean 2.4e-6);
a torus whose inner side shadows itself deeply (16² maps, F down to 0.57, its texels straddling
the sky's horizon step, where bilinear reads of a bilinear resampling differ most) within 2.0e-3
(mean 2.6e-4) — a few tenths of a percent of the irradiance, well inside the per-region accuracy
the renderer is held to. The moving vertices use it at every pose, their first frame included,
so a frame stays a function of the transforms.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import numpy as np
import warp as wp

from precompute.environment.cubemap import cube_face_of
from precompute.environment.irradiance import irradiance_unscaled, texel_directions_with_border
from precompute.visibility.ssdf_wp import concentric_to_dir_wp

from warp_sg.numeric.onb import local_to_world
from warp_sg.scene.envmap import env_lookup
from warp_sg.shading.vertex_visibility import texel_ssdf, visible_share
from warp_sg.shading.visibility_terms import EnvSG, Visibility

#: texels per cube face edge (without the border) of the turned sky
FACE = 32
#: bytes per listed texel (corner, fractions, weights)
TEXEL_BYTES = 20


def table_budget() -> int:
    """Bytes the texel lists may take (``WARP_SG_SKY_TABLE_MB``, default 256 MiB: the turning
    blob's take 2.7 MB, the 12.9 k moving vertices of the refined Stanford bunny 198 MB); beyond,
    the moving vertices are integrated against the map itself, every texel, every frame."""
    from precompute.visibility.ssdf import budget_mib

    return budget_mib("WARP_SG_SKY_TABLE_MB", "256")
_SQRT_2PI = wp.constant(float(np.sqrt(2.0 * np.pi)))


@wp.struct
class SkyTable:
    """Per listed vertex ``k`` (``vertices[k]``, of object ``slot[k]``): its texels inside the cone,
    ``start[k]`` to ``start[k+1]`` — per texel ``corner`` (the cube texel below and left of its
    direction, in its object's cube), ``frac`` (the bilinear fractions) and ``weight``
    (``(1 − s) c``, ``s c``). ``sky``: the turned sky of every object, cubes of ``size`` (with
    border) one after the other."""

    vertices: wp.array(dtype=int)
    slot: wp.array(dtype=int)
    start: wp.array(dtype=int)
    corner: wp.array(dtype=int)
    frac: wp.array(dtype=wp.vec2)
    weight: wp.array(dtype=wp.vec2)
    sky: wp.array(dtype=wp.vec3)
    size: int


@wp.func
def _cone_texel(dl: wp.vec3, t: wp.vec3, b: wp.vec3, n: wp.vec3, cone: wp.vec4, c_min: float) -> int:
    """1 when the texel of local direction ``dl`` lies in the cone (the test of
    ``env_vertex_visible_kernel``)."""
    r = int(0)
    if wp.dot(local_to_world(dl, t, b, n), wp.vec3(cone[0], cone[1], cone[2])) >= c_min:
        r = 1
    return r


@wp.func
def _texel_local(R: int, q: int) -> wp.vec3:
    y = q / R
    x = q - y * R
    return concentric_to_dir_wp((float(x) + 0.5) * 2.0 / float(R) - 1.0, (float(y) + 0.5) * 2.0 / float(R) - 1.0)


@wp.kernel(enable_backward=False)
def count_texels_kernel(vis: Visibility, rest_n: wp.array(dtype=wp.vec3), rest_t: wp.array(dtype=wp.vec3),
                        rest_b: wp.array(dtype=wp.vec3), rest_cone: wp.array(dtype=wp.vec4), count: wp.array(dtype=int)):
    """``count[i]``: the texels inside listed vertex i's cone (its rest frame and cone)."""
    i = wp.tid()
    cone = rest_cone[i]
    m = int(0)
    if cone[3] >= 0.0:
        R = vis.mean.shape[0]
        c_min = wp.cos(wp.min(cone[3] + _SQRT_2PI / float(R), wp.pi))
        for q in range(R * R):
            m += _cone_texel(_texel_local(R, q), rest_t[i], rest_b[i], wp.normalize(rest_n[i]), cone, c_min)
    count[i] = m


@wp.kernel(enable_backward=False)
def fill_texels_kernel(vis: Visibility, ids: wp.array(dtype=int), rest_n: wp.array(dtype=wp.vec3),
                       rest_t: wp.array(dtype=wp.vec3), rest_b: wp.array(dtype=wp.vec3),
                       rest_cone: wp.array(dtype=wp.vec4), start: wp.array(dtype=int), face: int,
                       corner: wp.array(dtype=int), frac: wp.array(dtype=wp.vec2), weight: wp.array(dtype=wp.vec2)):
    """Listed vertex i's texels inside its cone (:class:`SkyTable`): cube corner, fractions and
    weights, from ``start[i]``."""
    i = wp.tid()
    cone = rest_cone[i]
    if cone[3] < 0.0:
        return
    v = ids[i]
    R = vis.mean.shape[0]
    h = _SQRT_2PI / float(R)
    om = 2.0 * wp.pi / float(R * R)
    c_min = wp.cos(wp.min(cone[3] + h, wp.pi))
    n = wp.normalize(rest_n[i])
    j = start[i]
    stride = face + 2
    for q in range(R * R):
        dl = _texel_local(R, q)
        if _cone_texel(dl, rest_t[i], rest_b[i], n, cone, c_min) == 1:
            y = q / R
            s = wp.clamp(0.5 + texel_ssdf(vis, v, y, q - y * R) / h, 0.0, 1.0)
            c = dl[2] * om
            fab = cube_face_of(local_to_world(dl, rest_t[i], rest_b[i], n))
            fx = (fab[1] + 1.0) * 0.5 * float(face) + 0.5  # (as precompute.environment.cubemap.bordered_bilinear)
            fy = (fab[2] + 1.0) * 0.5 * float(face) + 0.5
            x0 = wp.clamp(int(wp.floor(fx)), 0, face)
            y0 = wp.clamp(int(wp.floor(fy)), 0, face)
            corner[j] = int(fab[0]) * stride * stride + y0 * stride + x0
            frac[j] = wp.vec2(wp.clamp(fx - float(x0), 0.0, 1.0), wp.clamp(fy - float(y0), 0.0, 1.0))
            weight[j] = wp.vec2((1.0 - s) * c, s * c)
            j += 1


@wp.kernel(enable_backward=False)
def turn_sky_kernel(base: int, dirs: wp.array(dtype=wp.vec3), radiance: wp.array2d(dtype=wp.vec3),
                    to_env: wp.array(dtype=wp.mat33), out: wp.array(dtype=wp.vec3)):
    """Cube texel ``p = base + tid`` of object ``p / |dirs|``: ``L̄`` (bilinear) along that object's
    motion times the texel's direction, in the map's frame (``to_env[k] = Rᵀ_env · R_k``)."""
    p = base + wp.tid()
    n = dirs.shape[0]
    k = p / n
    out[p] = env_lookup(radiance, to_env[k], dirs[p - k * n])


@wp.kernel(enable_backward=False)
def moving_visible_kernel(base: int, tab: SkyTable, vis: Visibility, env: EnvSG, out: wp.array(dtype=wp.vec3),
                          out_irr: wp.array(dtype=wp.vec3)):
    """Listed vertex ``k = base + tid`` (``v = tab.vertices[k]``): ``out[v]`` its visible fraction
    and ``out_irr[v] = E ∘ F``, as ``env_vertex_visible_kernel`` with ``L̄(d_t)`` read from its
    object's turned sky (module docstring)."""
    k = base + wp.tid()
    v = tab.vertices[k]
    n = wp.normalize(vis.normals[v])
    cone = vis.cones[v]
    f = wp.vec3(1.0, 1.0, 1.0)
    ex = irradiance_unscaled(env.exact, n)
    if cone[3] >= 0.0:
        stride = tab.size
        o = tab.slot[k] * 6 * stride * stride
        occ_sum = wp.vec3(0.0, 0.0, 0.0)
        seen_sum = wp.vec3(0.0, 0.0, 0.0)
        for j in range(tab.start[k], tab.start[k + 1]):
            c = o + tab.corner[j]
            fr = tab.frac[j]
            t0 = tab.sky[c] * (1.0 - fr[0]) + tab.sky[c + 1] * fr[0]
            t1 = tab.sky[c + stride] * (1.0 - fr[0]) + tab.sky[c + stride + 1] * fr[0]
            e = t0 * (1.0 - fr[1]) + t1 * fr[1]
            w = tab.weight[j]
            occ_sum += e * w[0]
            seen_sum += e * w[1]
        f = visible_share(occ_sum, seen_sum, ex, cone, n, _SQRT_2PI / float(vis.mean.shape[0]))
    out[v] = f
    out_irr[v] = wp.cw_mul(ex, f)


class MovingSky:
    """The :class:`SkyTable` of the moving vertices of one installed visibility (module docstring).

    ``vertices`` (mesh ids), ``slot`` (their object's index among the moving objects) and their
    rest rows on the device (normals, SSDF frames, cones): the lists are built once, here."""

    def __init__(self, vis: Visibility, vertices: wp.array, slot: np.ndarray, rest: tuple, n_objects: int, device,
                 face: int = FACE):
        from raster import parallel

        rest_n, rest_t, rest_b, rest_cone = rest
        n = int(vertices.shape[0])
        self.device, self.count, self.n_objects = device, n, int(n_objects)
        count = wp.zeros(max(n, 1), dtype=int, device=device)
        if n:
            wp.launch(count_texels_kernel, dim=n, inputs=[vis, rest_n, rest_t, rest_b, rest_cone, count], device=device)
        start, total = parallel.exclusive_scan(count)
        #: whether the lists fit :func:`table_budget` (else :meth:`visible` is not to be called)
        self.fits = total * TEXEL_BYTES <= table_budget()
        if not self.fits:
            self.count = self.texels = 0
            return
        st = np.append(start.numpy()[:n], total).astype(np.int32)
        tab = SkyTable()
        tab.vertices, tab.slot = vertices, wp.array(np.asarray(slot, np.int32), dtype=int, device=device)
        tab.start = wp.array(st, dtype=int, device=device)
        tab.corner = wp.empty(max(total, 1), dtype=int, device=device)
        tab.frac = wp.empty(max(total, 1), dtype=wp.vec2, device=device)
        tab.weight = wp.empty(max(total, 1), dtype=wp.vec2, device=device)
        if total:
            wp.launch(fill_texels_kernel, dim=n, inputs=[vis, vertices, rest_n, rest_t, rest_b, rest_cone, tab.start,
                                                         int(face), tab.corner, tab.frac, tab.weight], device=device)
        self.texels = int(total)
        # ranges of about equal work for the CPU threads: a vertex costs its texels (and one more)
        work = np.cumsum(np.diff(st) + 1)
        w = parallel.cpu_workers()
        self.bounds = np.unique(np.concatenate([[0], np.searchsorted(work, work[-1] * np.arange(1, w) / w) if n else [],
                                                [n]]).astype(np.int64))
        self.dirs = wp.array(texel_directions_with_border(int(face)).reshape(-1, 3).astype(np.float32), dtype=wp.vec3,
                             device=device)
        tab.size = int(face) + 2
        tab.sky = wp.zeros(max(self.n_objects, 1) * int(self.dirs.shape[0]), dtype=wp.vec3, device=device)
        self.table = tab
        self._turned = None  # the key of the sky in tab.sky

    def visible(self, vis: Visibility, env: EnvSG, radiance: wp.array, env_rotation, motions: list, into) -> None:
        """The listed vertices' rows of ``into = (F, E ∘ F)`` (``env_vertex_visible``'s), in place:
        the sky of map ``radiance`` (the box-filtered residual) turned by ``env_rotation`` and each
        object's rotation ``motions[k]`` (from the rest pose), then the weighted sums."""
        from raster import parallel

        if not self.count:
            return
        to_env = np.stack([np.asarray(env_rotation, np.float64).T @ np.asarray(M, np.float64) for M in motions])
        key = (id(radiance), to_env.tobytes())
        if self._turned != key and self.texels:
            m = len(motions) * int(self.dirs.shape[0])
            parallel.launch(turn_sky_kernel, m, [self.dirs, radiance, wp.array(to_env.astype(np.float32),
                                                                            dtype=wp.mat33, device=self.device),
                                                 self.table.sky], self.device, chunks=parallel.cpu_workers())
            self._turned = key
        parallel.launch_split(moving_visible_kernel, self.bounds, [self.table, vis, env, *into], self.device)


__all__ = ["FACE", "MovingSky", "SkyTable", "moving_visible_kernel", "table_budget", "turn_sky_kernel"]

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
import math

import numpy as np
import warp as wp

from precompute.environment.irradiance import irradiance_unscaled, texel_directions_with_border
from precompute.visibility.ssdf_wp import concentric_to_dir_wp

from warp_sg.numeric.onb import local_to_world
from warp_sg.scene.envmap import env_lookup
from warp_sg.shading.vertex_visibility import texel_ssdf, visible_share
from warp_sg.shading.visibility_terms import EnvSG, Visibility

#: texels per cube face edge (without the border) of the turned sky
FACE = 32
#: the spherical-harmonic order of the transfer vectors ((ORDER + 1)² coefficients per vertex)
ORDER = 8
#: the largest bound on a vertex's visible-fraction error from the truncated sky that its
#: transfer vectors are used with; a vertex over it is integrated against the map (module docstring)
BOUND = 0.25
_SQRT_2PI = wp.constant(float(np.sqrt(2.0 * np.pi)))


def sh_norms(order: int) -> np.ndarray:
    """``K[l·(order+1) + m] = √((2l+1)/4π · (l−m)!/(l+m)!)``, times √2 for m > 0: the factors of
    the real orthonormal spherical harmonics in :func:`sh_accumulate`."""
    k = np.zeros((order + 1) ** 2)
    for l in range(order + 1):
        for m in range(l + 1):
            k[l * (order + 1) + m] = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - m)
                                               / math.factorial(l + m)) * (math.sqrt(2.0) if m else 1.0)
    return k


@wp.func
def sh_accumulate(out: wp.array2d(dtype=wp.vec2), row: int, order: int, norms: wp.array(dtype=float), d: wp.vec3,
                  w: wp.vec2):
    """``out[row, i] += w·Y_i(d)`` for the real orthonormal spherical harmonics up to ``order``
    (``i = l² + l + m``, ``−l ≤ m ≤ l``): ``Y_l^0 = K_l^0 Q_l^0(z)``, ``Y_l^{±m} = √2 K_l^m
    Q_l^m(z)·(Re, Im)(x + iy)^m``, with ``Q_l^m`` the associated Legendre function less its
    ``sin^m θ`` (no Condon–Shortley phase): ``Q_m^m = (2m−1)!!``, ``Q_{m+1}^m = (2m+1) z Q_m^m``,
    ``(l−m) Q_l^m = (2l−1) z Q_{l−1}^m − (l+m−1) Q_{l−2}^m`` (Sloan, "Efficient spherical
    harmonic evaluation", JCGT 2013)."""
    x = d[0]
    y = d[1]
    z = d[2]
    c = float(1.0)
    s = float(0.0)
    qmm = float(1.0)
    for m in range(order + 1):
        if m > 0:
            c1 = x * c - y * s
            s = x * s + y * c
            c = c1
            qmm = qmm * float(2 * m - 1)
        q1 = qmm
        q2 = float(0.0)
        for l in range(m, order + 1):
            q = qmm
            if l == m + 1:
                q = float(2 * m + 1) * z * qmm
            elif l > m + 1:
                q = (float(2 * l - 1) * z * q1 - float(l + m - 1) * q2) / float(l - m)
            if l > m:
                q2 = q1
                q1 = q
            k = norms[l * (order + 1) + m] * q
            if m == 0:
                out[row, l * l + l] = out[row, l * l + l] + w * k
            else:
                out[row, l * l + l + m] = out[row, l * l + l + m] + w * (k * c)
                out[row, l * l + l - m] = out[row, l * l + l - m] + w * (k * s)


@wp.struct
class SkyTable:
    """Per listed vertex ``k`` (``vertices[k]``, of object ``slot[k]``; ``exact[k] = 1``: left to
    the map quadrature): its transfer vectors ``t^O``, ``t^S`` against the turned sky's coefficients, four at a time
    (``groups`` of them, zero-padded): ``transfer[2(k·groups + j)]`` ``t^O_{4j…4j+3}``, ``+1``
    ``t^S`` likewise, and ``coef[3(slot·groups + j) + c]`` channel c of the sky's (a layout the
    CPU runs ≈ 3× faster than one coefficient at a time). ``sky``: the turned sky of every object,
    cubes of ``size`` (with border) one after the other."""

    vertices: wp.array(dtype=int)
    slot: wp.array(dtype=int)
    exact: wp.array(dtype=int)
    transfer: wp.array(dtype=wp.vec4)
    coef: wp.array(dtype=wp.vec4)
    groups: int
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
def transfer_kernel(base: int, vis: Visibility, ids: wp.array(dtype=int), rest_n: wp.array(dtype=wp.vec3),
                    rest_t: wp.array(dtype=wp.vec3), rest_b: wp.array(dtype=wp.vec3),
                    rest_cone: wp.array(dtype=wp.vec4), order: int, norms: wp.array(dtype=float),
                    out: wp.array2d(dtype=wp.vec2), norm2: wp.array(dtype=wp.vec2)):
    """Listed vertex ``i = base + tid``'s transfer vectors (module docstring), ``out[i, j] = Σ_t
    ((1 − s_t) c_t, s_t c_t) Y_j(D_t)`` over its texels inside the cone (rest pose), and
    ``norm2[i] = Σ_t ((1 − s_t) c_t, s_t c_t)² / Ω``."""
    i = base + wp.tid()
    cone = rest_cone[i]
    if cone[3] < 0.0:
        return
    v = ids[i]
    R = vis.mean.shape[0]
    h = _SQRT_2PI / float(R)
    om = 2.0 * wp.pi / float(R * R)
    c_min = wp.cos(wp.min(cone[3] + h, wp.pi))
    n = wp.normalize(rest_n[i])
    acc = wp.vec2(0.0, 0.0)
    for q in range(R * R):
        dl = _texel_local(R, q)
        if _cone_texel(dl, rest_t[i], rest_b[i], n, cone, c_min) == 1:
            y = q / R
            s = wp.clamp(0.5 + texel_ssdf(vis, v, y, q - y * R) / h, 0.0, 1.0)
            c = dl[2] * om
            w = wp.vec2((1.0 - s) * c, s * c)
            acc += wp.cw_mul(w, w) / om
            sh_accumulate(out, i, order, norms, local_to_world(dl, rest_t[i], rest_b[i], n), w)
    norm2[i] = acc


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
def project_sky_kernel(base: int, basis: wp.array2d(dtype=wp.vec4), inner: wp.array(dtype=int),
                       sky: wp.array(dtype=wp.vec3), size: int, out: wp.array(dtype=wp.vec4)):
    """Coefficients ``4j…4j+3`` of object ``k`` (``p = base + tid = k·groups + j``): ``Σ_q Ω_q
    Y_i(d_q) L'_k(d_q)`` over the cube's inner texels (``basis[j, q]`` = the four ``Ω_q Y_i(d_q)``,
    ``inner[q]`` the texel in the bordered cube of ``size`` texels), channel by channel into
    ``out[3p + c]`` (:class:`SkyTable`)."""
    p = base + wp.tid()
    ng = basis.shape[0]
    k = p / ng
    j = p - k * ng
    o = k * size
    r = wp.vec4(0.0, 0.0, 0.0, 0.0)
    g = wp.vec4(0.0, 0.0, 0.0, 0.0)
    b = wp.vec4(0.0, 0.0, 0.0, 0.0)
    for q in range(basis.shape[1]):
        e = sky[o + inner[q]]
        y = basis[j, q]
        r += y * e[0]
        g += y * e[1]
        b += y * e[2]
    out[3 * p] = r
    out[3 * p + 1] = g
    out[3 * p + 2] = b


@wp.kernel(enable_backward=False)
def moving_visible_kernel(base: int, tab: SkyTable, vis: Visibility, env: EnvSG, out: wp.array(dtype=wp.vec3),
                          out_irr: wp.array(dtype=wp.vec3)):
    """Listed vertex ``k = base + tid`` (``v = tab.vertices[k]``): ``out[v]`` its visible fraction
    and ``out_irr[v] = E ∘ F``, as ``env_vertex_visible_kernel`` with the cone's sums ``O = t^O·l``,
    ``S = t^S·l`` from its transfer vectors and its object's turned sky's coefficients ``l``
    (module docstring); a vertex left to the map quadrature (``tab.exact[k]``) is not written."""
    k = base + wp.tid()
    if tab.exact[k] != 0:
        return
    v = tab.vertices[k]
    n = wp.normalize(vis.normals[v])
    cone = vis.cones[v]
    f = wp.vec3(1.0, 1.0, 1.0)
    ex = irradiance_unscaled(env.exact, n)
    if cone[3] >= 0.0:
        o = 3 * tab.slot[k] * tab.groups
        t = 2 * k * tab.groups
        o0 = wp.vec4(0.0, 0.0, 0.0, 0.0)
        o1 = wp.vec4(0.0, 0.0, 0.0, 0.0)
        o2 = wp.vec4(0.0, 0.0, 0.0, 0.0)
        s0 = wp.vec4(0.0, 0.0, 0.0, 0.0)
        s1 = wp.vec4(0.0, 0.0, 0.0, 0.0)
        s2 = wp.vec4(0.0, 0.0, 0.0, 0.0)
        for j in range(tab.groups):
            wo = tab.transfer[t + 2 * j]
            ws = tab.transfer[t + 2 * j + 1]
            c0 = tab.coef[o + 3 * j]
            c1 = tab.coef[o + 3 * j + 1]
            c2 = tab.coef[o + 3 * j + 2]
            o0 += wp.cw_mul(c0, wo)
            o1 += wp.cw_mul(c1, wo)
            o2 += wp.cw_mul(c2, wo)
            s0 += wp.cw_mul(c0, ws)
            s1 += wp.cw_mul(c1, ws)
            s2 += wp.cw_mul(c2, ws)
        one = wp.vec4(1.0, 1.0, 1.0, 1.0)
        occ_sum = wp.vec3(wp.dot(o0, one), wp.dot(o1, one), wp.dot(o2, one))
        seen_sum = wp.vec3(wp.dot(s0, one), wp.dot(s1, one), wp.dot(s2, one))
        f = visible_share(occ_sum, seen_sum, ex, cone, n, _SQRT_2PI / float(vis.mean.shape[0]))
    out[v] = f
    out_irr[v] = wp.cw_mul(ex, f)


@wp.kernel(enable_backward=False)
def basis_kernel(base: int, dirs: wp.array(dtype=wp.vec3), order: int, norms: wp.array(dtype=float),
                 out: wp.array2d(dtype=wp.vec2)):
    """``out[p, i] = (Y_i(dirs[p]), 0)`` for ``p = base + tid``."""
    p = base + wp.tid()
    sh_accumulate(out, p, order, norms, dirs[p], wp.vec2(1.0, 0.0))


def sh_values(dirs: np.ndarray, order: int, device="cpu") -> np.ndarray:
    """(M, (order+1)²) float64: the real spherical harmonics of :func:`sh_accumulate` at unit
    directions ``dirs`` (M, 3)."""
    d = wp.array(np.ascontiguousarray(dirs, np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)
    out = wp.zeros((max(int(d.shape[0]), 1), (order + 1) ** 2), dtype=wp.vec2, device=device)
    nm = wp.array(sh_norms(order).astype(np.float32), dtype=float, device=device)
    if d.shape[0]:
        wp.launch(basis_kernel, dim=int(d.shape[0]), inputs=[0, d, int(order), nm, out], device=device)
    return out.numpy()[:int(d.shape[0]), :, 0].astype(np.float64)


def cube_quadrature(face: int):
    """(inner, directions, Ω) of the cube's inner texels (the bordered cube of
    :func:`~precompute.environment.irradiance.texel_directions_with_border`): their flat indices,
    unit directions and solid angles ``Ω = (2/N)² / (1 + a² + b²)^{3/2}``."""
    st = int(face) + 2
    t = (np.arange(st) - 0.5) * 2.0 / face - 1.0
    a, b = np.meshgrid(t, t)
    om = (2.0 / face) ** 2 / (1.0 + a * a + b * b) ** 1.5
    mask = np.zeros((6, st, st), bool)
    mask[:, 1:-1, 1:-1] = True
    dirs = texel_directions_with_border(int(face))
    return np.flatnonzero(mask.ravel()), dirs[mask], np.broadcast_to(om, (6, st, st))[mask]


class MovingSky:
    """The :class:`SkyTable` of the moving vertices of one installed visibility (module docstring).

    ``vertices`` (mesh ids), ``slot`` (their object's index among the moving objects) and their
    rest rows on the device (normals, SSDF frames, cones): the transfer vectors are computed once,
    here; which vertices keep texel lists instead is decided per sky (:meth:`prepare`)."""

    def __init__(self, vis: Visibility, vertices: wp.array, slot: np.ndarray, rest: tuple, n_objects: int, device,
                 face: int = FACE, order: int | None = None):
        from raster import parallel

        n = int(vertices.shape[0])
        order = ORDER if order is None else order
        self.device, self.count, self.n_objects, self.face, self.order = device, n, int(n_objects), int(face), int(order)
        self.vis, self.vertices, self.rest = vis, vertices, rest
        nc = (self.order + 1) ** 2
        self.norms = wp.array(sh_norms(self.order).astype(np.float32), dtype=float, device=device)
        tab = SkyTable()
        tab.vertices, tab.slot = vertices, wp.array(np.asarray(slot, np.int32), dtype=int, device=device)
        transfer = wp.zeros((max(n, 1), nc), dtype=wp.vec2, device=device)
        norm2 = wp.zeros(max(n, 1), dtype=wp.vec2, device=device)
        if n:
            parallel.launch(transfer_kernel, n, [vis, vertices, *rest, self.order, self.norms, transfer, norm2], device,
                            min_chunk=64)
        # (host copies for the bound, :meth:`prepare`; the kernels' layout of four coefficients a group)
        self._transfer, self._norm2 = transfer.numpy()[:n].astype(np.float64), norm2.numpy()[:n].astype(np.float64)
        ng = -(-nc // 4)
        T = np.zeros((max(n, 1), 4 * ng, 2), np.float32)
        T[:n, :nc] = self._transfer
        tab.transfer = wp.array(T.reshape(-1, ng, 4, 2).transpose(0, 1, 3, 2).reshape(-1, 4), dtype=wp.vec4, device=device)
        del transfer, norm2
        inner, dirs, om = cube_quadrature(self.face)
        self._omega = om
        self._basis_np = (sh_values(dirs, self.order, device) * om[:, None]).T  # (nc, inner texels)
        B = np.zeros((4 * ng, len(om)), np.float32)
        B[:nc] = self._basis_np
        self.basis = wp.array(np.ascontiguousarray(B.reshape(ng, 4, -1).transpose(0, 2, 1)), dtype=wp.vec4, device=device)
        self.inner = wp.array(inner.astype(np.int32), dtype=int, device=device)
        self.dirs = wp.array(texel_directions_with_border(self.face).reshape(-1, 3).astype(np.float32), dtype=wp.vec3,
                             device=device)
        tab.size, tab.groups = self.face + 2, ng
        tab.sky = wp.zeros(max(self.n_objects, 1) * int(self.dirs.shape[0]), dtype=wp.vec3, device=device)
        tab.coef = wp.zeros(max(self.n_objects, 1) * 3 * ng, dtype=wp.vec4, device=device)
        self.table = tab
        self._turned = None  # the key of the sky in tab.sky
        self._prepared = None  # the key of the sky the lists were decided for
        self.exact_count, self.bound, self.quadrature_ids, self.sky_residual = 0, np.zeros(n), None, np.zeros(3)

    def transfer_bytes(self) -> int:
        """Bytes of the transfer vectors (8 per coefficient and vertex, float32)."""
        return int(self.table.transfer.shape[0]) * 16

    def _turn(self, radiance, to_env: np.ndarray) -> None:
        from raster import parallel

        m = len(to_env) * int(self.dirs.shape[0])
        parallel.launch(turn_sky_kernel, m, [self.dirs, radiance, wp.array(to_env.astype(np.float32), dtype=wp.mat33,
                                                                           device=self.device), self.table.sky],
                        self.device, chunks=parallel.cpu_workers())

    def residual(self, radiance) -> np.ndarray:
        """(3,) ``‖L' − L'_n‖₂`` per channel: the energy of the turned sky outside the basis (the
        same at every rotation: each order's harmonics span a rotation-invariant space), on the
        cube at the map's own frame."""
        self._turn(radiance, np.eye(3)[None])
        self._turned = None
        L = self.table.sky.numpy()[:int(self.dirs.shape[0])].reshape(-1, 3)[self.inner.numpy()].astype(np.float64)
        coef = self._basis_np @ L
        return np.sqrt(np.maximum((self._omega[:, None] * L * L).sum(0) - (coef * coef).sum(0), 0.0))

    def prepare(self, radiance, e_min) -> None:
        """For the sky of map ``radiance`` (its irradiance at least ``e_min`` (3,) at every normal):
        each vertex's bound on the error of its visible fraction from the truncated sky,
        ``(‖ρ^O − ρ^O_n‖ + ‖ρ^S − ρ^S_n‖)·‖L' − L'_n‖ / E_min`` (module docstring); the vertices
        over :data:`BOUND` are left to the map quadrature, every texel, every frame."""
        from raster import parallel

        n, tab, d = self.count, self.table, self.device
        a = np.sqrt(np.maximum(self._norm2 - (self._transfer ** 2).sum(1), 0.0))
        self.sky_residual = self.residual(radiance)
        self.bound = (a.sum(1)[:, None] * self.sky_residual[None]
                      / np.maximum(np.asarray(e_min, np.float64), 1e-30)).max(1)
        exact = (self.bound > BOUND).astype(np.int32)
        tab.exact = wp.array(exact if n else np.zeros(1, np.int32), dtype=int, device=d)
        self.exact_count = int(exact.sum())
        self.quadrature_ids = wp.array(self.vertices.numpy()[:n][exact == 1].astype(np.int32), dtype=int, device=d) \
            if self.exact_count else None
        # ranges of about equal work for the CPU threads (a vertex left to the quadrature costs nothing here)
        work = np.cumsum(np.where(exact == 0, 4 * tab.groups, 0) + 1)
        w = parallel.cpu_workers()
        self.bounds = np.unique(np.concatenate([[0], np.searchsorted(work, work[-1] * np.arange(1, w) / w) if n else [],
                                                [n]]).astype(np.int64))

    def visible(self, vis: Visibility, env: EnvSG, radiance: wp.array, env_rotation, motions: list, into) -> None:
        """The listed vertices' rows of ``into = (F, E ∘ F)`` (``env_vertex_visible``'s), in place:
        the sky of map ``radiance`` (the box-filtered residual) turned by ``env_rotation`` and each
        object's rotation ``motions[k]`` (from the rest pose), projected onto the basis, then each
        vertex's sums."""
        from raster import parallel

        if not self.count:
            return
        pkey = (id(radiance), id(env.exact.texels))
        if self._prepared != pkey:
            self.prepare(radiance, env.exact.texels.numpy().reshape(-1, 3).min(0))
            self._prepared = pkey
        to_env = np.stack([np.asarray(env_rotation, np.float64).T @ np.asarray(M, np.float64) for M in motions])
        key = (id(radiance), to_env.tobytes())
        tab = self.table
        if self._turned != key:
            self._turn(radiance, to_env)
            parallel.launch(project_sky_kernel, len(motions) * tab.groups,
                            [self.basis, self.inner, tab.sky, int(self.dirs.shape[0]), tab.coef], self.device,
                            chunks=parallel.cpu_workers(), min_chunk=8)
            self._turned = key
        parallel.launch_split(moving_visible_kernel, self.bounds, [tab, vis, env, *into], self.device)
        if self.quadrature_ids is not None:
            from warp_sg.shading.vertex_visibility import env_vertex_visible

            env_vertex_visible(vis, env, int(into[0].shape[0]), self.device, ids=self.quadrature_ids, into=into)


__all__ = ["BOUND", "FACE", "MovingSky", "ORDER", "SkyTable", "cube_quadrature", "moving_visible_kernel",
           "project_sky_kernel", "sh_accumulate", "sh_norms", "sh_values", "transfer_kernel", "turn_sky_kernel"]

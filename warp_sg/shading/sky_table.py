r"""The visible sky of a moving object's vertices: their weights projected once, the sky turned into the object.

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

Both sums are linear in ``L'``. So, once per vertex (:class:`MovingSky`, in the rest pose), its
weights are projected onto the real spherical harmonics ``Y_i`` up to order :data:`ORDER`
(precomputed radiance transfer, Sloan, Kautz & Snyder, SIGGRAPH 2002) — two transfer vectors::

    t^O_i = Σ_t (1 − s_t) c_t Y_i(D_t),   t^S_i = Σ_t s_t c_t Y_i(D_t)     (:func:`transfer_kernel`);

once per sky, the map's own coefficients ``l_i = Σ_q Ω_q Y_i(d_q) L̄_q`` over its 64 × 128 cells
(:meth:`MovingSky.project`); once per frame and object, those of ``L' = L̄ ∘ M`` (``M = Rᵀ_env R``)
— the harmonics of each order span a rotation-invariant space, so a quadrature exact for
products of two of them turns them exactly, ``l'_j = Σ_p w_p Y_j(x_p) Σ_i l_i Y_i(M x_p)`` on
(ORDER+1)·(2·ORDER+1) = 153 Gauss–Legendre × uniform-φ nodes (:func:`rotation_quadrature`, host
work of ≈ 0.1 ms); then per vertex ``O ≈ t^O·l'``, ``S ≈ t^S·l'`` — 81 products instead of a
read per cone texel — and ``F`` as before (:func:`moving_visible_kernel`). The moving vertices
use it at every pose, their first frame included, so a frame stays a function of the transforms.

**The truncation, bounded.** With ``ρ`` the weights as a density (``w_t/Ω`` on texel t) and
``ρ_n``, ``L'_n`` the projections, ``Σ_t w_t L'(D_t) − t·l = ⟨ρ − ρ_n, L' − L'_n⟩`` (the
projection is orthogonal), so by Cauchy–Schwarz ``|ΔO| ≤ ‖ρ^O − ρ^O_n‖·‖L' − L'_n‖`` with
``‖ρ − ρ_n‖² = Σ_t w_t²/Ω − Σ_i t_i²`` (per vertex, once) and ``‖L' − L'_n‖² = ‖L̄‖² − Σ_i l_i²``,
the sky's energy outside the basis (the same at every rotation; :meth:`MovingSky.project`). As
``F = 1 − O/max(E, O + S)``, ``|ΔF| ≤ (|ΔO| + |ΔS|)/E``, and ``E ≥ E_min``, the least irradiance
of the map at any normal::

    |ΔF| ≤ (‖ρ^O − ρ^O_n‖ + ‖ρ^S − ρ^S_n‖)·‖L' − L'_n‖ / E_min     (MovingSky.bound),

against the exact sums ``Σ_t w_t L'(D_t)`` (up to the quadratures' own sampling of ``L̄``: the
texel sums point-sample it where the norms integrate it). A vertex whose bound exceeds
:data:`BOUND` (0.25) is left to the map quadrature, every texel, every frame
(:func:`~warp_sg.shading.vertex_visibility.env_vertex_visible`): the residual of a sky whose sun
was extracted (``env_peaks``) is smooth, ``‖L' − L'_n‖`` ≈ 0.23 (the plain scenes' sky, order 8),
bounds at most 0.09 (blob), 0.11 (torus), 0.21 (bunny), none over; with the sun left in the map
(``env_peaks = 0``) ``‖L' − L'_n‖`` > 10 and every shadowed vertex goes to the map (bounds 7–14 on
the torus; the per-texel lists that read the sky from a cube erred there by up to 0.27 too). The
bound is 30–60× the error it bounds (median), so it only catches a sharp sky.

**Measured** against the map-read quadrature at the same pose (``tests/test_moving_caches.py``;
four poses, ORDER 8): the blob (32² maps, F ≥ 0.98) within 1.0e-3 (mean 3.7e-5); a torus whose
inner side shadows itself deeply (16² maps, F down to 0.57) within 1.3e-2 (mean 1.6e-3); the
refined Stanford bunny (12 862 moving vertices, 12 032 shadowed, F down to 0.35) within 1.9e-2
(mean 8.2e-4, 99 % within 7.7e-3) — the error is the sky's horizon step rung by the truncation, at
the few vertices whose occluders' edges fall on it. Order 12 halves it (bunny 1.1e-2, mean 3.8e-4)
at twice the products; the texel lists this replaces (per texel a bilinear read of the sky turned
on a cube) were within 1.0e-4 / 2.0e-3 (blob / torus), but cost 83 ms a frame on the bunny (9.9 M
texels, 198 MB) where the transfer vectors take 8.6 MB and ≈ 3 ms of CPU.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import math

import numpy as np
import warp as wp

from precompute.environment.irradiance import irradiance_unscaled
from precompute.visibility.ssdf_wp import texel_direction_array
from warp_sg.numeric.onb import local_to_world
from warp_sg.shading.vertex_visibility import cone_in_frame, texel_ssdf, visible_share
from warp_sg.shading.visibility_terms import EnvSG, Visibility

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
    CPU runs ≈ 3× faster than one coefficient at a time)."""

    vertices: wp.array(dtype=int)
    slot: wp.array(dtype=int)
    exact: wp.array(dtype=int)
    transfer: wp.array(dtype=wp.vec4)
    coef: wp.array(dtype=wp.vec4)
    groups: int


@wp.kernel(enable_backward=False)
def transfer_kernel(base: int, vis: Visibility, ids: wp.array(dtype=int), rest_n: wp.array(dtype=wp.vec3),
                    rest_t: wp.array(dtype=wp.vec3), rest_b: wp.array(dtype=wp.vec3),
                    rest_cone: wp.array(dtype=wp.vec4), dirs: wp.array(dtype=wp.vec3), order: int,
                    norms: wp.array(dtype=float), out: wp.array2d(dtype=wp.vec2), norm2: wp.array(dtype=wp.vec2)):
    """Listed vertex ``i = base + tid``'s transfer vectors (module docstring), ``out[i, j] = Σ_t
    ((1 − s_t) c_t, s_t c_t) Y_j(D_t)`` over its texels inside the cone (rest pose), and
    ``norm2[i] = Σ_t ((1 − s_t) c_t, s_t c_t)² / Ω``. ``dirs``: the R² texel directions of the maps
    (``ssdf_wp.texel_direction_array``); the cone is tested in the vertex's frame, as
    ``env_vertex_visible_kernel`` tests it (the same texels), and a texel's world direction is
    formed only inside it."""
    i = base + wp.tid()
    cone = rest_cone[i]
    if cone[3] < 0.0:
        return
    v = ids[i]
    R = vis.mean.shape[0]
    h = _SQRT_2PI / float(R)
    om = 2.0 * wp.pi / float(R * R)
    n = wp.normalize(rest_n[i])
    t = rest_t[i]
    b = rest_b[i]
    axis_l, c_min = cone_in_frame(cone, t, b, n, h)
    acc = wp.vec2(0.0, 0.0)
    for y in range(R):
        for x in range(R):
            dl = dirs[y * R + x]
            if wp.dot(dl, axis_l) >= c_min:
                s = wp.clamp(0.5 + texel_ssdf(vis, v, y, x) / h, 0.0, 1.0)
                c = dl[2] * om
                w = wp.vec2((1.0 - s) * c, s * c)
                acc += wp.cw_mul(w, w) / om
                sh_accumulate(out, i, order, norms, local_to_world(dl, t, b, n), w)
    norm2[i] = acc


#: vertices one CPU thread computes in :func:`moving_visible_kernel` (Warp copies the kernel's
#: struct arguments at each thread's entry; ``raster.parallel.launch(per_thread=...)``)
VERTICES_PER_THREAD = 16


@wp.kernel(enable_backward=False)
def moving_visible_kernel(base: int, per: int, tab: SkyTable, rows: wp.array(dtype=int), vis: Visibility, env: EnvSG,
                          out: wp.array(dtype=wp.vec3), out_irr: wp.array(dtype=wp.vec3)):
    """Listed vertices ``k = base + tid·per + s`` (``s < per``; ``v = tab.vertices[k]``; with
    ``rows`` not empty, the table's rows ``rows[base + tid·per + s]`` instead): ``out[v]``
    the visible fraction and ``out_irr[v] = E ∘ F``, as ``env_vertex_visible_kernel`` with the
    cone's sums ``O = t^O·l``, ``S = t^S·l`` from the vertex's transfer vectors and its object's
    turned sky's coefficients ``l`` (module docstring); a vertex left to the map quadrature
    (``tab.exact[k]``) is not written."""
    k0 = base + wp.tid() * per
    h = _SQRT_2PI / float(vis.mean.shape[0])
    one = wp.vec4(1.0, 1.0, 1.0, 1.0)
    n_rows = rows.shape[0]
    for s in range(per):
        k = k0 + s
        if n_rows > 0:
            if k >= n_rows:
                break
            k = rows[k]
        elif k >= tab.vertices.shape[0]:
            break
        if tab.exact[k] != 0:
            continue
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
            occ_sum = wp.vec3(wp.dot(o0, one), wp.dot(o1, one), wp.dot(o2, one))
            seen_sum = wp.vec3(wp.dot(s0, one), wp.dot(s1, one), wp.dot(s2, one))
            f = visible_share(occ_sum, seen_sum, ex, cone, n, h)
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


def rotation_quadrature(order: int) -> tuple:
    """(points (P, 3), weights (P,)): Gauss–Legendre in z × uniform in φ, ``order + 1`` by
    ``2·order + 1`` nodes — exact for products of two harmonics up to ``order`` (polynomials of
    degree 2·order), so ``l'_j = Σ_p w_p Y_j(x_p) Σ_i l_i Y_i(M x_p)`` gives a band-limited sky's
    coefficients after a rotation ``M`` exactly (each order's harmonics span a rotation-invariant
    space)."""
    z, wz = np.polynomial.legendre.leggauss(order + 1)
    m = 2 * order + 1
    phi = (np.arange(m) + 0.5) * 2.0 * np.pi / m
    Z, P = np.meshgrid(z, phi, indexing="ij")
    S = np.sqrt(np.maximum(1.0 - Z * Z, 0.0))
    return (np.stack([S * np.cos(P), S * np.sin(P), Z], -1).reshape(-1, 3),
            np.repeat(wz, m) * 2.0 * np.pi / m)


class MovingSky:
    """The :class:`SkyTable` of the moving vertices of one installed visibility (module docstring).

    ``vertices`` (mesh ids), ``slot`` (their object's index among the moving objects) and their
    rest rows on the device (normals, SSDF frames, cones): the transfer vectors are computed once,
    here; which vertices are left to the map quadrature instead is decided per sky (:meth:`prepare`)."""

    def __init__(self, vis: Visibility, vertices: wp.array, slot: np.ndarray, rest: tuple, n_objects: int, device,
                 order: int | None = None):
        from raster import parallel

        n = int(vertices.shape[0])
        order = ORDER if order is None else order
        self.device, self.count, self.n_objects, self.order = device, n, int(n_objects), int(order)
        self.vis, self.vertices, self.rest = vis, vertices, rest
        nc = (self.order + 1) ** 2
        self.norms = wp.array(sh_norms(self.order).astype(np.float32), dtype=float, device=device)
        tab = SkyTable()
        tab.vertices, tab.slot = vertices, wp.array(np.asarray(slot, np.int32), dtype=int, device=device)
        transfer = wp.zeros((max(n, 1), nc), dtype=wp.vec2, device=device)
        norm2 = wp.zeros(max(n, 1), dtype=wp.vec2, device=device)
        if n:
            dirs = texel_direction_array(vis.mean.shape[0], device)
            parallel.launch(transfer_kernel, n, [vis, vertices, *rest, dirs, self.order, self.norms, transfer, norm2],
                            device, min_chunk=64)
        # (host copies for the bound, :meth:`prepare`; the kernels' layout of four coefficients a group)
        self._transfer, self._norm2 = transfer.numpy()[:n].astype(np.float64), norm2.numpy()[:n].astype(np.float64)
        ng = -(-nc // 4)
        T = np.zeros((max(n, 1), 4 * ng, 2), np.float32)
        T[:n, :nc] = self._transfer
        tab.transfer = wp.array(T.reshape(-1, ng, 4, 2).transpose(0, 1, 3, 2).reshape(-1, 4), dtype=wp.vec4,
                                device=device)
        del transfer, norm2
        self._x, self._xw = rotation_quadrature(self.order)
        self._yx = sh_values(self._x, self.order, device) * self._xw[:, None]  # (P, nc): w_p Y(x_p)
        self._map_coef = None  # the map's coefficients (nc, 3), its frame (:meth:`prepare`)
        self._ng = tab.groups = ng
        self.table = tab
        self._turned = None  # the key of the coefficients in tab.coef
        self._prepared = None  # the key of the sky the bounds were computed for
        self.exact_count, self.bound, self.quadrature_ids, self.sky_residual = 0, np.zeros(n), None, np.zeros(3)
        self._exact = np.zeros(n, np.int32)
        self._vertices_np = vertices.numpy()[:n].astype(np.int32)
        self._all_rows = wp.zeros(0, dtype=int, device=device)  # (moving_visible_kernel's "every row")

    def transfer_bytes(self) -> int:
        """Bytes of the transfer vectors (8 per coefficient and vertex, float32)."""
        return int(self.table.transfer.shape[0]) * 16

    def project(self, radiance) -> tuple:
        """``(l (nc, 3), ‖L̄ − L̄_n‖₂ (3,))``: the map's coefficients in its own frame,
        ``l_i = Σ_q Ω_q Y_i(d_q) L̄_q`` over its cells (centres ``d_q``, solid angles ``Ω_q``), and
        the energy outside the basis, ``‖L̄‖² − Σ_i l_i²`` (the same at every rotation)."""
        from warp_sg.scene.envmap import texel_directions, texel_solid_angles

        L = np.asarray(radiance.numpy(), np.float64)
        h, w = L.shape[:2]
        om = texel_solid_angles(h, w).reshape(-1)
        L = L.reshape(-1, 3)
        Y = sh_values(texel_directions(h, w).reshape(-1, 3), self.order, self.device)
        coef = (Y * om[:, None]).T @ L
        return coef, np.sqrt(np.maximum((om[:, None] * L * L).sum(0) - (coef * coef).sum(0), 0.0))

    def turned(self, to_env: np.ndarray) -> np.ndarray:
        """(objects, nc, 3): the coefficients of the map's projection seen from each object's frame,
        ``L'(D) = L̄_n(M_k D)`` (``to_env[k] = M_k = Rᵀ_env·R_k``), by :func:`rotation_quadrature`."""
        out = np.empty((len(to_env), self._yx.shape[1], 3))
        for k, M in enumerate(to_env):
            out[k] = self._yx.T @ (sh_values(self._x @ np.asarray(M, np.float64).T, self.order, self.device)
                                   @ self._map_coef)
        return out

    def prepare(self, radiance, e_min) -> None:
        """For the sky of map ``radiance`` (its irradiance at least ``e_min`` (3,) at every normal):
        each vertex's bound on the error of its visible fraction from the truncated sky,
        ``(‖ρ^O − ρ^O_n‖ + ‖ρ^S − ρ^S_n‖)·‖L' − L'_n‖ / E_min`` (module docstring); the vertices
        over :data:`BOUND` are left to the map quadrature, every texel, every frame."""
        n, tab, d = self.count, self.table, self.device
        a = np.sqrt(np.maximum(self._norm2 - (self._transfer ** 2).sum(1), 0.0))
        self._map_coef, self.sky_residual = self.project(radiance)
        self.bound = (a.sum(1)[:, None] * self.sky_residual[None]
                      / np.maximum(np.asarray(e_min, np.float64), 1e-30)).max(1)
        exact = (self.bound > BOUND).astype(np.int32)
        self._exact = exact
        tab.exact = wp.array(exact if n else np.zeros(1, np.int32), dtype=int, device=d)
        self.exact_count = int(exact.sum())
        self.quadrature_ids = wp.array(self.vertices.numpy()[:n][exact == 1].astype(np.int32), dtype=int, device=d) \
            if self.exact_count else None

    def visible(self, vis: Visibility, env: EnvSG, radiance: wp.array, env_rotation, motions: list, into,
                rows: np.ndarray | None = None) -> None:
        """The listed vertices' rows of ``into = (F, E ∘ F)`` (``env_vertex_visible``'s), in place:
        the sky of map ``radiance`` (the box-filtered residual) turned by ``env_rotation`` and each
        object's rotation ``motions[k]`` (from the rest pose) in the harmonics, then each vertex's
        sums. ``rows``: only those of the table (ascending; default all)."""
        from raster import parallel

        if not self.count:
            return
        pkey = (id(radiance), id(env.exact.texels))
        if self._prepared != pkey:
            self.prepare(radiance, env.exact.texels.numpy().reshape(-1, 3).min(0))
            self._prepared = pkey
        to_env = np.stack([np.asarray(env_rotation, np.float64).T @ np.asarray(M, np.float64) for M in motions])
        key = (pkey, to_env.tobytes())
        tab = self.table
        if self._turned != key:
            c = np.zeros((len(motions), 4 * self._ng, 3), np.float32)
            c[:, :self._yx.shape[1]] = self.turned(to_env)
            tab.coef = wp.array(c.reshape(len(motions), self._ng, 4, 3).transpose(0, 1, 3, 2).reshape(-1, 4),
                                dtype=wp.vec4, device=self.device)
            self._turned = key
        if rows is None:
            n, rows_w, quad = self.count, self._all_rows, self.quadrature_ids
        else:
            n = len(rows)
            rows_w = wp.array(np.asarray(rows, np.int32), dtype=int, device=self.device) if n else self._all_rows
            quad = None
            if self.exact_count and n:
                sel = np.asarray(rows)[self._exact[np.asarray(rows)] != 0]
                quad = wp.array(self._vertices_np[sel], dtype=int, device=self.device) if len(sel) else None
        if n:
            parallel.launch(moving_visible_kernel, n, [tab, rows_w, vis, env, *into], self.device, min_chunk=512,
                            per_thread=VERTICES_PER_THREAD, chunks=2 * parallel.cpu_workers())  # (each range: a dispatch)
        if quad is not None:
            from warp_sg.shading.vertex_visibility import env_vertex_visible

            env_vertex_visible(vis, env, int(into[0].shape[0]), self.device, ids=quad, into=into)


__all__ = ["BOUND", "MovingSky", "ORDER", "SkyTable", "VERTICES_PER_THREAD", "moving_visible_kernel",
           "rotation_quadrature", "sh_accumulate", "sh_norms", "sh_values", "transfer_kernel"]

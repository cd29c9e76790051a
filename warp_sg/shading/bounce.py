r"""Light that bounces: the indirect light of every vertex from the gather rows
(:mod:`precompute.visibility.gather`), per frame, and what the shading kernel reads of it.

Per vertex ``v`` (the direct-to-indirect transfer of Hašan, Pellacini and Bala 2006, iterated as
in a gathering radiosity solver — Jacobi, one sparse product per bounce)::

    B_0[v]     = A[v] ∘ G_direct[v] + Le[v]                 (outgoing radiance of the direct light)
    B_k[v]     = A[v] ∘ (T · B_{k−1})[v]                    (k = 1 … bounces − 1)
    B_tot      = Σ_k B_k,        E_ind[v] = π (T · B_tot)[v]

``G_direct = E_direct/π`` is the vertex's direct irradiance (lights, the environment's peaks and
its diffuse term, with the renderer's own visibility; :mod:`warp_sg.renderer.interreflection`
shades the vertices with a white Lambert material for it), ``A`` the vertex's albedo as a sender —
its texel's diffuse albedo ``kd`` (textures and vertex colours at the vertex) plus the specular
lobe's hemispherical albedo ``Ā_s = (1/π)∫∫ f_s cos θ_o cos θ_i`` (:func:`specular_albedo`): a
glossy sender as its view-independent average, the light it reflects spread evenly over its
hemisphere. ``Le`` the vertex's emission. Bounces stop at ``[render] bounces`` or once a bounce
adds less than :data:`STOP` of the light gathered so far (Σ over vertices and channels).

**Diffuse receivers.** The kernel adds ``ρd(o) ∘ Σ_k b_k E_ind[i_k]`` — the vertices' indirect
irradiance interpolated like the environment's visible irradiance.

**Glossy receivers.** The radiance arriving at ``v`` from its gather's directions is kept as
amplitudes of :data:`LOBES` fixed world-space spherical Gaussians ``Ĝ_m`` (axes on a Fibonacci
sphere, sharpness :data:`LOBE_SHARPNESS`, normalised: ∫Ĝ_m = 1)::

    L_ind(i) ≈ Σ_m a_m[v] Ĝ_m(i),     a_m[v] = Σ_r B_tot[s_r] dω_r κ_m(d_r)

(each reference ``r`` of the row: sender ``s_r``, direction ``d_r``, solid angle ``dω_r = π w_r /
(n·d_r)``, shared between its two nearest lobes by ``κ``). The shading kernel interpolates the
amplitudes with the barycentrics and, per slice lobe ``G(p, λ)`` of the BRDF (eq. 41), adds the
mean indirect radiance over the lobe beside the environment's ``ΓL/∫G`` of its visible part (the
indirect light fills the directions the SSDF cuts out)::

    L̄_ind(p, λ) = [Σ_m a_m I_m / Σ_m c_m(n) I_m] · fh(θh, λ)/∫G(λ),     I_m = ∫G Ĝ_m

— the lobes' reconstruction divided by that of a unit radiance over the receiver's hemisphere
(``c_m(n)``, :func:`unit_table`, tabulated over the normal) and times the exact share of the lobe
above the horizon (``fh`` of :mod:`warp_sg.sg.fh` at ``θh = asin(p·n)``). The fixed lobes blur and
spill below the horizon; the ratio cancels both for a uniform surround (without it a glossy
receiver seeing a floor at 60° from its normal lost 18 % of it, at 80° 33 %). Lobes whose product
with ``G(p, λ)`` is under ``e^{−5}`` of its peak are skipped in both sums (``G_m`` at more than
``5 (λ + λ_m)/(λ λ_m)`` of ``1 − p·axis_m``).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import math

import numpy as np
import warp as wp

from warp_sg.brdf.kernel.albedo import _radical_inverse as radical_inverse
from warp_sg.brdf.kernel.material_wp import Material, material_funcs
from warp_sg.sg.algebra_wp import sg_inner, sg_integral
from warp_sg.sg.fh import fh_table_wp
from warp_sg.shading.surface import MaterialTextures, textured_material
from warp_sg.shading.surface_layers import Layers, emission_at, vertex_coloured

#: a bounce that adds less than this share of the light gathered so far ends the iteration
STOP = 0.01
#: fixed world-space lobes of the indirect radiance seen by glossy receivers, and their sharpness
LOBES = 32
LOBE_SHARPNESS = 8.0
#: lobes whose product with a BRDF lobe is below e^-CUT_EXPONENT of its peak are skipped
CUT_EXPONENT = wp.constant(5.0)
#: the smallest cosine a reference's solid angle is computed with (grazing rays: dω = π w / cos)
MIN_COS = 0.02


@wp.struct
class Indirect:
    """What the shading kernel reads of the indirect light (module docstring): per vertex the
    irradiance ``irr`` (V,) and the lobe amplitudes ``lobes`` (V, M); the lobes' axes and
    sharpness; ``count`` M (0: no glossy receiver reads them)."""

    irr: wp.array(dtype=wp.vec3)
    lobes: wp.array2d(dtype=wp.vec3)
    axis: wp.array(dtype=wp.vec3)
    lam: float
    count: int
    unit: wp.array2d(dtype=float)  # (Q², M): c_m(n) on the octahedral grid of normals (unit_table)
    unit_q: int
    fh: wp.array2d(dtype=float)  # warp_sg.sg.fh's ratio table


def lobe_axes(m: int = LOBES) -> np.ndarray:
    """(m, 3) float32 unit axes on a Fibonacci sphere."""
    k = np.arange(m) + 0.5
    z = 1.0 - 2.0 * k / m
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=1).astype(np.float32)


def nearest_lobes(dirs: np.ndarray, axes: np.ndarray, chunk: int = 65536):
    """Per direction its two nearest lobes and the first's share: ``(l1, l2 (n,) int32, κ1 (n,)
    float32)``, κ1 = e^{λ c1}/(e^{λ c1} + e^{λ c2}) with the cosines c and λ = 2 × the lobes'
    sharpness (a soft split that is ½ on the bisector)."""
    n = len(dirs)
    l1 = np.zeros(n, np.int32)
    l2 = np.zeros(n, np.int32)
    k1 = np.ones(n, np.float32)
    for s in range(0, n, chunk):
        c = np.asarray(dirs[s:s + chunk], np.float32) @ axes.T
        two = np.argpartition(-c, 1, axis=1)[:, :2]
        c2 = np.take_along_axis(c, two, axis=1)
        swap = c2[:, 1] > c2[:, 0]
        two[swap] = two[swap][:, ::-1]
        c2[swap] = c2[swap][:, ::-1]
        l1[s:s + chunk], l2[s:s + chunk] = two[:, 0], two[:, 1]
        k1[s:s + chunk] = 1.0 / (1.0 + np.exp(-2.0 * LOBE_SHARPNESS * (c2[:, 0] - c2[:, 1])))
    return l1, l2, k1


#: normals per side of the octahedral grid of :func:`unit_table`
UNIT_Q = 32


def octahedral_cell_normals(q: int = UNIT_Q) -> np.ndarray:
    """(q², 3) unit normals at the centres of a q×q octahedral grid (row ``y``, column ``x``)."""
    c = (np.arange(q) + 0.5) / q * 2 - 1
    x, y = np.meshgrid(c, c)
    x, y = x.ravel(), y.ravel()
    z = 1 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0.0)
    x = x + np.where(x >= 0, -t, t)
    y = y + np.where(y >= 0, -t, t)
    d = np.stack([x, y, z], axis=1)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def unit_table(axes: np.ndarray, q: int = UNIT_Q, samples: int = 8192) -> np.ndarray:
    """(q², M) float32: per normal of the octahedral grid, the lobe amplitudes ``c_m(n)`` of a unit
    radiance over its upper hemisphere, split between lobes as :func:`nearest_lobes` splits the
    references (Fibonacci directions of solid angle 4π/samples)."""
    k = np.arange(samples) + 0.5
    z = 1.0 - 2.0 * k / samples
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    d = np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=1)
    l1, l2, k1 = nearest_lobes(d, axes)
    P = np.zeros((samples, len(axes)))
    np.add.at(P, (np.arange(samples), l1), k1)
    np.add.at(P, (np.arange(samples), l2), 1.0 - k1)
    W = (octahedral_cell_normals(q) @ d.T > 0.0) * (4.0 * math.pi / samples)
    return (W @ P).astype(np.float32)


_UNIT: dict = {}


def no_indirect(device) -> Indirect:
    """The argument of the kernel variants without bounces."""
    from warp_sg.sg.fh import fh_table_array

    ind = Indirect()
    ind.irr = wp.zeros(1, dtype=wp.vec3, device=device)
    ind.lobes = wp.zeros((1, 1), dtype=wp.vec3, device=device)
    ind.axis = wp.zeros(1, dtype=wp.vec3, device=device)
    ind.lam = LOBE_SHARPNESS
    ind.count = 0
    ind.unit = wp.zeros((1, 1), dtype=float, device=device)
    ind.unit_q = 1
    ind.fh = fh_table_array(device)
    return ind


# --------------------------------------------------------------------------------------------
# per-frame kernels
# --------------------------------------------------------------------------------------------
@wp.kernel(enable_backward=False)
def gather_kernel(base: int, offsets: wp.array(dtype=int), senders: wp.array(dtype=int),
                  weights: wp.array(dtype=float), b: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    """``out[v] = Σ_r w_r b[s_r]`` over row ``v = base + tid``: the gathered radiance ``(T · b)[v]``."""
    v = base + wp.tid()
    acc = wp.vec3(0.0, 0.0, 0.0)
    for r in range(offsets[v], offsets[v + 1]):
        acc += b[senders[r]] * weights[r]
    out[v] = acc


@wp.kernel(enable_backward=False)
def bounce_kernel(albedo: wp.array(dtype=wp.vec3), g: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3),
                  total: wp.array(dtype=wp.vec3)):
    """One bounce at vertex ``v``: ``b[v] = A[v] ∘ g[v]`` (what it sends on), added to ``total``."""
    v = wp.tid()
    x = wp.cw_mul(albedo[v], g[v])
    b[v] = x
    total[v] = total[v] + x


@wp.kernel(enable_backward=False)
def lobes_kernel(base: int, offsets: wp.array(dtype=int), senders: wp.array(dtype=int), weights: wp.array(dtype=float),
                 dirs: wp.array(dtype=wp.vec3), l1: wp.array(dtype=int), l2: wp.array(dtype=int),
                 k1: wp.array(dtype=float), normals: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3),
                 out: wp.array2d(dtype=wp.vec3)):
    """``out[v, m] = Σ_r b[s_r] dω_r κ_m(d_r)`` (module docstring): the radiance row ``v`` sees,
    as amplitudes of the fixed lobes (its two nearest per reference); ``v = base + tid``."""
    v = base + wp.tid()
    for m in range(out.shape[1]):
        out[v, m] = wp.vec3(0.0, 0.0, 0.0)
    n = wp.normalize(normals[v])
    for r in range(offsets[v], offsets[v + 1]):
        c = wp.max(wp.dot(dirs[r], n), MIN_COS)
        x = b[senders[r]] * (wp.pi * weights[r] / c)
        out[v, l1[r]] = out[v, l1[r]] + x * k1[r]
        out[v, l2[r]] = out[v, l2[r]] + x * (1.0 - k1[r])


@wp.kernel(enable_backward=False)
def blend_kernel(base: int, index: wp.array2d(dtype=int), weight: wp.array2d(dtype=float),
                 x: wp.array2d(dtype=wp.vec3)):
    """``x[v, :] = Σ_k weight[v, k] x[index[v, k], :]`` for every vertex ``v = base + tid`` that is not
    a representative (``index[v, 0] ≠ v``): a mesh gathered at representatives
    (:class:`Transfer`), blended as its SSDFs were (``precompute.visibility.representatives``)."""
    v = base + wp.tid()
    if index[v, 0] != v:
        for j in range(x.shape[1]):
            s = wp.vec3(0.0, 0.0, 0.0)
            for k in range(index.shape[1]):
                s += x[index[v, k], j] * weight[v, k]
            x[v, j] = s


@wp.func
def unit_row(ind: Indirect, n: wp.vec3) -> int:
    """The row of :func:`unit_table` nearest normal ``n`` (octahedral map)."""
    s = wp.abs(n[0]) + wp.abs(n[1]) + wp.abs(n[2])
    x = n[0] / s
    y = n[1] / s
    if n[2] < 0.0:
        xo = (1.0 - wp.abs(y)) * wp.sign(x)
        y = (1.0 - wp.abs(x)) * wp.sign(y)
        x = xo
    q = ind.unit_q
    cx = wp.clamp(int((x * 0.5 + 0.5) * float(q)), 0, q - 1)
    cy = wp.clamp(int((y * 0.5 + 0.5) * float(q)), 0, q - 1)
    return cy * q + cx


@wp.func
def lobe_mean_radiance(ind: Indirect, i0: int, i1: int, i2: int, b0: float, b1: float, b2: float, n: wp.vec3,
                       p: wp.vec3, lam: float) -> wp.vec3:
    """The mean indirect radiance over the lobe ``G(p, λ)`` at a point of normal ``n``:
    ``[Σ_m a_m I_m / Σ_m c_m(n) I_m] · fh(θh, λ)/∫G(λ)``, the amplitudes interpolated from the
    triangle's vertices (module docstring)."""
    acc = wp.vec3(0.0, 0.0, 0.0)
    den = float(0.0)
    row = unit_row(ind, n)
    # lobes whose product with G(p, λ) is below e^-5 of its peak are left out (both sums alike)
    cut = 1.0 - CUT_EXPONENT * (lam + ind.lam) / wp.max(lam * ind.lam, 1.0e-6)
    for m in range(ind.count):
        if wp.dot(p, ind.axis[m]) < cut:
            continue
        im = sg_inner(p, lam, ind.axis[m], ind.lam)
        den += ind.unit[row, m] * im
        a = ind.lobes[i0, m] * b0 + ind.lobes[i1, m] * b1 + ind.lobes[i2, m] * b2
        if a[0] + a[1] + a[2] > 0.0:
            acc += a * im
    if den <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    th = wp.asin(wp.clamp(wp.dot(p, n), -1.0, 1.0))
    return acc * (fh_table_wp(ind.fh, th, lam) / (sg_integral(lam) * den))


@wp.func
def indirect_irradiance(ind: Indirect, i0: int, i1: int, i2: int, b0: float, b1: float, b2: float) -> wp.vec3:
    """The vertices' indirect irradiance ``E_ind`` interpolated with the barycentrics."""
    return ind.irr[i0] * b0 + ind.irr[i1] * b1 + ind.irr[i2] * b2


_INDIRECT_SPECULAR: dict = {}


def indirect_specular_func(MF):
    """The ``@wp.func`` ``indirect_specular(mat, o_l, ts, bs, ns, irr, ind, iv, bw)`` of the material
    functions ``MF`` (``material_funcs``; cached per model set): the indirect light of every slice
    lobe of the BRDF (eq. 41's lobes, :func:`lobe_mean_radiance` each) for a kernel variant without
    the environment's specular loop, where it is added per lobe instead."""
    if MF.tag in _INDIRECT_SPECULAR:
        return _INDIRECT_SPECULAR[MF.tag]
    from warp_sg.numeric.onb import local_to_world
    from warp_sg.sg.algebra_wp import sg_product_lobe
    from warp_sg.sg.irradiance import sg_irradiance_norm
    from warp_sg.shading.visibility_terms import CC_LAM

    slice_lobe_count, shading_slice_lobe = MF.slice_lobe_count, MF.shading_slice_lobe

    @wp.func(name="indirect_specular" + MF.tag)
    def indirect_specular(mat: Material, o_l: wp.vec3, ts: wp.vec3, bs: wp.vec3, ns: wp.vec3,
                          irr: wp.array2d(dtype=float), ind: Indirect, iv: wp.vec3i, bw: wp.vec3) -> wp.vec3:
        sind = wp.vec3(0.0, 0.0, 0.0)
        for k in range(slice_lobe_count(mat)):
            pw_l, lw, mw = shading_slice_lobe(mat, o_l, k)
            e = sg_irradiance_norm(irr, pw_l[2], lw) * sg_integral(lw)
            if e > 0.0 and wp.length_sq(mw) > 0.0:
                pa, lam = sg_product_lobe(ns, CC_LAM, local_to_world(pw_l, ts, bs, ns), lw)
                sind += wp.cw_mul(mw, lobe_mean_radiance(ind, iv[0], iv[1], iv[2], bw[0], bw[1], bw[2], ns, pa,
                                                         lam)) * e
        return sind

    _INDIRECT_SPECULAR[MF.tag] = indirect_specular
    return indirect_specular


# --------------------------------------------------------------------------------------------
# senders: albedo and emission per vertex, the specular albedo per material
# --------------------------------------------------------------------------------------------
_SENDER_KERNELS: dict = {}


def sender_kernel(models):
    """The kernel of :func:`sender_arrays` for the material model codes ``models`` (cached)."""
    key = tuple(sorted(int(m) for m in models))
    if key in _SENDER_KERNELS:
        return _SENDER_KERNELS[key]
    MF = material_funcs(key)
    brdf_eval, brdf_diffuse, brdf_sample, brdf_pdf = MF.brdf_eval, MF.brdf_diffuse, MF.brdf_sample, MF.brdf_pdf

    def spec_albedo(mats: wp.array(dtype=Material), views: int, samples: int, out: wp.array2d(dtype=wp.vec3)):
        """``out[m, j]`` = the specular directional albedo of material ``m`` at the ``j``-th of
        ``views`` cosine-distributed view angles (importance-sampled with the model's own
        sampling, Hammersley points); their mean is ``Ā_s``."""
        mi, j = wp.tid()
        mat = mats[mi]
        ct = wp.sqrt((float(j) + 0.5) / float(views))
        st = wp.sqrt(wp.max(1.0 - ct * ct, 0.0))
        o = wp.vec3(st, 0.0, ct)
        acc = wp.vec3(0.0, 0.0, 0.0)
        for s in range(samples):
            i = brdf_sample(mat, o, wp.vec2((float(s) + 0.5) / float(samples), radical_inverse(s)))  # (Hammersley)
            if i[2] > 0.0:
                p = brdf_pdf(mat, o, i)
                if p > 0.0:
                    acc += (brdf_eval(mat, o, i) - brdf_diffuse(mat, o, i)) * (i[2] / p)
        out[mi, j] = acc / float(samples)

    def senders(tri_id: wp.array(dtype=int), bary: wp.array(dtype=wp.vec2), tris: wp.array(dtype=wp.vec3i),
                uvs: wp.array(dtype=wp.vec2), tri_material: wp.array(dtype=int), mats: wp.array(dtype=Material),
                tex: MaterialTextures, lay: Layers, spec: wp.array(dtype=wp.vec3), albedo: wp.array(dtype=wp.vec3),
                emit: wp.array(dtype=wp.vec3)):
        """Vertex ``v``'s albedo as a sender, ``kd`` of its texel (textures and vertex colours at
        the vertex) plus its material's ``Ā_s``, and its emission (module docstring)."""
        v = wp.tid()
        t = tri_id[v]
        if t < 0:
            albedo[v] = wp.vec3(0.0, 0.0, 0.0)
            emit[v] = wp.vec3(0.0, 0.0, 0.0)
            return
        tri = tris[t]
        b1 = bary[v][0]
        b2 = bary[v][1]
        b0 = 1.0 - b1 - b2
        mi = tri_material[t]
        uv = uvs[tri[0]] * b0 + uvs[tri[1]] * b1 + uvs[tri[2]] * b2
        mat = vertex_coloured(textured_material(mats[mi], tex, mi, uv), lay, tri[0], tri[1], tri[2], b0, b1, b2)
        kd = wp.vec3(wp.clamp(mat.kd[0], 0.0, 1.0), wp.clamp(mat.kd[1], 0.0, 1.0), wp.clamp(mat.kd[2], 0.0, 1.0))
        albedo[v] = kd + spec[mi]
        emit[v] = emission_at(lay, tex, mi, uv)

    name = "senders" + MF.tag
    spec_albedo.__name__ = spec_albedo.__qualname__ = "spec_albedo" + MF.tag
    senders.__name__ = senders.__qualname__ = name
    out = (wp.kernel(spec_albedo, enable_backward=False, module="unique"),
           wp.kernel(senders, enable_backward=False, module="unique"))
    _SENDER_KERNELS[key] = out
    return out


def specular_albedo(materials, models, device, views: int = 16, samples: int = 512) -> np.ndarray:
    """(n_materials, 3) ``Ā_s`` of the packed kernel materials (module docstring)."""
    k, _ = sender_kernel(models)
    n = int(materials.shape[0])
    out = wp.zeros((max(n, 1), int(views)), dtype=wp.vec3, device=device)
    if n:
        wp.launch(k, dim=(n, int(views)), inputs=[materials, int(views), int(samples), out], device=device)
    return np.clip(out.numpy().mean(axis=1), 0.0, 1.0)


def sender_arrays(tri_id, bary, geo, materials, models, tex, lay, spec, device):
    """``(albedo, emission)`` (V,) vec3 device arrays of the vertices (``tri_id``, ``bary``: a
    triangle and the barycentrics that select each vertex, ``warp_sg.scene.geometry.vertex_samples``;
    ``geo``: the kernel's ``GeometryArrays``; ``spec``: :func:`specular_albedo` per material)."""
    _, k = sender_kernel(models)
    nv = int(tri_id.shape[0])
    albedo = wp.zeros(max(nv, 1), dtype=wp.vec3, device=device)
    emit = wp.zeros(max(nv, 1), dtype=wp.vec3, device=device)
    sp = wp.array(np.asarray(spec, np.float32).reshape(-1, 3), dtype=wp.vec3, device=device)
    if nv:
        wp.launch(k, dim=nv, inputs=[tri_id, bary, geo.tris, geo.uvs, geo.tri_material, materials, tex, lay, sp,
                                     albedo, emit], device=device)
    return albedo, emit


# --------------------------------------------------------------------------------------------
# the bounces
# --------------------------------------------------------------------------------------------
class Transfer:
    """The gather rows on the device with each reference's direction and lobe split
    (:class:`precompute.visibility.gather.GatherData`; built once per installed geometry).
    :meth:`turn` turns the directions of rows whose object moved (a group's rows hold under its
    rigid motions, :mod:`precompute.visibility.gather`)."""

    def __init__(self, data, device, blend=None):
        self.device = device
        self.data = data
        self.blend = blend  # (index (V, k), weight (V, k)): rows at representatives, blended (blend_kernel)
        self.n = data.n_vertices
        self.offsets, self.senders, self.weights, self.dirs = data.device_arrays(device)
        axes = lobe_axes()
        self.axes = axes
        self.axis = wp.array(axes, dtype=wp.vec3, device=device)
        if "unit" not in _UNIT:
            _UNIT["unit"] = unit_table(axes)
        self.unit = wp.array(_UNIT["unit"], dtype=float, device=device)
        self.rest_dirs = self.dirs.numpy().copy()
        self._split(self.rest_dirs)

    def _split(self, dirs):
        l1, l2, k1 = nearest_lobes(dirs, self.axes)
        self.l1 = wp.array(l1, dtype=int, device=self.device)
        self.l2 = wp.array(l2, dtype=int, device=self.device)
        self.k1 = wp.array(k1, dtype=float, device=self.device)

    def turn(self, turns, rows=None) -> None:
        """``turns``: ``[(vertex ids, R)]``: the references of those vertices' rows point along their
        rest direction turned by ``R`` (3×3), the others' along their rest direction; ``rows``: rows
        cast at the current pose that replace those vertices' own
        (:func:`precompute.visibility.gather_pose.posed_rows`)."""
        from precompute.visibility.gather_pose import posed_rows

        off, snd, w, d = posed_rows(self.data, self.rest_dirs, turns, rows)
        one = lambda a, z, t: wp.array(a if len(a) else z, dtype=t, device=self.device)  # noqa: E731
        self.offsets = wp.array(off, dtype=int, device=self.device)
        self.senders, self.weights = one(snd, np.zeros(1, np.int32), int), one(w, np.zeros(1, np.float32), float)
        self.dirs = one(d, np.zeros((1, 3), np.float32), wp.vec3)
        self.l1 = None  # (the lobe split of the new directions: at the next solve that reads the lobes)

    def _launch(self, kernel, inputs):
        from raster import parallel

        parallel.launch(kernel, self.n, inputs, self.device, min_chunk=1024)

    def _gather(self, b, out):
        """``out = T · b`` at every row, then blended where the rows are at representatives."""
        self._launch(gather_kernel, [self.offsets, self.senders, self.weights, b, out])
        self._blend(out.reshape((self.n, 1)))

    def _blend(self, x):
        if self.blend is not None:
            self._launch(blend_kernel, [self.blend[0], self.blend[1], x])

    def solve(self, g_direct, albedo, emit, normals, bounces: int, lobes: bool, stop: float = STOP):
        """``(Indirect, bounces run)`` of the direct light ``g_direct`` = E_direct/π per vertex
        (module docstring)."""
        d, n = self.device, self.n
        b = wp.empty(n, dtype=wp.vec3, device=d)
        total = wp.zeros(n, dtype=wp.vec3, device=d)
        wp.launch(bounce_kernel, dim=n, inputs=[albedo, g_direct, b, total], device=d)
        total_np = total.numpy() + emit.numpy()[:n]
        total = wp.array(total_np, dtype=wp.vec3, device=d)
        b = wp.array(total_np, dtype=wp.vec3, device=d)  # B_0 (with the emission)
        g = wp.empty(n, dtype=wp.vec3, device=d)
        done = 1
        gathered = float(np.abs(total_np).sum())
        while done < bounces:
            self._gather(b, g)
            wp.launch(bounce_kernel, dim=n, inputs=[albedo, g, b, total], device=d)
            added = float(np.abs(b.numpy()).sum())
            done += 1
            gathered += added
            if added < stop * gathered:
                break
        ind = no_indirect(d)
        irr = wp.empty(n, dtype=wp.vec3, device=d)
        self._gather(total, irr)
        ind.irr = wp.array(irr.numpy() * np.float32(math.pi), dtype=wp.vec3, device=d)
        ind.axis = self.axis
        ind.lam = LOBE_SHARPNESS
        if lobes:
            if self.l1 is None:
                self._split(self.dirs.numpy())
            ind.lobes = wp.empty((n, int(self.axis.shape[0])), dtype=wp.vec3, device=d)
            self._launch(lobes_kernel, [self.offsets, self.senders, self.weights, self.dirs, self.l1, self.l2,
                                        self.k1, normals, total, ind.lobes])
            self._blend(ind.lobes)
            ind.count = int(self.axis.shape[0])
            ind.unit, ind.unit_q = self.unit, UNIT_Q
        else:
            ind.lobes = wp.zeros((1, 1), dtype=wp.vec3, device=d)
            ind.count = 0
        return ind, done


__all__ = ["Indirect", "Transfer", "no_indirect", "lobe_axes", "nearest_lobes", "gather_kernel", "bounce_kernel",
           "lobes_kernel", "lobe_mean_radiance", "indirect_irradiance", "sender_kernel", "sender_arrays",
           "specular_albedo", "indirect_specular_func", "unit_table", "octahedral_cell_normals", "unit_row", "STOP",
           "LOBES", "LOBE_SHARPNESS",
           "UNIT_Q"]

r"""The exact diffuse irradiance of an environment map, tabulated on a cube map.

The environment's diffuse term needs the irradiance ``E(n) = ∫ L(i) max(n·i, 0) di`` (eq. 34 with
the clamped cosine) at every shading normal, and, for shadows, how much of it each part of the sky
contributes (the SG mixture of ``precompute.environment.sg_fit``, whose lobes' visible fractions the SSDF
gives, eq. 39). An 8-lobe mixture cannot hold a real sky's irradiance: measured on the Poly Haven
maps (their sun and lamps already taken out as lights, ``precompute.environment.peaks``) its irradiance is
off by up to 8–26 % of the per-normal value (1–3 % on average). The irradiance itself is cheap to
have exactly — it is a smooth function of the normal — so the renderer takes the **magnitude**
from this table and only the **visible fraction** from the mixture::

    D(n) = E(n) · (Σ_j a_j(n) V_j) / (Σ_j a_j(n)),     a_j(n) = μ_j ∫G_j e(n·p_j, λ_j)

(per colour channel; unshadowed, ``V_j = 1``, it is ``E(n)`` itself; ``warp_sg.shading.kernel``). This is a
deviation from the paper's eq. 39, which uses the mixture for both; it buys an unshadowed diffuse
term within 0.3 % of the map's own cosine-weighted integral for every normal.

:func:`irradiance_cubemap` computes the table:

1. The map is reduced to about ``rows × 2·rows`` cells (default 64 × 128, any source size): each
   cell holds its texels' power ``S = Σ L Ω`` per channel and stands at their luminance energy
   centroid ``d = normalize(Σ lum Ω d)`` (first-order exact for a bright source inside a cell).
2. Each texel of a cube map with faces of ``face`` texels plus a one-texel border (computed at its
   own direction, so bilinear fetches never leave a face) gets ``E_c(n) = Σ S_c max(n·d_c, 0)``.

Lookup (:func:`env_irradiance` in kernels, :meth:`EnvIrradiance.lookup` in numpy): bilinear on the
face of the normal's major axis, in the map's frame (``to_env = Rᵀ`` of the environment's rotation),
times the environment's scale. Cached on disk (kind ``env_irradiance``).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import numpy as np
import warp as wp

from precompute.environment.cubemap import bordered_bilinear, cube_dir_numpy, cube_face_of, cube_face_of_numpy
from warp_sg.core.cache import code_key
from warp_sg.core.image_io import LUMINANCE
from warp_sg.scene.envmap import row_solid_angles, uv_to_dir

_VERSION = code_key(__name__, cube_dir_numpy, row_solid_angles)  # the producing code


def _cells(env: np.ndarray, rows: int):
    """``(S (K, 3), d (K, 3))``: per cell of a ``rows × 2·rows`` grid of the map, the power of its
    texels per channel and their (luminance) energy centroid direction (the cell centre where the
    cell is black). Any map size; the map is read in row blocks (bounded temporaries)."""
    h, w = env.shape[:2]
    ch, cw = max(1, min(rows, h)), max(1, min(2 * rows, w))
    om = row_solid_angles(h, w)
    col_cell = (np.arange(w) * cw) // w
    S = np.zeros((ch * cw, 3))
    M = np.zeros((ch * cw, 3))  # Σ lum Ω d per cell
    u = (np.arange(w) + 0.5) / w
    step = max(1, (1 << 21) // max(w, 1))
    for r0 in range(0, h, step):
        r = np.arange(r0, min(h, r0 + step))
        d = uv_to_dir(u[None, :], ((r + 0.5) / h)[:, None]).reshape(-1, 3)
        e = (np.asarray(env[r0:r0 + len(r)], np.float64) * om[r][:, None, None]).reshape(-1, 3)
        el = e @ LUMINANCE
        cell = (((r * ch) // h)[:, None] * cw + col_cell[None, :]).reshape(-1)
        for c in range(3):
            S[:, c] += np.bincount(cell, weights=e[:, c], minlength=ch * cw)
            M[:, c] += np.bincount(cell, weights=el * d[:, c], minlength=ch * cw)
    centre = uv_to_dir(((np.arange(cw) + 0.5) / cw)[None, :], ((np.arange(ch) + 0.5) / ch)[:, None]).reshape(-1, 3)
    norm = np.linalg.norm(M, axis=1, keepdims=True)
    dirs = np.where(norm > 0, M / np.where(norm > 0, norm, 1.0), centre)
    return S, dirs


def texel_directions_with_border(face: int) -> np.ndarray:
    """(6, N+2, N+2, 3) unit directions of the cube texels, the one-texel border included
    (texel x of a face stands at ``a = (x − ½)·2/N − 1``)."""
    n = int(face)
    t = (np.arange(n + 2) - 0.5) * 2.0 / n - 1.0
    a, b = np.meshgrid(t, t)  # a along x (columns), b along y (rows)
    d = np.stack([cube_dir_numpy(np.full(a.shape, f), a, b) for f in range(6)])
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def irradiance_quadrature(S: np.ndarray, dirs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``E_c(n) = Σ_k S_kc max(n·d_k, 0)`` (float64) for normals (..., 3)."""
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    out = np.empty((len(n), 3))
    for i0 in range(0, len(n), 512):
        out[i0:i0 + 512] = np.maximum(n[i0:i0 + 512] @ dirs.T, 0.0) @ S
    return out.reshape(np.shape(normals)[:-1] + (3,))


class EnvIrradiance:
    """The tabulated irradiance of a map: ``texels (6, N+2, N+2, 3)`` float32 (map frame, unscaled)."""

    def __init__(self, texels: np.ndarray):
        self.texels = np.asarray(texels, np.float32)
        self.face = int(self.texels.shape[1]) - 2

    def lookup(self, normals, rotation=None, scale: float = 1.0) -> np.ndarray:
        """numpy twin of :func:`env_irradiance`: ``scale · E(Rᵀ n)``, bilinear (float64)."""
        d = np.asarray(normals, np.float64)
        if rotation is not None:
            d = d @ np.asarray(rotation, np.float64)  # Rᵀ n for row vectors
        face, a, b = cube_face_of_numpy(d)
        n = self.face
        x = (a + 1.0) * 0.5 * n + 0.5
        y = (b + 1.0) * 0.5 * n + 0.5
        x0 = np.clip(np.floor(x).astype(int), 0, n)
        y0 = np.clip(np.floor(y).astype(int), 0, n)
        fx = np.clip(x - x0, 0.0, 1.0)[..., None]
        fy = np.clip(y - y0, 0.0, 1.0)[..., None]
        t = self.texels.astype(np.float64)
        t0 = t[face, y0, x0] * (1 - fx) + t[face, y0, x0 + 1] * fx
        t1 = t[face, y0 + 1, x0] * (1 - fx) + t[face, y0 + 1, x0 + 1] * fx
        return scale * (t0 * (1 - fy) + t1 * fy)

    def table(self, rotation=None, scale: float = 1.0, device=None) -> "IrradianceTable":
        """The kernel-side :class:`IrradianceTable` (rotation: environment → world)."""
        tab = IrradianceTable()
        tab.texels = wp.array(self.texels.reshape(-1, 3), dtype=wp.vec3, device=device)
        tab.size = self.face
        R = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
        tab.to_env = wp.mat33(*R.T.astype(np.float32).ravel())
        tab.scale = float(scale)
        return tab


@wp.kernel(enable_backward=False)
def _quadrature_kernel(base: int, normals: wp.array(dtype=wp.vec3), power: wp.array(dtype=wp.vec3),
                       dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    """``out[t] = Σ_k power_k max(n_t·d_k, 0)`` for texel ``t = base + tid``."""
    t = base + wp.tid()
    n = normals[t]
    acc = wp.vec3(0.0, 0.0, 0.0)
    for k in range(power.shape[0]):
        c = wp.dot(n, dirs[k])
        if c > 0.0:
            acc += power[k] * c
    out[t] = acc


def irradiance_cubemap(env, *, face: int = 48, rows: int = 64, cache: bool = True, device="cpu") -> EnvIrradiance:
    """The irradiance table of ``env`` (H, W, 3), unscaled, in the map's frame (module docstring);
    the texels are summed by :func:`_quadrature_kernel` on ``device`` (CPU: a thread pool)."""
    env = np.asarray(env)
    params = dict(v=_VERSION, face=int(face), rows=int(rows))

    def build():
        from raster import parallel

        S, dirs = _cells(env, int(rows))
        normals = texel_directions_with_border(int(face)).reshape(-1, 3)
        # the cells' powers relative to the largest (float32 sums stay well inside their range)
        top = float(np.abs(S).max()) or 1.0
        nw = wp.array(normals.astype(np.float32), dtype=wp.vec3, device=device)
        pw = wp.array((S / top).astype(np.float32), dtype=wp.vec3, device=device)
        dw = wp.array(dirs.astype(np.float32), dtype=wp.vec3, device=device)
        out = wp.zeros(len(normals), dtype=wp.vec3, device=device)
        parallel.launch(_quadrature_kernel, len(normals), [nw, pw, dw, out], device, min_chunk=256)
        texels = out.numpy().astype(np.float64) * top
        return {"texels": texels.reshape(6, face + 2, face + 2, 3).astype(np.float32)}

    if cache:
        from warp_sg.core.cache import content_key, load_or_build

        data = load_or_build("env_irradiance", content_key(np.ascontiguousarray(env, np.float32), params), build)
    else:
        data = build()
    return EnvIrradiance(data["texels"])


def cell_radiance(env, rows: int = 64) -> np.ndarray:
    """(rows, 2·rows, 3) float64: the map box-filtered to that grid (each cell its texels' mean
    radiance by solid angle, ``Σ L Ω / Σ Ω``; any source size), the radiance at the scale of an SSDF
    texel that ``warp_sg.shading.vertex_visibility`` weighs visibility with."""
    env = np.asarray(env)
    h, w = env.shape[:2]
    ch, cw = max(1, min(rows, h)), max(1, min(2 * rows, w))
    S, _ = _cells(env, rows)
    om = row_solid_angles(h, w)
    cell_rows = (np.arange(h) * ch) // h
    cell_cols = (np.arange(w) * cw) // w
    om_cell = np.bincount(cell_rows, weights=om, minlength=ch)[:, None] * np.bincount(cell_cols, minlength=cw)[None, :]
    return (S.reshape(ch, cw, 3) / np.maximum(om_cell, 1e-300)[..., None])


def placeholder_table(device=None) -> "IrradianceTable":
    """A 1-texel-face table of zeros: the argument of kernel variants without an environment."""
    return EnvIrradiance(np.zeros((6, 3, 3, 3), np.float32)).table(device=device)


# --------------------------------------------------------------------------------------------
# Kernel side
# --------------------------------------------------------------------------------------------
@wp.struct
class IrradianceTable:
    """Kernel-side irradiance table: faces with a one-texel border, (6·(N+2)²) texels."""

    texels: wp.array(dtype=wp.vec3)
    size: int  # N, the face size without the border
    to_env: wp.mat33  # world → environment frame (Rᵀ)
    scale: float  # radiance scale (dynamic)


@wp.func
def env_irradiance(tab: IrradianceTable, n: wp.vec3) -> wp.vec3:
    """``scale · E(Rᵀ n)``: the environment's irradiance on a surface of world normal ``n``
    (bilinear in the table, :class:`EnvIrradiance.lookup` is the numpy twin)."""
    return irradiance_unscaled(tab, n) * tab.scale


@wp.func
def irradiance_unscaled(tab: IrradianceTable, n: wp.vec3) -> wp.vec3:
    """``E(Rᵀ n)`` of the map at unit scale (:func:`env_irradiance` without ``tab.scale``)."""
    fab = cube_face_of(tab.to_env * n)
    face = int(fab[0])
    sz = tab.size
    return bordered_bilinear(tab.texels, face * (sz + 2) * (sz + 2), sz, fab[1], fab[2])


__all__ = ["EnvIrradiance", "IrradianceTable", "cell_radiance", "env_irradiance", "irradiance_cubemap",
           "irradiance_quadrature", "irradiance_unscaled",
           "placeholder_table", "texel_directions_with_border"]

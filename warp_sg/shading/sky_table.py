r"""A cheaper quadrature of the visible sky for the vertices of moving objects.

The visible fraction of a vertex's diffuse environment irradiance
(:func:`warp_sg.shading.vertex_visibility.env_vertex_visible_kernel`) sums, over the texels ``t``
of the vertex's SSDF map inside its occluder cone, ``(n·d_t) L̄(d_t) Ω_t`` weighted by the
texel's occluded and visible shares. A static vertex computes it when the environment turns; a
vertex of a dynamic object (:mod:`warp_sg.renderer.dynamic_objects`) every time its object turns,
because the texels' world directions ``d_t = R·D_t`` turn with it — a rotation of the object is a
rotation of the sky in its frame, and nothing of the sum but the per-texel weights can be kept.
:func:`moving_visible_kernel` computes the same sum, cheaper:

* **only the texels inside the cone** (:meth:`SkyTable` ``texels``): which texels of a vertex's
  map the cone holds does not change under a rigid motion (map, cone axis and texel directions
  all turn with the object), so each moving vertex's list is found once, in the pose the
  geometry was built in (:func:`cone_texels`), instead of testing all R² texels every frame — on
  the turning blob 352 of 1024 texels on average;
* **the local directions from a table** (``dirs``) instead of the concentric map's ``sin``/``cos``;
* **the map on a cube**: ``L̄`` (the residual map box-filtered to 64 × 128,
  ``precompute.environment.irradiance.cell_radiance``) is read by longitude and latitude — an
  ``atan2`` and an ``asin`` per texel; ``radiance`` holds it resampled once per map onto a cube
  with faces of :data:`FACE` texels and a one-texel border (each cube texel ``L̄`` read
  bilinearly at its direction, as the map itself is read), read bilinearly on the face of the
  direction's major axis (a division, no trigonometry: the irradiance table's lookup,
  ``precompute.environment.irradiance.irradiance_unscaled``).

The cube's second interpolation smooths ``L̄`` by a fraction of its own cell (1.4° texels against
2.8° cells at 64 per face); the visible fraction differs from the map-read quadrature by a few
1e-5 (``tests/test_moving_caches.py``: the turning blob and a bowl that shadows itself deeply
against :func:`~warp_sg.shading.vertex_visibility.env_vertex_visible`). The moving vertices
use it at every pose, their first frame included, so a frame stays a function of the transforms.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the kernel annotations.
import numpy as np
import warp as wp

from precompute.environment.irradiance import EnvIrradiance, IrradianceTable, irradiance_unscaled, \
    texel_directions_with_border
from precompute.visibility.ssdf_wp import concentric_to_dir_wp

from warp_sg.numeric.onb import local_to_world
from warp_sg.shading.vertex_visibility import texel_ssdf, vertex_frame, visible_share
from warp_sg.shading.visibility_terms import EnvSG, Visibility

#: texels per cube face edge (without the border) of the resampled map
FACE = 64
_SQRT_2PI = wp.constant(float(np.sqrt(2.0 * np.pi)))


@wp.struct
class SkyTable:
    """What :func:`moving_visible_kernel` reads besides the visibility: the residual map on a cube
    (``radiance``, an irradiance-table layout of radiance in the map's frame, ``to_env`` the
    environment's rotation), the local directions of the R×R SSDF texels (``dirs``, row-major),
    and per listed vertex (``vertices``) its texels inside the cone, ``texels[start[k]:start[k+1]]``."""

    radiance: IrradianceTable
    dirs: wp.array(dtype=wp.vec3)
    vertices: wp.array(dtype=int)
    start: wp.array(dtype=int)
    texels: wp.array(dtype=wp.uint16)


@wp.kernel(enable_backward=False)
def _texel_dirs_kernel(R: int, out: wp.array(dtype=wp.vec3)):
    k = wp.tid()
    y = k / R
    x = k - y * R
    out[k] = concentric_to_dir_wp((float(x) + 0.5) * 2.0 / float(R) - 1.0, (float(y) + 0.5) * 2.0 / float(R) - 1.0)


@wp.kernel(enable_backward=False)
def moving_visible_kernel(base: int, sky: SkyTable, vis: Visibility, env: EnvSG, out: wp.array(dtype=wp.vec3),
                          out_irr: wp.array(dtype=wp.vec3)):
    """Listed vertex ``k = base + tid`` (``v = sky.vertices[k]``): ``out[v]`` its visible fraction
    and ``out_irr[v] = E ∘ F``, as :func:`~warp_sg.shading.vertex_visibility.env_vertex_visible_kernel`
    over its listed texels with the table's directions and cube (module docstring)."""
    k = base + wp.tid()
    v = sky.vertices[k]
    n = wp.normalize(vis.normals[v])
    cone = vis.cones[v]
    f = wp.vec3(1.0, 1.0, 1.0)
    ex = irradiance_unscaled(env.exact, n)
    if cone[3] >= 0.0:
        t, b = vertex_frame(vis, v, n)
        R = vis.mean.shape[0]
        h = _SQRT_2PI / float(R)
        om = 2.0 * wp.pi / float(R * R)
        occ_sum = wp.vec3(0.0, 0.0, 0.0)
        seen_sum = wp.vec3(0.0, 0.0, 0.0)
        for j in range(sky.start[k], sky.start[k + 1]):
            q = int(sky.texels[j])
            y = q / R
            dl = sky.dirs[q]
            s = wp.clamp(0.5 + texel_ssdf(vis, v, y, q - y * R) / h, 0.0, 1.0)
            e = irradiance_unscaled(sky.radiance, local_to_world(dl, t, b, n)) * (dl[2] * om)
            occ_sum += e * (1.0 - s)
            seen_sum += e * s
        f = visible_share(occ_sum, seen_sum, ex, cone, n, h)
    out[v] = f
    out_irr[v] = wp.cw_mul(ex, f)


def texel_dirs(resolution: int, device) -> wp.array:
    """(R²,) the local directions of an R×R equal-area concentric map's texels, row-major."""
    R = int(resolution)
    out = wp.empty(R * R, dtype=wp.vec3, device=device)
    wp.launch(_texel_dirs_kernel, dim=R * R, inputs=[R, out], device=device)
    return out


def radiance_cube(cells: np.ndarray, face: int = FACE) -> EnvIrradiance:
    """``cells`` (the (rows, 2·rows, 3) box-filtered map, ``cell_radiance``) on a bordered cube:
    each texel the map read bilinearly at its direction (``warp_sg.scene.envmap.env_lookup``)."""
    from warp_sg.scene.envmap import env_lookup_numpy

    d = texel_directions_with_border(int(face)).reshape(-1, 3)
    tex = env_lookup_numpy(np.asarray(cells, np.float64), d)
    return EnvIrradiance(tex.reshape(6, face + 2, face + 2, 3).astype(np.float32))


def cone_texels(dirs: np.ndarray, normals, tangents, bitangents, cones, resolution: int):
    """``(start (n+1,), texels (Σ,) uint16)``: per vertex the row-major indices of its SSDF map's
    texels inside its occluder cone (the test of ``env_vertex_visible_kernel``, ``d·axis ≥
    cos(min(θ + h, π))``, in float64) — none for a vertex with no cone (θ < 0). ``dirs`` the
    texels' local directions; the frames (t, b, n) and cones of one pose."""
    R = int(resolution)
    h = np.sqrt(2.0 * np.pi) / R
    dl = np.asarray(dirs, np.float64).reshape(-1, 3)
    cones = np.asarray(cones, np.float64).reshape(-1, 4)
    counts = np.zeros(len(cones), np.int64)
    parts = []
    for i0 in range(0, len(cones), 256):  # (256 vertices × R² texels at a time)
        sl = slice(i0, i0 + 256)
        frame = np.stack([np.asarray(a, np.float64)[sl] for a in (tangents, bitangents, normals)], 1)  # (m, 3, 3)
        D = np.einsum("tk,mkj->mtj", dl, frame)
        c = cones[sl]
        inside = (np.einsum("mtj,mj->mt", D, c[:, :3]) >= np.cos(np.minimum(c[:, 3] + h, np.pi))[:, None])
        inside &= (c[:, 3] >= 0.0)[:, None]
        counts[sl] = inside.sum(1)
        parts.append(np.nonzero(inside)[1].astype(np.uint16))
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    return start, (np.concatenate(parts) if parts else np.zeros(0, np.uint16))


class MovingSky:
    """The moving vertices' :class:`SkyTable` of one installed visibility: the lists (once), the
    cube (once per map) and the table (per environment rotation)."""

    def __init__(self, vertices: np.ndarray, frames: tuple, cones: np.ndarray, resolution: int, device):
        self.device, self.resolution = device, int(resolution)
        self.dirs = texel_dirs(resolution, device)
        n, t, b = frames
        ids = np.asarray(vertices, np.int64)
        start, texels = cone_texels(self.dirs.numpy(), n[ids], t[ids], b[ids], cones[ids], resolution)
        self.count = len(ids)
        self.vertices = wp.array(ids.astype(np.int32), dtype=int, device=device)
        self.start = wp.array(start, dtype=int, device=device)
        self.texels = wp.array(texels if len(texels) else np.zeros(1, np.uint16), dtype=wp.uint16, device=device)
        self._cube = (None, None)  # (the cells it was made of, EnvIrradiance)
        self._table = (None, None)  # (key, SkyTable)

    def table(self, cells: wp.array, rotation) -> SkyTable:
        """The :class:`SkyTable` of the box-filtered map ``cells`` (a device array) turned by
        ``rotation`` (environment → world)."""
        if self._cube[0] is not cells:
            self._cube, self._table = (cells, radiance_cube(cells.numpy())), (None, None)
        key = (id(cells), tuple(np.asarray(rotation, np.float64).ravel()))
        if self._table[0] != key:
            st = SkyTable()
            st.radiance = self._cube[1].table(rotation=rotation, scale=1.0, device=self.device)
            st.dirs, st.vertices, st.start, st.texels = self.dirs, self.vertices, self.start, self.texels
            self._table = (key, st)
        return self._table[1]

    def visible(self, vis: Visibility, env: EnvSG, table: SkyTable, into) -> None:
        """The listed vertices' rows of ``into = (F, E ∘ F)`` (:func:`env_vertex_visible`'s), in place."""
        from raster import parallel

        if self.count:
            parallel.launch(moving_visible_kernel, self.count, [table, vis, env, *into], self.device, min_chunk=32)


__all__ = ["FACE", "MovingSky", "SkyTable", "cone_texels", "moving_visible_kernel", "radiance_cube", "texel_dirs"]

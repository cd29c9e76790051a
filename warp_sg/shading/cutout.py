r"""Alpha cut-outs (glTF ``alphaMode = "MASK"``): rays pass through the holes (issue 27).

A point of a triangle whose material has an ``alpha_cutoff`` (:mod:`warp_sg.scene.material_layers`) is
a hole where its alpha is below the cutoff::

    alpha(x) = alpha_m · alpha_map_m(uv(x)) · a(x)  <  cutoff_m

with ``uv`` and the vertex alpha ``a`` (COLOR_0's) interpolated barycentrically, ``alpha_map``
read bilinearly (:func:`warp_sg.scene.textures.tex_sample`). Every ray query of the project that must
see through holes goes through the ``@wp.func``\ s here: the renderer's camera rays (the shading
kernel continues the ray behind a hole, :mod:`warp_sg.shading.kernel`), the SSDF precompute's visibility
rays (:mod:`precompute.visibility.rays`), the Monte-Carlo reference's camera and shadow rays
(:mod:`warp_sg.groundtruth.reference_wp`) and the region masks' shadow test (:mod:`warp_sg.groundtruth.region_error`). A query
takes the nearest hit (``wp.mesh_query_ray``) and, while that hit is a hole, starts again
``step`` past it (a small fraction of the scene's size) — at most :data:`MAX_LAYERS` times.

:func:`cutout_data` collects the host side (:class:`CutoutData`, numpy) from a scene's geometry and
materials — None when no material is cut out, so scenes without cut-outs keep the any-hit queries.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func / struct annotations.
from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_sg.scene.textures import TextureAtlas, build_atlas, tex_sample

#: most holes one ray passes through before it counts as blocked
MAX_LAYERS = 64
#: how far past a hole a query starts again, as a fraction of the scene's bounding-box diagonal
STEP_SCALE = 1.0e-5


@wp.struct
class Cutouts:
    """The device side of :class:`CutoutData` (``enabled`` 0: every hit is opaque)."""

    enabled: int
    indices: wp.array(dtype=int)  # 3T, the mesh's triangles
    tri_material: wp.array(dtype=int)
    uvs: wp.array(dtype=wp.vec2)
    vertex_alpha: wp.array(dtype=float)
    has_vertex_alpha: int
    cutoff: wp.array(dtype=float)  # per material; < 0: opaque
    alpha: wp.array(dtype=float)  # per material constant alpha
    alpha_tex: wp.array(dtype=int)  # per material texture in ``atlas`` (−1: none)
    atlas: TextureAtlas
    step: float  # world units


@wp.func
def is_hole(c: Cutouts, face: int, b0: float, b1: float, b2: float) -> bool:
    """Whether point (b0, b1, b2) (the weights of the triangle's vertices 0, 1, 2) of ``face`` is a hole."""
    if c.enabled == 0:
        return False
    m = c.tri_material[face]
    cut = c.cutoff[m]
    if cut < 0.0:
        return False
    i0 = c.indices[3 * face]
    i1 = c.indices[3 * face + 1]
    i2 = c.indices[3 * face + 2]
    a = c.alpha[m]
    t = c.alpha_tex[m]
    if t >= 0:
        uv = c.uvs[i0] * b0 + c.uvs[i1] * b1 + c.uvs[i2] * b2
        a = a * tex_sample(c.atlas, t, uv)[0]
    if c.has_vertex_alpha != 0:
        a = a * (c.vertex_alpha[i0] * b0 + c.vertex_alpha[i1] * b1 + c.vertex_alpha[i2] * b2)
    return a < cut


@wp.func
def hole_at_hit(c: Cutouts, face: int, u: float, v: float) -> bool:
    """:func:`is_hole` at a ``wp.mesh_query_ray`` hit (its barycentrics: P = u·v0 + v·v1 + (1 − u − v)·v2)."""
    return is_hole(c, face, u, v, 1.0 - u - v)


@wp.func
def first_opaque_hit(mesh: wp.uint64, c: Cutouts, o: wp.vec3, d: wp.vec3, max_t: float):
    """The nearest hit along ``o + s d``, ``0 < s < max_t``, that is not a hole:
    ``(hit, s, face, u, v, geometric normal)`` (``wp.mesh_query_ray``'s barycentrics)."""
    q = wp.mesh_query_ray(mesh, o, d, max_t)
    base = float(0.0)
    org = o
    n = int(0)
    while q.result and n < MAX_LAYERS:
        if not hole_at_hit(c, q.face, q.u, q.v):
            return True, base + q.t, q.face, q.u, q.v, q.normal
        adv = q.t + c.step
        base = base + adv
        org = org + d * adv
        if base >= max_t:
            break
        q = wp.mesh_query_ray(mesh, org, d, max_t - base)
        n += 1
    return False, max_t, int(-1), 0.0, 0.0, wp.vec3(0.0, 0.0, 1.0)


@wp.func
def see_behind(mesh: wp.uint64, c: Cutouts, positions: wp.array(dtype=wp.vec3), eye: wp.vec3, face: int,
               b0: float, b1: float, b2: float):
    """A camera ray from ``eye`` that meets point (b0, b1, b2) of ``face``: where it ends, behind the
    holes, as ``(hit, face, b0, b1, b2, unit ray direction)`` (the point itself where it is opaque)."""
    i0 = c.indices[3 * face]
    i1 = c.indices[3 * face + 1]
    i2 = c.indices[3 * face + 2]
    p = positions[i0] * b0 + positions[i1] * b1 + positions[i2] * b2
    d = wp.normalize(p - eye)
    if not is_hole(c, face, b0, b1, b2):
        return True, face, b0, b1, b2, d
    hit, s, f, u, v, n = first_opaque_hit(mesh, c, p + d * c.step, d, 1.0e30)
    return hit, f, u, v, 1.0 - u - v, d


@wp.func
def blocked(mesh: wp.uint64, c: Cutouts, o: wp.vec3, d: wp.vec3, max_t: float) -> bool:
    """Whether an opaque point lies on ``o + s d``, ``0 < s < max_t`` (any hit without cut-outs)."""
    if c.enabled == 0:
        return wp.mesh_query_ray_anyhit(mesh, o, d, max_t)
    hit, s, face, u, v, n = first_opaque_hit(mesh, c, o, d, max_t)
    return hit


@wp.kernel(enable_backward=False)
def see_through_kernel(mesh: wp.uint64, c: Cutouts, positions: wp.array(dtype=wp.vec3), eye: wp.vec3,
                       tri_id: wp.array2d(dtype=int), bary: wp.array2d(dtype=wp.vec2)):
    """A visibility buffer's samples that see a hole take the opaque surface behind it along the
    camera ray (or none: −1); ``bary`` holds the weights of vertices 1 and 2 (the raster's)."""
    y, x = wp.tid()
    t = tri_id[y, x]
    if t < 0:
        return
    b1 = bary[y, x][0]
    b2 = bary[y, x][1]
    b0 = 1.0 - b1 - b2
    if not is_hole(c, t, b0, b1, b2):
        return
    p = (positions[c.indices[3 * t]] * b0 + positions[c.indices[3 * t + 1]] * b1
         + positions[c.indices[3 * t + 2]] * b2)
    d = wp.normalize(p - eye)
    hit, s, face, u, v, n = first_opaque_hit(mesh, c, p + d * c.step, d, 1.0e30)
    if hit:
        tri_id[y, x] = face
        bary[y, x] = wp.vec2(v, 1.0 - u - v)
    else:
        tri_id[y, x] = -1
        bary[y, x] = wp.vec2(0.0, 0.0)


def see_through(vb, vertices, triangles, data, eye, device) -> None:
    """Apply :func:`see_through_kernel` to a visibility buffer ``vb`` (``raster.rasterize``) of the
    mesh ``vertices``/``triangles`` whose cut-outs are ``data`` (:class:`CutoutData`), in place."""
    c = data.device(triangles, device)
    pts = wp.array(np.ascontiguousarray(vertices, np.float32), dtype=wp.vec3, device=device)
    mesh = wp.Mesh(points=pts, indices=c.indices)
    wp.launch(see_through_kernel, dim=tuple(vb.tri_id.shape), device=device,
              inputs=[mesh.id, c, pts, wp.vec3(*np.asarray(eye, np.float32)), vb.tri_id, vb.bary])


# --------------------------------------------------------------------------------------------
# host side
# --------------------------------------------------------------------------------------------
@dataclass
class CutoutData:
    """What the cut-out test needs, as numpy arrays: per triangle its material, per vertex the
    uvs and alpha (None: 1), per material the cutoff (−1: opaque), constant alpha and alpha image
    (index into ``images``, −1: none); ``extent``: the scene's bounding-box diagonal."""

    tri_material: np.ndarray
    uvs: np.ndarray
    vertex_alpha: np.ndarray | None
    cutoff: np.ndarray
    alpha: np.ndarray
    alpha_tex: np.ndarray
    images: list
    extent: float

    def key(self) -> dict:
        """Content digests for cache keys (of what changes which points are holes)."""
        from warp_sg.core.cache import content_key

        parts = [self.tri_material.astype(np.int32), self.uvs.astype(np.float32), self.cutoff.astype(np.float32),
                 self.alpha.astype(np.float32), self.alpha_tex.astype(np.int32)]
        if self.vertex_alpha is not None:
            parts.append(self.vertex_alpha.astype(np.float32))
        parts += [np.asarray(im, np.float32) for im in self.images]
        return {"cutouts": content_key(*parts, {})}

    def device(self, triangles, device) -> Cutouts:
        """The :class:`Cutouts` struct for the mesh ``triangles`` (the same triangles, in order)."""
        c = Cutouts()
        c.enabled = 1
        c.indices = wp.array(np.ascontiguousarray(np.asarray(triangles, np.int32).reshape(-1)), dtype=int,
                             device=device)
        c.tri_material = wp.array(np.ascontiguousarray(self.tri_material, np.int32), dtype=int, device=device)
        c.uvs = wp.array(np.ascontiguousarray(self.uvs, np.float32), dtype=wp.vec2, device=device)
        c.has_vertex_alpha = int(self.vertex_alpha is not None)
        va = np.ones(1, np.float32) if self.vertex_alpha is None else self.vertex_alpha
        c.vertex_alpha = wp.array(np.ascontiguousarray(va, np.float32), dtype=float, device=device)
        c.cutoff = wp.array(self.cutoff.astype(np.float32), dtype=float, device=device)
        c.alpha = wp.array(self.alpha.astype(np.float32), dtype=float, device=device)
        c.alpha_tex = wp.array(self.alpha_tex.astype(np.int32), dtype=int, device=device)
        c.atlas = build_atlas(self.images, device)
        c.step = float(STEP_SCALE * max(self.extent, 1e-30))
        return c


def no_cutouts(device) -> Cutouts:
    """A disabled :class:`Cutouts` (placeholder arrays): every hit is opaque."""
    c = Cutouts()
    c.enabled = 0
    one_i = wp.zeros(3, dtype=int, device=device)
    c.indices = one_i
    c.tri_material = wp.zeros(1, dtype=int, device=device)
    c.uvs = wp.zeros(1, dtype=wp.vec2, device=device)
    c.vertex_alpha = wp.ones(1, dtype=float, device=device)
    c.has_vertex_alpha = 0
    c.cutoff = wp.full(1, -1.0, dtype=float, device=device)
    c.alpha = wp.ones(1, dtype=float, device=device)
    c.alpha_tex = wp.full(1, -1, dtype=int, device=device)
    c.atlas = build_atlas([], device)
    c.step = 0.0
    return c


class CutoutScene:
    """A renderer's cut-outs: ``data`` (:class:`CutoutData` or None), ``arrays`` (the device
    struct, disabled without cut-outs) and ``mesh_id`` (a ``wp.Mesh`` of the geometry's device
    ``positions`` for the shading kernel's continued camera rays; 0 without cut-outs)."""

    def __init__(self, geometry, materials: dict, positions, device):
        self.data = cutout_data(geometry, materials)
        self.mesh = None
        if self.data is None:
            self.arrays, self.mesh_id = no_cutouts(device), wp.uint64(0)
            return
        self.arrays = self.data.device(geometry.triangles, device)
        self.mesh = wp.Mesh(points=positions, indices=self.arrays.indices)
        self.mesh_id = self.mesh.id


def cutout_data(geometry, materials: dict) -> CutoutData | None:
    """The :class:`CutoutData` of a :class:`warp_sg.scene.Geometry` whose ``material_names`` index
    ``materials`` ({name: Material}); None when none of its materials is cut out."""
    names = geometry.material_names
    lays = [getattr(materials[n], "layers", None) for n in names]
    if not any(lay is not None and lay.cut_out for lay in lays):
        return None
    n = max(len(names), 1)
    cutoff = np.full(n, -1.0, np.float32)
    alpha = np.ones(n, np.float32)
    alpha_tex = np.full(n, -1, np.int32)
    images, index = [], {}
    for i, lay in enumerate(lays):
        if lay is None or not lay.cut_out:
            continue
        cutoff[i], alpha[i] = float(lay.alpha_cutoff), float(lay.alpha)
        if lay.alpha_map is not None:
            k = id(lay.alpha_map)
            if k not in index:
                index[k] = len(images)
                images.append(lay.alpha_map.rgba())
            alpha_tex[i] = index[k]
    v = np.asarray(geometry.vertices, np.float64)
    colors = getattr(geometry, "colors", None)
    va = None if colors is None or np.all(colors[:, 3] == 1.0) else np.asarray(colors[:, 3], np.float32)
    return CutoutData(tri_material=np.asarray(geometry.tri_material, np.int32), uvs=np.asarray(geometry.uvs, np.float32),
                      vertex_alpha=va, cutoff=cutoff, alpha=alpha, alpha_tex=alpha_tex, images=images,
                      extent=float(np.linalg.norm(v.max(0) - v.min(0))) if len(v) else 1.0)


__all__ = ["Cutouts", "CutoutData", "MAX_LAYERS", "STEP_SCALE", "is_hole", "hole_at_hit", "first_opaque_hit",
           "blocked", "see_behind", "cutout_data", "no_cutouts", "see_through", "see_through_kernel", "CutoutScene"]

r"""Objects that move after the precompute: ``[[objects]] dynamic = true`` and
``Renderer.set_object_transform(obj, matrix)``.

The paper's visibility is static (its §9): every SSDF holds the occluders where they stood. A
scene with dynamic objects is precomputed so that nothing in it depends on where they are:

* **Self-visibility in the object's own frame.** The SSDFs are computed per group — the static
  objects together, each dynamic object alone (:mod:`precompute.visibility.ssdf_groups`) — so a dynamic
  object's maps hold only its own occluders. Under a rigid motion ``P' = sRP + t``
  (:mod:`warp_sg.numeric.rigid_motion`) they are unchanged *in the object's frame*: each vertex keeps the
  frame its map was computed in, turned by ``R`` (``Visibility.frame_t``/``frame_b``,
  ``precompute.visibility.ssdf_wp.ssdf_point_framed``), and its occluder cone's axis turns with it. Its
  self-shadows rotate with it; no SSDF is recomputed.
* **Occlusion between groups through proxies** (:mod:`precompute.visibility.proxies`, fitted once in the
  rest pose and moved with their object): spheres for curved objects, a plane for a flat static
  one (a floor). Per pixel, every lobe's and light's visibility is capped by the proxies' — the
  minimum of SSDFs, the SSDF of the union of occluders, before the SSDF × SG product — and the
  diffuse environment term's visible fraction is multiplied by what the proxies leave
  (:mod:`warp_sg.shading.motion_wp`). A dynamic object's shadow on the floor, the floor under it, and
  two dynamic objects on each other come from there.
* **Per frame** (:meth:`DynamicObjects.apply`, when a transform changed): the moved objects'
  positions, normals, tangents, SSDF frames and cone axes are written into the renderer's device
  arrays in place, the proxies are moved, the visibility buffer is invalidated, and the per-vertex
  caches (:mod:`warp_sg.shading.vertex_visibility`) are recomputed for the moved vertices only. The
  static vertices' caches stay. The result is a pure function of the transforms: an object moved
  away and back renders bit for bit the first frame.

``Renderer.scene`` follows the motion (``SceneObject.motion``), so ``ws.reference(r.scene)`` is the
Monte-Carlo reference at the current transforms.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import warp as wp

from warp_sg.core.errors import SceneError
from warp_sg.core.suggest import did_you_mean
from warp_sg.numeric.onb import frame_from_normal
from warp_sg.numeric.rigid_motion import check_motion


def object_index(scene, obj) -> int:
    """The index of object ``obj`` (an index or a label, ``SceneObject.label``) of ``scene``."""
    n = len(scene.objects)
    if isinstance(obj, (int, np.integer)) and not isinstance(obj, bool):
        if not 0 <= int(obj) < n:
            raise SceneError(f"no object #{int(obj)} (the scene has {n})", where="set_object_transform")
        return int(obj)
    labels = [ob.label(i) for i, ob in enumerate(scene.objects)]
    if obj in labels:
        return labels.index(obj)
    raise SceneError(f"no object '{obj}'{did_you_mean(obj, labels)}", where="set_object_transform")


def scene_with_transforms(scene, transforms: dict):
    """A copy of ``scene`` with dynamic objects moved (``{object (index or label): 4×4 matrix}``,
    as :meth:`Renderer.set_object_transform`): what ``ws.reference`` renders at those transforms."""
    import copy

    out = copy.deepcopy(scene)
    for obj, matrix in transforms.items():
        k = object_index(out, obj)
        if not out.objects[k].dynamic:
            raise SceneError(f"object '{out.objects[k].label(k)}' is not dynamic (give its [[objects]] table "
                             f"dynamic = true)", where="transform")
        R, s, t = check_motion(matrix, where=f"transform of '{out.objects[k].label(k)}'")
        M = np.eye(4)
        M[:3, :3], M[:3, 3] = s * R, t
        out.objects[k].motion = M
    out.invalidate_geometry()
    return out


def parse_transform_argument(text: str) -> tuple:
    """``"OBJECT=m00,m01,...,m33"`` (16 numbers, row-major) → ``(object, (4, 4) matrix)``; an
    object that is a number is an index."""
    name, sep, nums = str(text).partition("=")
    try:
        vals = [float(x) for x in nums.split(",")]
    except ValueError:
        vals = []
    if not sep or not name or len(vals) != 16:
        raise SceneError(f"expected OBJECT=16 comma-separated numbers, got {text!r}", where="--transform")
    return (int(name) if name.isdigit() else name), np.asarray(vals).reshape(4, 4)


def _write(dst: wp.array, values: np.ndarray) -> None:
    """``dst`` ← ``values`` (its shape): on the CPU in place through the array's own memory (no
    temporary array), elsewhere a copy from the host."""
    if dst.device.is_cpu:
        view = dst.numpy()
        view[...] = np.asarray(values).reshape(view.shape)
    else:
        dst.assign(np.ascontiguousarray(values, np.float32))


@wp.kernel(enable_backward=False)
def move_vertices_kernel(base: int, ids: wp.array(dtype=int), slot: wp.array(dtype=int), rest_p: wp.array(dtype=wp.vec3),
                         rest_n: wp.array(dtype=wp.vec3), rest_t: wp.array(dtype=wp.vec3),
                         rest_ft: wp.array(dtype=wp.vec3), rest_fb: wp.array(dtype=wp.vec3),
                         rest_cone: wp.array(dtype=wp.vec4), xf: wp.array(dtype=wp.vec3), frames: int,
                         pos: wp.array(dtype=wp.vec3),
                         nor: wp.array(dtype=wp.vec3), tan: wp.array(dtype=wp.vec3), frame_t: wp.array(dtype=wp.vec3),
                         frame_b: wp.array(dtype=wp.vec3), cones: wp.array(dtype=wp.vec4)):
    """Moving vertex ``ids[i]`` (its object's motion ``slot[i] = k``: ``P' = sR P + t``, directions
    turned by ``R``; ``xf[7k:7k+7]`` the rows of sR, of R, and t): position, normal, tangent and,
    with ``frames``, its SSDF frame and cone axis (``i = base + tid``)."""
    i = base + wp.tid()
    v = ids[i]
    o = 7 * slot[i]
    A = wp.matrix_from_rows(xf[o], xf[o + 1], xf[o + 2])
    R = wp.matrix_from_rows(xf[o + 3], xf[o + 4], xf[o + 5])
    pos[v] = A * rest_p[i] + xf[o + 6]
    nor[v] = R * rest_n[i]
    tan[v] = R * rest_t[i]
    if frames != 0:
        frame_t[v] = R * rest_ft[i]
        frame_b[v] = R * rest_fb[i]
        c = rest_cone[i]
        a = R * wp.vec3(c[0], c[1], c[2])
        cones[v] = wp.vec4(a[0], a[1], a[2], c[3])


class DynamicObjects:
    """The moving objects of one renderer (module docstring): built with each geometry the renderer
    installs (the input mesh, then the refined one), it owns the rest pose, the proxies and the
    transforms. ``rest_motions``: ``{object: SceneObject.motion}`` when the renderer was built (the
    pose its geometry is in); ``previous``: the last install's, whose transforms carry over."""

    def __init__(self, r, rest_motions: dict, previous=None):
        scene, g, d = r.scene, r.geometry, r.device
        from precompute.visibility.proxies import object_proxies

        if r.cutouts is not None:  # (the groups' SSDFs and the proxies are solid: no hole would show)
            c = r.cutouts
            cut = np.asarray(c.cutoff)[np.asarray(c.tri_material, np.int64)] >= 0.0
            names = sorted({str(g.object_names[k]) for k in np.unique(np.asarray(g.tri_object)[cut])})
            raise SceneError(f"alpha cut-outs ({', '.join(names)}) are not supported in a scene with dynamic "
                             "objects", where="[[objects]] dynamic")
        self.n_objects = len(scene.objects)
        self.flags = np.array([bool(ob.dynamic) for ob in scene.objects])
        T = np.asarray(g.triangles, np.int64)
        to = np.asarray(g.tri_object, np.int64)
        vo = np.full(len(g.vertices), -1, np.int64)
        vo[T.ravel()] = np.repeat(to, 3)
        self.vertex_object = vo
        self.ids = {k: np.flatnonzero(vo == k) for k in np.flatnonzero(self.flags)}
        self.all_ids = wp.array(np.concatenate(list(self.ids.values())).astype(np.int32), dtype=int, device=d)
        #: SSDF groups: 0 the static objects, 1 + k dynamic object k
        self.tri_group = np.where(self.flags[to], 1 + to, 0)
        self.rest_v = np.asarray(g.vertices, np.float64)
        self.rest_n = np.asarray(g.normals, np.float64)
        self.rest_n /= np.maximum(np.linalg.norm(self.rest_n, axis=1, keepdims=True), 1e-30)
        self.rest_t = np.asarray(g.tangents, np.float64)
        self.rest_ft, self.rest_fb = frame_from_normal(self.rest_n)
        # the pose the geometry was built in (a scene may come with motions set)
        self.rest_motion = {k: np.eye(4) if rest_motions.get(k) is None else np.asarray(rest_motions[k], np.float64)
                            for k in self.ids}
        self.motion = {k: (previous.motion[k] if previous is not None else m).copy()
                       for k, m in self.rest_motion.items()}
        spheres, sowner, planes, disks, powner, outlines = [], [], [], [], [], []
        self.rest_blobs = np.zeros((max(self.n_objects, 1), 4))
        self.fields = {}  # object -> its occlusion field (precompute.visibility.occlusion_field)
        self.blob_owner = np.full(max(self.n_objects, 1), -1, np.int64)
        for k in range(self.n_objects):
            sel = to == k
            if not sel.any():
                continue
            ids = np.unique(T[sel])
            p = object_proxies(self.rest_v[ids], np.searchsorted(ids, T[sel]), self.rest_n[ids],
                               allow_plane=not self.flags[k])
            spheres.append(p.spheres)
            sowner += [k] * len(p.spheres)
            if p.diffuse is not None:
                self.rest_blobs[k], self.blob_owner[k] = p.diffuse, k
            if p.field is not None:
                self.fields[k] = p.field
            if p.plane is not None:
                planes.append(p.plane)
                disks.append(p.disk)
                powner.append(k)
                outlines.append(p.polygon)
        self.rest_spheres = np.concatenate(spheres).astype(np.float64) if spheres else np.zeros((0, 4))
        self.sphere_owner = np.asarray(sowner, np.int64)
        n = max(self.n_objects, 1)
        self.sphere_count = np.bincount(self.sphere_owner, minlength=n)[:n] if len(sowner) else np.zeros(n, np.int64)
        self.sphere_start = np.concatenate([[0], np.cumsum(self.sphere_count)[:-1]])
        self.rest_bounds = np.zeros((n, 4))
        self.rest_bounds[:, 3] = -1.0
        for k in np.flatnonzero(self.sphere_count):  # a sphere around the object's spheres
            S = self.rest_spheres[self.sphere_start[k]:self.sphere_start[k] + self.sphere_count[k]]
            c = S[:, :3].mean(0)
            self.rest_bounds[k] = [*c, float(np.max(np.linalg.norm(S[:, :3] - c, axis=1) + S[:, 3]))]
        self.planes = np.asarray(planes, np.float32).reshape(-1, 4)
        self.disks = np.asarray(disks, np.float32).reshape(-1, 4)
        self.plane_owner = np.asarray(powner, np.int64)
        self.outlines = outlines
        self.version = 0 if previous is None else previous.version  # bumped by set_transform
        self._applied = self.version if previous is None else -1  # the version in the device arrays
        from warp_sg.renderer.moving_rows import FrameRows

        self.rows = FrameRows(self.all_ids.numpy(), len(g.vertices), d)  # the moving rows a frame reads
        #: the moving part's buffer of this frame (its queue: the rows it reads), None: every row
        self.reads = None
        self._sky = None  # the moving vertices' sky table (_visible)
        self._rest_dev = None  # the moving vertices' rest rows on the device (_device_rest)
        self._host = None  # the host copy of the moving geometry (apply)
        self._rest_rows = None  # per moving object its vertices' rest positions, normals, tangents (a host copy)
        self._rest_box = None  # per moving object the corners of its rest-pose box (place_culling)
        self._xf = None  # the moving objects' transforms on the device (apply)
        self._decomp = {}  # (object, matrix bytes) -> check_motion (_decomposed)
        self._behind_key = None
        self.px = self._proxies_struct(r)
        self.rest_cones = None
        from warp_sg.renderer.moving_raster import MovingRaster

        self.raster = MovingRaster(g, self.flags, d)  # the static objects' buffer kept per camera

    # ------------------------------------------------------------------ precompute
    def ssdf(self, r):
        """The per-group SSDFs of the renderer's (refined) geometry (:mod:`precompute.visibility.ssdf_groups`)."""
        from precompute.visibility.ssdf_groups import ssdf_for_groups

        g, rs = r.geometry, r.scene.render
        return ssdf_for_groups(g.vertices, g.triangles, g.normals, self.tri_group, resolution=rs.ssdf_resolution,
                               pca_terms=rs.pca_terms, device=r.device, progress=r.progress,
                               compute=r._ssdf_compute)

    def attach(self, r) -> None:
        """Give the renderer's ``Visibility`` the per-vertex SSDF frames (rest pose)."""
        d = r.device
        r.vis.frame_t = wp.array(self.rest_ft.astype(np.float32), dtype=wp.vec3, device=d)
        r.vis.frame_b = wp.array(self.rest_fb.astype(np.float32), dtype=wp.vec3, device=d)
        self.rest_cones = r.vis.cones.numpy().astype(np.float64)
        self._sky = None

    def _proxies_struct(self, r):
        from precompute.environment.irradiance import placeholder_table
        from warp_sg.shading.motion_wp import Proxies

        d = r.device
        px = Proxies()
        px.active = 1
        px.tri_object = wp.array(np.asarray(r.geometry.tri_object, np.int32), dtype=int, device=d)
        px.dynamic = wp.array(self.flags.astype(np.int32), dtype=int, device=d)
        S = self.rest_spheres if len(self.rest_spheres) else np.zeros((1, 4))
        px.spheres = wp.array(S.astype(np.float32), dtype=wp.vec4, device=d)
        px.sphere_owner = wp.array(self.sphere_owner.astype(np.int32) if len(self.sphere_owner)
                                   else np.array([-1], np.int32), dtype=int, device=d)
        px.blobs = wp.array(self.rest_blobs.astype(np.float32), dtype=wp.vec4, device=d)
        px.bounds = wp.array(self.rest_bounds.astype(np.float32), dtype=wp.vec4, device=d)
        px.sphere_start = wp.array(self.sphere_start.astype(np.int32), dtype=int, device=d)
        px.sphere_count = wp.array(self.sphere_count.astype(np.int32), dtype=int, device=d)
        px.blob_owner = wp.array(self.blob_owner.astype(np.int32), dtype=int, device=d)
        # the occlusion fields, one object after the other; field_inv = (sRρ)⁻¹, the rest pose's I/ρ
        cells = [self.fields[k].table.shape[0] for k in sorted(self.fields)]
        cell0 = dict(zip(sorted(self.fields), np.concatenate([[0], np.cumsum(cells)[:-1]]).astype(int)))
        n = max(self.n_objects, 1)
        self.rest_field_inv = np.zeros((n, 3, 3))
        for k, f in self.fields.items():
            self.rest_field_inv[k] = np.eye(3) / f.radius
        tabs = [self.fields[k].table.reshape(-1, 4) for k in sorted(self.fields)] or [np.zeros((1, 4), np.float32)]
        rins = [self.fields[k].r_in for k in sorted(self.fields)] or [np.ones(1, np.float32)]
        px.field = wp.array(np.concatenate(tabs).astype(np.float32), dtype=wp.vec4, device=d)
        from precompute.visibility.occlusion_field import cell_axes

        axes, rings = cell_axes(np.concatenate(rins)) if self.fields else (np.zeros((1, 4)), np.ones((1, 2)))
        px.field_axis = wp.array(axes.astype(np.float32), dtype=wp.vec4, device=d)
        px.field_ring = wp.array(rings.astype(np.float32), dtype=wp.vec2, device=d)
        px.field_cell = wp.array(np.array([cell0.get(k, -1) for k in range(n)], np.int32), dtype=int, device=d)
        px.field_inv = wp.array(self.rest_field_inv.astype(np.float32), dtype=wp.mat33, device=d)
        n_pl = len(self.planes)
        px.planes = wp.array(self.planes if n_pl else np.zeros((1, 4), np.float32), dtype=wp.vec4, device=d)
        px.disks = wp.array(self.disks if n_pl else np.zeros((1, 4), np.float32), dtype=wp.vec4, device=d)
        px.plane_owner = wp.array(self.plane_owner.astype(np.int32) if n_pl else np.array([-1], np.int32),
                                  dtype=int, device=d)
        cnt = np.array([len(o) for o in self.outlines] or [0], np.int32)
        px.outline = wp.array(np.concatenate(self.outlines).astype(np.float32) if self.outlines
                              else np.zeros((1, 3), np.float32), dtype=wp.vec3, device=d)
        px.outline_start = wp.array(np.concatenate([[0], np.cumsum(cnt)[:-1]]).astype(np.int32), dtype=int, device=d)
        px.outline_count = wp.array(cnt, dtype=int, device=d)
        px.behind = placeholder_table(d)
        px.behind_axis = wp.vec3(0.0, 0.0, 0.0)
        return px

    def _update_behind(self, r) -> None:
        """The irradiance table of the residual map behind the first plane proxy (its far side,
        ``d·m < 0`` in world space), rebuilt when the environment turns."""
        env = getattr(r, "env_light", None)
        if not len(self.planes) or env is None or getattr(r, "env_residual", None) is None:
            return
        key = float(env.rotation)
        if key == self._behind_key:
            return
        from precompute.environment.irradiance import irradiance_cubemap
        from warp_sg.scene.envmap import texel_directions

        m = self.planes[0, :3].astype(np.float64)
        Rm = env.rotation_matrix()
        base = np.asarray(r.env_residual, np.float32)
        dirs = texel_directions(*base.shape[:2])  # environment frame
        masked = base * ((dirs @ (Rm.T @ m)) < 0.0)[..., None].astype(np.float32)
        tab = irradiance_cubemap(masked, device=r.device).table(rotation=Rm, scale=1.0, device=r.device)
        self.px.behind = tab
        self.px.behind_axis = wp.vec3(*m.astype(np.float32))
        self._behind_key = key

    # ------------------------------------------------------------------ motion
    def set_transform(self, scene, obj, matrix) -> int:
        """Record the transform of object ``obj`` (applied on the next frame); returns its index."""
        k = object_index(scene, obj)
        label = scene.objects[k].label(k)
        if not self.flags[k]:
            raise SceneError(f"object '{label}' is not dynamic (give its [[objects]] table dynamic = true)",
                             where="set_object_transform")
        R, s, t = check_motion(matrix, where=f"set_object_transform('{label}')")
        M = np.eye(4)
        M[:3, :3], M[:3, 3] = s * R, t
        self._check_extent(k, M, f"set_object_transform('{label}')")  # (before anything changes)
        if not np.array_equal(M, self.motion[k]):
            self._decomposed(k, M, (R, s, t))
            self.motion[k] = M
            self.version += 1
            scene.objects[k].motion = M
            scene.invalidate_geometry()
        return k

    def _check_extent(self, k, M, where: str) -> None:
        """Object k moved by ``M`` stays where float32 shading holds (its rest box carried by
        ``M·M0⁻¹``, :func:`warp_sg.scene.geometry.check_moved_extent`)."""
        from warp_sg.scene.geometry import check_moved_extent

        if k in self._rest_boxes():  # (an object without vertices has nothing to check)
            check_moved_extent(self._rest_boxes()[k], M @ np.linalg.inv(self.rest_motion[k]), where)

    def _rest_boxes(self) -> dict:
        """Per moving object the corners of its rest-pose box (computed once)."""
        from warp_sg.scene.culling import box_corners

        if self._rest_box is None:
            self._rest_box = {k: box_corners(self.rest_v[i].min(0), self.rest_v[i].max(0)) for k, i in self.ids.items() if len(i)}
        return self._rest_box

    def _delta(self, k) -> tuple:
        """``(R, s, t)`` of object k's motion from the pose its geometry was built in (the identity
        exactly when it is back there)."""
        if np.array_equal(self.motion[k], self.rest_motion[k]):
            return np.eye(3), 1.0, np.zeros(3)
        (R, s, t), (R0, s0, t0) = self._decomposed(k, self.motion[k]), self._decomposed(k, self.rest_motion[k])
        Rd, sd = R @ R0.T, s / s0  # M·M0⁻¹ = [sR | t]·[R0ᵀ/s0 | −R0ᵀt0/s0]
        return Rd, sd, t - sd * (Rd @ t0)

    def _decomposed(self, k, M, known=None) -> tuple:
        """``check_motion(M)`` of a validated motion of object k (``known``: it, computed already),
        kept for the last few matrices."""
        key = (k, M.tobytes())
        if key not in self._decomp:
            if len(self._decomp) > 8:
                self._decomp.clear()
            self._decomp[key] = check_motion(M) if known is None else known
        return self._decomp[key]

    def _device_rest(self, r):
        """The moving vertices' rest rows on the device (:func:`move_vertices_kernel`'s inputs)."""
        if self._rest_dev is None or self._rest_dev[0] != (self.rest_cones is not None):
            ids = self.all_ids.numpy()
            f32 = lambda a, t=wp.vec3: wp.array(np.ascontiguousarray(a[ids], np.float32), dtype=t, device=r.device)  # noqa: E731
            cones = self.rest_cones if self.rest_cones is not None else np.zeros((len(self.rest_v), 4))
            slot = np.concatenate([np.full(len(v), j, np.int32) for j, v in enumerate(self.ids.values())])
            self._rest_dev = (self.rest_cones is not None, [wp.array(slot, dtype=int, device=r.device),
                              f32(self.rest_v), f32(self.rest_n), f32(self.rest_t), f32(self.rest_ft), f32(self.rest_fb),
                              f32(cones, wp.vec4)])
        return self._rest_dev[1]

    def apply(self, r) -> bool:
        """Write the current transforms into the renderer's arrays (module docstring): the moving
        vertices' rows on the device (one :func:`move_vertices_kernel` launch), the proxies, and the
        host copy of the geometry; False when nothing changed since the last call."""
        self._update_behind(r)
        if self._applied == self.version:
            return False
        S, B, Bd = self.rest_spheres.copy(), self.rest_blobs.copy(), self.rest_bounds.copy()
        host = self._host_geometry(r)
        Fi = self.rest_field_inv.copy()
        xf = np.zeros((len(self.ids), 7, 3), np.float32)  # per object: the rows of sR, of R, and t
        for j, (k, ids) in enumerate(self.ids.items()):
            R, s, t = self._delta(k)
            xf[j] = np.vstack([s * R, R, t])
            if host is not None:
                rv, rn, rt = self._rest_rows[k]
                host[0][ids] = rv @ (s * R).T + t
                host[1][ids] = rn @ R.T
                host[2][ids] = rt @ R.T
            own = self.sphere_owner == k
            S[own, :3] = self.rest_spheres[own, :3] @ (s * R).T + t
            S[own, 3] = self.rest_spheres[own, 3] * s
            B[k, :3] = self.rest_blobs[k, :3] @ (s * R).T + t
            B[k, 3] = self.rest_blobs[k, 3] * s
            Fi[k] = R.T @ self.rest_field_inv[k] / s
            Bd[k, :3] = self.rest_bounds[k, :3] @ (s * R).T + t
            Bd[k, 3] = self.rest_bounds[k, 3] * s if self.rest_bounds[k, 3] > 0 else -1.0
        d = r.device
        ga, frames = r.geo_arrays, self.rest_cones is not None  # (the SSDF frames and cones: with shadows)
        out = [ga.positions, ga.normals, ga.tangents] + ([r.vis.frame_t, r.vis.frame_b, r.vis.cones] if frames else
                                                          [ga.normals, ga.normals, wp.zeros(1, dtype=wp.vec4, device=d)])
        if self._xf is None or self._xf.shape[0] != xf.shape[0] * 7:
            self._xf = wp.empty(xf.shape[0] * 7, dtype=wp.vec3, device=d)
        _write(self._xf, xf.reshape(-1, 3))
        from raster import parallel

        parallel.launch(move_vertices_kernel, int(self.all_ids.shape[0]),
                        [self.all_ids, *self._device_rest(r), self._xf, int(frames), *out], d,
                        chunks=parallel.cpu_workers())  # (uniform work: a range per thread)
        if len(S):
            _write(self.px.spheres, S)
        _write(self.px.blobs, B)
        _write(self.px.field_inv, Fi)
        _write(self.px.bounds, Bd)
        r._vb_key = None  # the visibility buffer
        if r._culling is not None:
            self.place_culling(r._culling)
        if r._aa is not None:
            r._aa.forget_frame()
        self._applied = self.version
        return True

    def _host_geometry(self, r):
        """The host copy of the geometry (``r.geometry``'s vertices, normals and tangents), from
        the first move on. On the CPU it is the device arrays' own memory (numpy views, written by
        :func:`move_vertices_kernel`: nothing to do, returns None); elsewhere float32 copies, which
        :meth:`apply` updates in place (returned)."""
        if self._host is None:
            ga = r.geo_arrays
            if str(r.device).startswith("cpu"):
                self._host = (ga.positions.numpy(), ga.normals.numpy(), ga.tangents.numpy())
            else:
                self._host = tuple(np.array(a, np.float32) for a in (r.geometry.vertices, r.geometry.normals,
                                                                     r.geometry.tangents))
                self._rest_rows = {k: (self.rest_v[ids], self.rest_n[ids], self.rest_t[ids])
                                   for k, ids in self.ids.items()}
            r.geometry = replace(r.geometry, vertices=self._host[0], normals=self._host[1], tangents=self._host[2])
        return self._host if self._rest_rows is not None else None

    def place_culling(self, culling) -> None:
        """The moving objects' boxes for back-face culling (``warp_sg.scene.culling``): each one's
        rest-pose box carried by its motion — a function of the transform, not of the moved
        vertices (no pass over them)."""
        for k, corners in self._rest_boxes().items():
            R, s, t = self._delta(k)
            culling.place(k, corners @ (s * R).T + t)

    def _visible(self, r, es, into, rows=None) -> None:
        """The moving vertices' rows of the environment's visible fraction (``rows``: those of these
        slots, default all), from their transfer vectors (or texel lists) kept since the rest pose
        and the sky turned into each object's frame (:mod:`warp_sg.shading.sky_table`)."""
        from warp_sg.shading.sky_table import MovingSky

        env, cells = getattr(r, "env_light", None), getattr(r, "env_texel_radiance", None)
        if env is None or cells is None or self.rest_cones is None:
            return
        if self._sky is None:
            slot, _, rest_n, _, rest_ft, rest_fb, rest_cone = self._device_rest(r)
            self._sky = MovingSky(r.vis, self.all_ids, slot.numpy(), (rest_n, rest_ft, rest_fb, rest_cone),
                                  len(self.ids), r.device)
        self._sky.visible(r.vis, es, cells, env.rotation_matrix(), [self._delta(k)[0] for k in self.ids], into,
                          rows=rows)

    def patch_caches(self, r, es) -> None:
        """Recompute the per-vertex caches' rows of the moved vertices that this frame reads
        (:mod:`warp_sg.renderer.moving_rows`: those of the moving triangles the raster queued,
        :attr:`reads`; all without a kept queue) and that do not hold the current transforms: the
        lights' deficits and the environment lobes' visible fractions (a cache rebuilt this frame
        already holds them), and the visible fraction of the environment's irradiance, which the
        moving vertices always take from the sky table (:meth:`_visible`; after a rebuild too, so
        that a frame is a function of the transforms)."""
        from warp_sg.scene.render_settings import uses_sigmoid
        from warp_sg.shading.vertex_visibility import env_vertex_visibility, light_vertex_deficit

        d, nv, rows = r.device, len(r.geometry.vertices), self.rows
        needed = rows.needed(self.reads, r.geo_arrays.tris)
        jobs = (("light", r.light_vis_cache, True,
                 lambda v, s, ids: light_vertex_deficit(r.vis, r.geo_arrays.positions, r.light_arrays, nv,
                                                        uses_sigmoid(r.scene.render.fh), d, ids=ids, into=v)),
                ("visible", r.env_visible_cache, False, lambda v, s, ids: self._visible(r, es, v, s)),
                ("lobes", r.env_vis_cache, True,
                 lambda v, s, ids: env_vertex_visibility(r.irr_table, r.vis, es, nv, d, ids=ids, into=v)))
        for name, cache, fresh, run in jobs:
            if cache.key is None:
                continue
            ident = (id(cache.value[0] if isinstance(cache.value, tuple) else cache.value), cache.builds)
            slots = rows.stale(name, ident, fresh, self.version, needed)
            if len(slots):
                every = len(slots) == len(rows.ids)
                run(cache.value, None if every else slots, self.all_ids if every else rows.mesh_ids(slots))
                rows.done(name, slots, self.version, needed)


__all__ = ["DynamicObjects", "object_index", "scene_with_transforms", "parse_transform_argument"]

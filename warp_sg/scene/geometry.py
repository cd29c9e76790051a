"""Scene geometry: every object of a scene flattened into one world-space triangle mesh
(:class:`Geometry`) — mesh files (trimesh, with a minimal OBJ reader to name bad elements),
validation, area-weighted vertex normals and UV tangent generation. ``warp_sg.scene`` re-exports
these names; :meth:`warp_sg.scene.Scene.geometry` calls :func:`build_geometry`.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError, InputWarning, MeshError, SceneError, reason
from warp_sg.core.meshcheck import check_mesh, closed_and_oriented, signed_volume, weld_ids, winding_number
from warp_sg.core.watchdog import MAX_TRIANGLES, check_size
from warp_sg.scene.primitives import MeshData, make_primitive

#: mesh files an object's ``mesh`` may name (read by trimesh; ``.glb``/``.gltf`` by :mod:`warp_sg.scene.importers.gltf`,
#: USD by :mod:`warp_sg.scene.importers.usd`)
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf", ".usd", ".usda", ".usdc", ".usdz")
#: largest world-space coordinate magnitude: beyond it float32 shading and trimesh's vertex welding
#: (positions × 1e8 as int64) lose the mesh (a unit sphere scaled by 1e14 renders wrong)
MAX_COORDINATE = 1e12
#: smallest extent (bounding-box diagonal) of an object: below it trimesh's 1e-8 welding tolerance
#: merges its vertices (a unit sphere scaled by 1e-8 renders wrong)
MIN_EXTENT = 1e-5


@dataclass
class Geometry:
    """All objects of a scene flattened into one world-space triangle mesh (float32 / int32).

    ``vertices`` (N, 3), ``normals`` (N, 3) unit shading normals, ``uvs`` (N, 2), ``tangents``
    (N, 3) unit and orthogonal to the normals (∂P/∂u, or the Duff frame tangent where there are no
    UVs), ``triangles`` (M, 3), ``tri_material`` (M,) index into ``material_names``,
    ``tri_object`` (M,) and ``vertex_object`` (N,) index into ``object_names``;
    ``dropped_triangles``: zero-area triangles removed while flattening.
    """

    vertices: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    tangents: np.ndarray
    triangles: np.ndarray
    tri_material: np.ndarray
    tri_object: np.ndarray
    vertex_object: np.ndarray
    material_names: list
    object_names: list
    dropped_triangles: int = 0
    #: (N, 4) linear RGBA vertex colours (kd and cut-out alpha factors) and (N, 3) their ks factor;
    #: None when no object has vertex colours (``SceneObject.colors``)
    colors: np.ndarray | None = None
    specular_colors: np.ndarray | None = None
    #: (objects,) bool: the objects whose back faces camera rays never see (``SceneObject.double_sided``
    #: False: glTF single-sided materials); None when every object is double-sided
    one_sided: np.ndarray | None = None


def vertex_samples(triangles: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """For every vertex a triangle that contains it and the barycentrics (b1, b2) that select it
    there: ``(tri_id (V,) int32, bary (V, 2) float32)``, -1 and (0, 0) for unreferenced vertices
    (a "visibility buffer" of the vertices: ``Renderer.shade_vertices``)."""
    T = np.asarray(triangles)
    owner = np.full(n_vertices, -1, np.int32)
    corner = np.zeros(n_vertices, np.int32)
    for k in range(3):
        owner[T[:, k]] = np.arange(len(T), dtype=np.int32)
        corner[T[:, k]] = k
    bary = np.zeros((n_vertices, 2), np.float32)
    bary[corner == 1, 0] = 1.0
    bary[corner == 2, 1] = 1.0
    return owner, bary


# --------------------------------------------------------------------------------------------
# meshes
# --------------------------------------------------------------------------------------------
def refined_geometry(g: Geometry, ref) -> Geometry:
    """``g`` carried onto a :class:`precompute.visibility.refine.Refinement` of its mesh: positions and
    normals from the refinement, uvs and tangents interpolated (tangents renormalised), triangle
    attributes from the parent triangle, vertex objects from the nearest input vertex."""
    tang = ref.interpolate(np.asarray(g.tangents, np.float64))
    tang /= np.maximum(np.linalg.norm(tang, axis=1, keepdims=True), 1e-30)
    cols = {} if g.colors is None else {
        "colors": ref.interpolate(np.asarray(g.colors, np.float64)).astype(np.float32),
        "specular_colors": ref.interpolate(np.asarray(g.specular_colors, np.float64)).astype(np.float32)}
    return replace(g, **cols, vertices=np.asarray(ref.vertices, np.float32), normals=np.asarray(ref.normals, np.float32),
                   uvs=ref.interpolate(np.asarray(g.uvs, np.float64)).astype(np.float32),
                   tangents=tang.astype(np.float32), triangles=np.asarray(ref.triangles, np.int32),
                   tri_material=g.tri_material[ref.parent_tri], tri_object=g.tri_object[ref.parent_tri],
                   vertex_object=ref.interpolate(g.vertex_object))


def validate_mesh(vertices, triangles, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check a mesh; returns (vertices f32, triangles i32, keep mask of non-degenerate triangles).

    Non-finite vertices and out-of-range / non-integer indices raise :class:`MeshError` naming
    the first bad element (:func:`warp_sg.core.meshcheck.check_mesh`)."""
    v, t, _ = check_mesh(vertices, triangles, where=where, require_triangles=True)
    e = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    area2 = np.linalg.norm(e, axis=1)
    scale = max(float(np.max(np.ptp(v, axis=0))), 1e-30)
    keep = area2 > 1e-12 * scale * scale
    if not keep.any():
        raise MeshError("every triangle has zero area", where=where)
    return v.astype(np.float32), t.astype(np.int32), keep


def vertex_normals(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (numpy, float64)."""
    e = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]).astype(np.float64)
    n = np.zeros((len(v), 3))
    for k in range(3):
        np.add.at(n, t[:, k], e)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    fallback = np.tile([0.0, 1.0, 0.0], (len(v), 1))
    return np.where(ln > 0, n / np.where(ln > 0, ln, 1), fallback)


def uv_tangents(v, t, uv, n) -> np.ndarray:
    """Per-vertex tangents ∂P/∂u from UVs (accumulated per triangle, Gram–Schmidt against ``n``);
    the Duff frame tangent of ``n`` where the UVs are degenerate or absent."""
    from warp_sg.numeric.onb import frame_from_normal

    v = v.astype(np.float64)
    n = n.astype(np.float64)
    acc = np.zeros((len(v), 3))
    if uv is not None:
        uv = uv.astype(np.float64)
        d1 = v[t[:, 1]] - v[t[:, 0]]
        d2 = v[t[:, 2]] - v[t[:, 0]]
        w1 = uv[t[:, 1]] - uv[t[:, 0]]
        w2 = uv[t[:, 2]] - uv[t[:, 0]]
        det = w1[:, 0] * w2[:, 1] - w2[:, 0] * w1[:, 1]
        ok = np.abs(det) > 1e-20
        r = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        T = (d1 * w2[:, 1:2] - d2 * w1[:, 1:2]) * r[:, None]
        for k in range(3):
            np.add.at(acc, t[:, k], T)
    acc -= n * np.sum(acc * n, axis=1, keepdims=True)
    ln = np.linalg.norm(acc, axis=1, keepdims=True)
    duff, _ = frame_from_normal(n)
    return np.where(ln > 1e-12, acc / np.where(ln > 1e-12, ln, 1), duff)


def _read_simple_obj(path: Path) -> MeshData | None:
    """Minimal OBJ reader ('v' and 'f' lines, fans triangulated) used only to diagnose files that
    trimesh cannot load (e.g. out-of-range indices); None when it cannot parse the file either."""
    try:
        verts, faces = [], []
        for line in path.read_text(errors="replace").splitlines():
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
        return MeshData(np.asarray(verts, np.float64).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3))
    except (ValueError, IndexError, OSError):
        return None


#: an OBJ face corner whose vertex index is 0 (OBJ indices start at 1; negative ones count back)
_OBJ_ZERO_INDEX = re.compile(rb"^[ \t]*f[ \t][^\n]*?(?<=[ \t])0(?=[/ \t\r\n]|$)", re.MULTILINE)


def _load_mesh_file(path: Path, where: str) -> MeshData:
    import trimesh

    if path.is_dir():
        raise SceneError(f"mesh '{path}' is a folder, not a mesh file", where=where)
    if not path.is_file():
        raise SceneError(f"mesh file not found: {path}", where=where)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshError(f"mesh format '{path.suffix or path.name}' is not supported (use {', '.join(MESH_SUFFIXES)})",
                        where=str(path))
    if path.suffix.lower() == ".obj":
        try:
            zero = _OBJ_ZERO_INDEX.search(path.read_bytes())
        except OSError as e:
            raise MeshError(f"cannot read mesh ({e.strerror or e})", where=str(path)) from None
        if zero is not None:
            line = zero.string.count(b"\n", 0, zero.start()) + 1
            raise MeshError(f"line {line}: face vertex index 0 (OBJ indices start at 1)", where=str(path))
    try:
        m = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:  # noqa: BLE001 - trimesh raises many types
        if path.suffix.lower() == ".obj":  # name the bad element when we can (trimesh crashes on bad indices)
            simple = _read_simple_obj(path)
            if simple is not None:
                validate_mesh(simple.vertices, simple.triangles, where=str(path))
        raise MeshError(f"cannot read mesh ({reason(e)})", where=str(path)) from None
    if not hasattr(m, "faces") or len(getattr(m, "faces", [])) == 0:
        raise MeshError("file contains no triangles", where=str(path))
    v = np.asarray(m.vertices)
    f = np.asarray(m.faces)
    uv = None
    vis = getattr(m, "visual", None)
    if vis is not None and getattr(vis, "uv", None) is not None and len(vis.uv) == len(v):
        uv = np.asarray(vis.uv, np.float32)
    normals = None
    if "vertex_normals" in getattr(m, "_cache", {}) or getattr(m, "_vertex_normals", None) is not None:
        normals = None  # trimesh keeps file normals in its cache; read them below when sane
    try:
        if np.all(np.isfinite(v)) and len(v):
            vn = np.asarray(m.vertex_normals, np.float64)
            if vn.shape == v.shape and np.all(np.isfinite(vn)):
                normals = vn.astype(np.float32)
    except Exception:  # noqa: BLE001 - normals are recomputed by us anyway
        normals = None
    return MeshData(v, f, normals, uv, None)


def object_mesh(ob, index: int, base: Path | None, eye=None) -> MeshData:
    """The mesh of ``ob`` (a :class:`~warp_sg.scene.SceneObject`) in world space (transform applied),
    attributes filled in; inside-out closed meshes are turned outwards unless they enclose the world
    point ``eye`` (the camera: :func:`orient_outward`)."""
    where = f"{'scene' if base is None else base}: [[objects]] #{index + 1}"
    if ob.primitive is not None:
        try:
            mesh = make_primitive(ob.primitive, dict(ob.params), where=f"{ob.primitive}")
        except InputError as e:
            raise SceneError(str(e), where=where) from None
    elif ob.mesh is not None:
        p = Path(ob.mesh)
        mesh = _load_mesh_file(p, where)
    elif ob.vertices is not None and ob.triangles is not None:
        mesh = MeshData(np.asarray(ob.vertices), np.asarray(ob.triangles),
                        None if ob.normals is None else np.asarray(ob.normals, np.float32),
                        None if ob.uvs is None else np.asarray(ob.uvs, np.float32),
                        None if ob.tangents is None else np.asarray(ob.tangents, np.float32))
    else:
        raise SceneError("needs 'mesh', 'primitive' or vertices + triangles", where=where)
    label = ob.label(index)
    file = Path(ob.mesh).name if ob.mesh is not None else None
    at = f"{where} ({label}{f', {file}' if file and file != label else ''})"
    n_tri = np.size(mesh.triangles) // 3
    check_size("the mesh", n_tri, MAX_TRIANGLES, "too large", "triangles", where=at, error=MeshError)
    raw = np.asarray(mesh.vertices, np.float64)
    far = np.isfinite(raw).all(axis=1) & (np.abs(raw) > MAX_COORDINATE).any(axis=1) if raw.ndim == 2 else None
    if far is not None and far.any():  # (before the zero-area test, whose tolerance the far vertex sets)
        check_extent(raw[far], at)
    v, t, keep = validate_mesh(mesh.vertices, mesh.triangles, where=at)
    n = mesh.normals
    if n is None or n.shape != v.shape or not np.all(np.isfinite(n)) or np.any(np.linalg.norm(n, axis=1) < 1e-12):
        n = None
    else:
        n = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    if ob.primitive is None:  # primitives are built outward
        t, n = orient_outward(v, t, keep, n, at, eye=_object_point(ob.transform, eye))
    if n is None:
        n = vertex_normals(v, t[keep]).astype(np.float32)
    uv = mesh.uvs
    if uv is not None and (uv.shape != (len(v), 2) or not np.all(np.isfinite(uv))):
        raise MeshError(f"uvs must have shape ({len(v)}, 2) and be finite, got {uv.shape}", where=f"{where} ({label})")
    tan = mesh.tangents
    if tan is None or tan.shape != v.shape or not np.all(np.isfinite(tan)):
        tan = uv_tangents(v, t[keep], uv, n).astype(np.float32)
    mesh = MeshData(v, t[keep], n, np.zeros((len(v), 2), np.float32) if uv is None else uv.astype(np.float32), tan)
    try:
        mesh = ob.transform.apply(mesh)
    except SceneError as e:
        raise SceneError(f"{e.args[0].split(': ', 1)[-1]} (scale {ob.transform.scale})", where=at) from None
    check_extent(mesh.vertices, at)
    # re-orthogonalise the tangents against the (transformed) normals
    tn = mesh.tangents.astype(np.float64)
    nn = mesh.normals.astype(np.float64)
    tn -= nn * np.sum(tn * nn, 1, keepdims=True)
    ln = np.linalg.norm(tn, axis=1, keepdims=True)
    from warp_sg.numeric.onb import frame_from_normal

    duff, _ = frame_from_normal(nn)
    mesh.tangents = np.where(ln > 1e-12, tn / np.where(ln > 1e-12, ln, 1), duff).astype(np.float32)
    mesh.dropped = int((~keep).sum())  # type: ignore[attr-defined]
    return mesh


def _vertex_colours(ob, n: int, where: str):
    """(colors (n, 4), specular_colors (n, 3)) of an object, ones where it has none."""
    c = np.ones((n, 4), np.float32) if ob.colors is None else np.asarray(ob.colors, np.float32)
    ks = np.ones((n, 3), np.float32) if ob.specular_colors is None else np.asarray(ob.specular_colors, np.float32)
    for a, k, name in ((c, 4, "colors"), (ks, 3, "specular_colors")):
        if a.shape != (n, k) or not np.all(np.isfinite(a)):
            raise MeshError(f"vertex {name} must have shape ({n}, {k}) and be finite, got {a.shape}", where=where)
    return c, ks


def _object_point(transform, p):
    """World point ``p`` in the object's frame (``A⁻¹ (p − translate)``), None if there is none or
    the transform is singular (refused later)."""
    if p is None:
        return None
    A = transform.linear()
    if abs(np.linalg.det(A)) < 1e-30:
        return None
    return np.linalg.solve(A, np.asarray(p, np.float64) - np.asarray(transform.translate, np.float64))


def check_extent(vertices, where: str) -> None:
    """World-space coordinates within ±:data:`MAX_COORDINATE` and an extent of at least
    :data:`MIN_EXTENT`; else :class:`MeshError` naming ``where`` (and the first far vertex)."""
    v = np.asarray(vertices)
    far = ~(np.abs(v) <= MAX_COORDINATE).all(axis=1)
    if far.any():
        i = int(np.argmax(far))
        raise MeshError(f"vertex {i} is at {v[i].tolist()}: coordinates beyond ±{MAX_COORDINATE:g} are refused "
                        f"(float32 shading and vertex welding lose the mesh there); scale the object down", where=where)
    size = float(np.linalg.norm(v.max(axis=0).astype(np.float64) - v.min(axis=0)))
    if size < MIN_EXTENT:
        raise MeshError(f"the object is {size:.3g} across: at least {MIN_EXTENT:g} is needed (below it the "
                        f"renderer's welding tolerance merges its vertices); scale it up", where=where)


def check_moved_extent(corners, matrix, where: str) -> None:
    """An object whose box has ``corners`` (8, 3), moved by the 4×4 rigid ``matrix``, must stay
    within ±:data:`MAX_COORDINATE` and at least :data:`MIN_EXTENT` across (the rules of
    :func:`check_extent` for a loaded mesh); else one :class:`MeshError` line naming the scale."""
    M = np.asarray(matrix, np.float64)
    c = np.asarray(corners, np.float64) @ M[:3, :3].T + M[:3, 3]
    s = float(np.cbrt(abs(np.linalg.det(M[:3, :3]))))
    far = float(np.abs(c).max()) if np.isfinite(c).all() else float("inf")
    if far > MAX_COORDINATE:
        raise MeshError(f"the motion (uniform scale {s:.3g}) puts the object at coordinates up to {far:.3g}, beyond "
                        f"±{MAX_COORDINATE:g} (float32 shading loses it there)", where=where)
    size = float(np.linalg.norm(c.max(0) - c.min(0)))
    if size < MIN_EXTENT:
        raise MeshError(f"the motion (uniform scale {s:.3g}) makes the object {size:.3g} across: at least "
                        f"{MIN_EXTENT:g} is needed", where=where)


def orient_outward(v, t, keep, normals, where: str, eye=None):
    """``(triangles, normals)`` of a closed, consistently oriented mesh made to face outwards: a
    negative :func:`~warp_sg.core.meshcheck.signed_volume` (inside out) flips every triangle's winding,
    and normals that point inwards overall (``Σ n · N_geo < 0``, ``N_geo`` the area-weighted
    triangle normals at the vertices) are negated, with one :class:`~warp_sg.core.errors.InputWarning`
    naming ``where``. Open meshes (a floor) have no inside and are returned as they are; so is a
    closed mesh around the ``eye`` (in the mesh's frame; a room seen from inside faces inwards by
    design: :func:`~warp_sg.core.meshcheck.winding_number` ±1)."""
    tk = t[keep]
    if not closed_and_oriented(tk, weld_ids(v)):
        return t, normals
    if eye is not None and abs(winding_number(v, tk, eye)) > 0.5:
        return t, normals
    vol = signed_volume(v, tk)
    flipped = vol < 0
    if flipped:
        t, tk = t[:, [0, 2, 1]], tk[:, [0, 2, 1]]
    inward = False
    if normals is not None:
        e = np.cross(v[tk[:, 1]] - v[tk[:, 0]], v[tk[:, 2]] - v[tk[:, 0]]).astype(np.float64)
        inward = float(sum(np.einsum("ij,ij->", normals[tk[:, k]].astype(np.float64), e) for k in range(3))) < 0
        if inward:
            normals = -normals
    if flipped and (inward or normals is None):
        what = f"the closed mesh is inside out (signed volume {vol:.3g} < 0): its triangles and normals are flipped"
    elif flipped:
        what = (f"the closed mesh's triangles wind inwards (signed volume {vol:.3g} < 0): they are flipped "
                f"(its normals point outwards already)")
    elif inward:
        what = "the closed mesh's normals point inwards: they are flipped"
    else:
        return t, normals
    warnings.warn(f"{where}: {what}", InputWarning, stacklevel=2)
    return t, normals


def build_geometry(scene) -> Geometry:
    """Every object of ``scene`` (a :class:`~warp_sg.scene.Scene`) flattened into one :class:`Geometry`."""
    names = scene.material_names
    vs, ns, uvs, ts, tris, tm, to, vo, labels = [], [], [], [], [], [], [], [], []
    coloured = any(getattr(ob, "colors", None) is not None for ob in scene.objects)
    cs, kss = [], []
    base = 0
    dropped = 0
    for i, ob in enumerate(scene.objects):
        m = object_mesh(ob, i, scene.path, eye=scene.camera.origin)
        if getattr(ob, "motion", None) is not None:  # a dynamic object's rigid motion (warp_sg.numeric.rigid_motion)
            from warp_sg.numeric.rigid_motion import apply_motion

            mv, mn, mt = apply_motion(ob.motion, m.vertices, m.normals, m.tangents)
            m, dropped_here = replace(m, vertices=mv, normals=mn, tangents=mt), getattr(m, "dropped", 0)
            m.dropped = dropped_here
        check_size("the scene", sum(len(x) for x in tris) + len(m.triangles), MAX_TRIANGLES,
                   f"too large at object #{i + 1}", "triangles", where=str(scene.path or "scene"), error=MeshError)
        vs.append(m.vertices)
        ns.append(m.normals)
        uvs.append(m.uvs)
        ts.append(m.tangents)
        tris.append(m.triangles + base)
        tm.append(np.full(len(m.triangles), names.index(ob.material), np.int32))
        to.append(np.full(len(m.triangles), i, np.int32))
        vo.append(np.full(len(m.vertices), i, np.int32))
        labels.append(ob.label(i))
        if coloured:
            c, ks = _vertex_colours(ob, len(m.vertices), f"{scene.path or 'scene'}: [[objects]] #{i + 1} ({ob.label(i)})")
            cs.append(c)
            kss.append(ks)
        dropped += getattr(m, "dropped", 0)
        base += len(m.vertices)
    one_sided = np.array([not getattr(ob, "double_sided", True) for ob in scene.objects], bool)
    return Geometry(
        vertices=np.ascontiguousarray(np.concatenate(vs), np.float32),
        normals=np.ascontiguousarray(np.concatenate(ns), np.float32),
        uvs=np.ascontiguousarray(np.concatenate(uvs), np.float32),
        tangents=np.ascontiguousarray(np.concatenate(ts), np.float32),
        triangles=np.ascontiguousarray(np.concatenate(tris), np.int32),
        tri_material=np.concatenate(tm).astype(np.int32),
        tri_object=np.concatenate(to).astype(np.int32),
        vertex_object=np.concatenate(vo).astype(np.int32),
        material_names=names,
        object_names=labels,
        dropped_triangles=dropped,
        colors=np.ascontiguousarray(np.concatenate(cs), np.float32) if coloured else None,
        specular_colors=np.ascontiguousarray(np.concatenate(kss), np.float32) if coloured else None,
        one_sided=one_sided if one_sided.any() else None,
    )


__all__ = ["Geometry", "validate_mesh", "check_moved_extent", "vertex_normals", "uv_tangents", "object_mesh",
           "build_geometry", "vertex_samples",
           "orient_outward", "check_extent", "MESH_SUFFIXES", "MAX_COORDINATE", "MIN_EXTENT"]

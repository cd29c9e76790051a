r"""USD stages (``.usd`` / ``.usda`` / ``.usdc`` / ``.usdz``) as scene objects, read with Pixar's
``usd-core`` (module ``pxr``; ``pip install warp-sg[usd]``, imported only when a USD file is read).

A scene object ``[[objects]] mesh = "model.usd"`` stands for every ``UsdGeom.Mesh`` prim of the
stage (instance proxies included; invisible prims and ``guide`` purpose skipped), like a glTF
(:mod:`warp_sg.scene.importers.gltf`): :class:`warp_sg.scene.Scene` replaces it by one object per mesh
(and per material subset) with inline arrays (:func:`usd_object_parts`), placed by

    ``P_scene = C · s · M_world · P``

with ``M_world`` the prim's local-to-world matrix (``UsdGeom.XformCache``; USD's row-vector
matrices transposed), ``s`` the stage's ``metersPerUnit`` (USD's fallback when unauthored: 0.01,
centimetres) and ``C`` the turn from the stage's ``upAxis`` to the scene's +Y up (``Z``: the
rotation by −90° about X, ``(x, y, z) → (x, z, −y)``), then by the object's own
``translate``/``scale``/``rotate``. Values are read at the earliest time sample
(``Usd.TimeCode.EarliestTime``: the default value when nothing is animated).

Geometry: ``points``, ``faceVertexCounts`` / ``faceVertexIndices`` triangulated as fans
``(c₀, cₖ, cₖ₊₁)`` (exact for convex faces), ``holeIndices`` dropped, ``orientation =
leftHanded`` (and a mirroring matrix) flips the winding. ``normals`` (``primvars:normals`` first)
and ``primvars:st`` (UV origin bottom-left, as OBJ) of any interpolation (constant, uniform,
vertex/varying, faceVarying; indexed primvars flattened) become per-vertex attributes: a point is
split into as many vertices as it has distinct corner values. Without authored normals the
normals are the area-weighted ones of the points (smooth across UV seams). Materials
(:mod:`warp_sg.scene.importers.usd_material`): a bound UsdPreviewSurface, else the specification's
default surface with ``primvars:displayColor`` as its diffuse colour (constant: the material's;
varying: per-vertex colours, as :attr:`SceneObject.colors`); without a ``material`` key of the
object they join the scene as ``"<label>/<material name>"``.

Anything else the stage holds (other gprims, point instancers, curves, animation beyond the first
sample) is reported once per kind as one :class:`~warp_sg.scene.importers.gltf.AssetWarning` line.
Bad input is a :class:`~warp_sg.core.errors.MeshError` naming the file: a file USD cannot open, a
stage without a mesh with faces, a face with fewer than 3 vertices, indices past the points, a
primvar whose length does not fit its interpolation, non-finite points.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from warp_sg.core.errors import MeshError
from warp_sg.scene.importers.gltf import AssetWarning, GltfPart
from warp_sg.scene.importers.gltf_material import gltf_material, vertex_colour_factors
from warp_sg.scene.importers.usd_material import bound_surface_entry, preview_entry

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
#: the turn from a stage's up axis to the scene's +Y up
UP_AXIS = {"Y": np.eye(3), "Z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])}


@dataclass
class UsdAsset:
    """The meshes of a stage in scene units and axes: :class:`GltfPart` records (``material``: a
    key of ``entries``), the glTF material entries of their materials, and the notes."""

    path: Path
    parts: list
    entries: dict = field(default_factory=dict)  # material key -> glTF material entry
    notes: list = field(default_factory=list)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        v = np.concatenate([p.vertices for p in self.parts])
        return v.min(0), v.max(0)


def is_usd(path) -> bool:
    return Path(str(path)).suffix.lower() in USD_SUFFIXES


def _pxr(path: Path):
    try:
        from pxr import Usd, UsdGeom, UsdShade
    except ImportError:
        raise MeshError("reading USD needs the usd-core package: pip install warp-sg[usd]", where=str(path)) from None
    return Usd, UsdGeom, UsdShade


def tf_message(e: BaseException) -> str:
    """The message of a ``pxr.Tf`` error without its C++ location (``Error in 'f' at line n in
    file x : 'message'``), first line only."""
    first = next((ln.strip() for ln in str(e).splitlines() if ln.strip()), type(e).__name__)
    m = re.search(r" in file \S+ : '(.*)$", first)
    msg = re.sub(r"pxrInternal_\w+?__pxrReserved__::", "", (m.group(1).rstrip("'") if m else first))
    return msg.strip() or type(e).__name__


def open_stage(path):
    """``(stage, Usd, UsdGeom, UsdShade)`` of a USD file; a file USD cannot open is one line."""
    path = Path(path)
    if path.is_dir():
        raise MeshError("is a folder, not a USD file", where=str(path))
    if not path.is_file():
        raise MeshError("USD file not found", where=str(path))
    Usd, UsdGeom, UsdShade = _pxr(path)
    try:
        stage = Usd.Stage.Open(str(path), Usd.Stage.LoadAll)
    except Exception as e:  # noqa: BLE001 - pxr.Tf.ErrorException and friends
        raise MeshError(f"cannot read USD file ({tf_message(e)})", where=str(path)) from None
    if stage is None:
        raise MeshError("cannot read USD file", where=str(path))
    return stage, Usd, UsdGeom, UsdShade


def stage_matrix(stage, UsdGeom, path) -> np.ndarray:
    """``C · s`` (3×3): metres and +Y up from the stage's ``metersPerUnit`` and ``upAxis``."""
    up = str(UsdGeom.GetStageUpAxis(stage))
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    if up not in UP_AXIS:
        raise MeshError(f"upAxis '{up}' (USD allows Y or Z)", where=str(path))
    if not (np.isfinite(mpu) and mpu > 0):
        raise MeshError(f"metersPerUnit {mpu} (must be a positive number)", where=str(path))
    return UP_AXIS[up] * mpu


# --------------------------------------------------------------------------------------------
# one mesh
# --------------------------------------------------------------------------------------------
def _array(value, dtype, width=None) -> np.ndarray:
    a = np.asarray([] if value is None else value, dtype)
    return a.reshape(-1, width) if width else a.reshape(-1)


def fan_triangles(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fans of faces with ``counts`` corners: ``(corner triples (T, 3), face of each (T,))``, the
    corners numbered as in ``faceVertexIndices`` (face f's start ``o_f``: ``(o_f, o_f + k, o_f + k + 1)``,
    k = 1 … c − 2)."""
    counts = np.asarray(counts, np.int64)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    per = counts - 2
    face = np.repeat(np.arange(len(counts)), per)
    first = np.concatenate([[0], np.cumsum(per)[:-1]])
    k = np.arange(len(face)) - first[face] + 1
    o = start[face]
    return np.stack([o, o + k, o + k + 1], 1), face


def corner_values(values, interpolation: str, counts, indices, n_points: int, what: str) -> np.ndarray:
    """A primvar's values, one row per face corner (``faceVertexIndices`` order)."""
    v = np.asarray(values, np.float64)
    v = v.reshape(len(v), -1)
    need = {"constant": 1, "uniform": len(counts), "vertex": n_points, "varying": n_points,
            "faceVarying": len(indices)}.get(str(interpolation))
    if need is None:
        raise ValueError(f"{what} has interpolation '{interpolation}'")
    if len(v) != need:
        raise ValueError(f"{what} has {len(v)} values; '{interpolation}' interpolation needs {need}")
    if interpolation == "constant":
        return np.broadcast_to(v, (len(indices), v.shape[1]))
    if interpolation == "uniform":
        return np.repeat(v, counts, axis=0)
    if interpolation in ("vertex", "varying"):
        return v[indices]
    return v


def _primvar(api, name, time):
    """(flattened values, interpolation) of an authored primvar, else None."""
    pv = api.GetPrimvar(name)
    if not pv or not pv.HasAuthoredValue():
        return None
    vals = pv.ComputeFlattened(time)
    return (None if vals is None else np.asarray(vals)), str(pv.GetInterpolation())


def mesh_arrays(prim, time, UsdGeom) -> dict:
    """The mesh prim's triangles and per-vertex attributes in its own frame (module docstring):
    ``vertices``, ``triangles``, ``normals``, ``uvs`` (or None), ``display`` (a constant colour
    (3,) or None), ``display_vertex`` (per-vertex colours, when they vary), ``tri_face`` (the face
    of each triangle). Raises ValueError with the problem."""
    mesh = UsdGeom.Mesh(prim)
    pts = _array(mesh.GetPointsAttr().Get(time), np.float64, 3)
    counts = _array(mesh.GetFaceVertexCountsAttr().Get(time), np.int64)
    idx = _array(mesh.GetFaceVertexIndicesAttr().Get(time), np.int64)
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"point #{int(np.argwhere(~np.isfinite(pts))[0, 0])} is not finite")
    bad = np.flatnonzero(counts < 3)
    if len(bad):
        raise ValueError(f"face #{int(bad[0])} has {int(counts[bad[0]])} vertices (a face needs at least 3)")
    if int(counts.sum()) != len(idx):
        raise ValueError(f"faceVertexCounts add up to {int(counts.sum())} corners but faceVertexIndices has "
                         f"{len(idx)}")
    out = np.flatnonzero((idx < 0) | (idx >= len(pts)))
    if len(out):
        raise ValueError(f"faceVertexIndices[{int(out[0])}] = {int(idx[out[0]])} is out of range (the mesh has "
                         f"{len(pts)} points)")
    tri, face = fan_triangles(counts)
    holes = _array(mesh.GetHoleIndicesAttr().Get(time), np.int64)
    if len(holes):
        keep = ~np.isin(face, holes)
        tri, face = tri[keep], face[keep]
    if str(mesh.GetOrientationAttr().Get(time)) == "leftHanded":
        tri = tri[:, [0, 2, 1]]
    api = UsdGeom.PrimvarsAPI(prim)
    columns = {}  # per-corner attributes
    nrm = _primvar(api, "normals", time)
    if nrm is None and mesh.GetNormalsAttr().HasAuthoredValue():
        nrm = np.asarray(mesh.GetNormalsAttr().Get(time)), str(mesh.GetNormalsInterpolation())
    if nrm is not None and nrm[0] is not None and len(nrm[0]):
        columns["normals"] = corner_values(nrm[0], nrm[1], counts, idx, len(pts), "normals")
    st = _primvar(api, "st", time)
    if st is not None and st[0] is not None and len(st[0]):
        columns["uvs"] = corner_values(st[0], st[1], counts, idx, len(pts), "primvars:st")[:, :2]
    display = None
    col = _primvar(api, "displayColor", time)
    if col is not None and col[0] is not None and len(col[0]):
        if col[1] == "constant":
            display = np.asarray(col[0], np.float64).reshape(-1)[:3]
        else:
            columns["display_vertex"] = corner_values(col[0], col[1], counts, idx, len(pts),
                                                      "primvars:displayColor")[:, :3]
    # a vertex per distinct (point, corner values): split only where the corners disagree
    key = np.column_stack([idx.astype(np.float64)] + [np.round(c, 6) for c in columns.values()])
    _, first, vert = np.unique(key, axis=0, return_index=True, return_inverse=True)
    vert = vert.reshape(-1)
    point = idx[first]
    res = {"vertices": pts[point], "triangles": vert[tri], "tri_face": face, "uvs": None, "display": display}
    for name, c in columns.items():
        res[name] = c[first]
    if "normals" not in columns:  # smooth over the points (a UV seam does not split the shading)
        from warp_sg.scene.geometry import vertex_normals

        res["normals"] = vertex_normals(pts, idx[tri])[point] if len(tri) else np.zeros((len(point), 3))
    return res


def _placed(a: dict, M: np.ndarray) -> dict:
    """``a`` with the 4×4 matrix ``M`` applied: P' = A P + t, n' ∝ A⁻ᵀ n (winding flipped when det A < 0)."""
    A, t = M[:3, :3], M[:3, 3]
    det = np.linalg.det(A)
    if not np.isfinite(M).all() or abs(det) < 1e-30:
        raise ValueError("the prim's transform is singular or not finite")
    n = np.asarray(a["normals"], np.float64) @ np.linalg.inv(A)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    tri = a["triangles"][:, [0, 2, 1]] if det < 0 else a["triangles"]
    return {**a, "vertices": a["vertices"] @ A.T + t, "normals": n.astype(np.float32), "triangles": tri}


# --------------------------------------------------------------------------------------------
# the stage
# --------------------------------------------------------------------------------------------
def _material_keys(prim, tri_face, UsdGeom, UsdShade) -> list[tuple[object, np.ndarray]]:
    """``[(bound UsdShade.Material or None, triangle mask)]``: per material-bind subset, and the rest."""
    api = UsdShade.MaterialBindingAPI(prim)
    rest = np.ones(len(tri_face), bool)
    out = []
    for sub in api.GetMaterialBindSubsets():
        faces = _array(sub.GetIndicesAttr().Get(), np.int64)
        m = np.isin(tri_face, faces) & rest
        mat = UsdShade.MaterialBindingAPI(sub.GetPrim()).ComputeBoundMaterial()[0]
        if m.any():
            out.append((mat if mat else None, m))
            rest &= ~m
    if rest.any():
        mat = api.ComputeBoundMaterial()[0]
        out.append((mat if mat else None, rest))
    return out


#: a USD diagnostic as the library prints it: ``Warning: in F at line N of FILE -- message``
_DIAGNOSTIC = re.compile(r"^(?:[A-Za-z ]+: )?in \S+ at line \d+ of \S+ -- (.*?)(?: \(instantiating stage on .*\))?$")


def load_usd(path) -> UsdAsset:
    """Every mesh of a USD stage in scene units and axes (module docstring). What USD prints on
    stderr meanwhile (a sublayer it cannot load, a binding it ignores) becomes one note line."""
    from warp_sg.core.native_stderr import native_stderr

    path = Path(path)
    lines: list = []
    with native_stderr(lines):
        asset = _load_usd(path)
    said = list(dict.fromkeys(m.group(1).strip() if (m := _DIAGNOSTIC.match(ln.strip())) else ln.strip()
                              for ln in lines if ln.strip()))
    if said:
        more = f" (and {len(said) - 1} more)" if len(said) > 1 else ""
        asset.notes.append(f"{path.name}: USD reports: {said[0][:300]}{more}")
    return asset


def _load_usd(path: Path) -> UsdAsset:
    stage, Usd, UsdGeom, UsdShade = open_stage(path)
    time = Usd.TimeCode.EarliestTime()
    S = stage_matrix(stage, UsdGeom, path)
    xforms = UsdGeom.XformCache(time)
    parts, entries, notes, skipped = [], {}, [], {}
    mat_keys: dict = {}
    animated = False
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if prim.IsA(UsdGeom.Imageable):
            img = UsdGeom.Imageable(prim)
            if img.ComputeVisibility(time) == UsdGeom.Tokens.invisible or img.ComputePurpose() == UsdGeom.Tokens.guide:
                continue
        if prim.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(prim).TransformMightBeTimeVarying():
            animated = True
        if not prim.IsA(UsdGeom.Mesh):
            if prim.IsA(UsdGeom.Gprim) or prim.IsA(UsdGeom.PointInstancer):
                skipped.setdefault(str(prim.GetTypeName()), str(prim.GetPath()))
            continue
        where = f"mesh '{prim.GetPath()}'"
        animated |= UsdGeom.Mesh(prim).GetPointsAttr().ValueMightBeTimeVarying()
        try:
            a = mesh_arrays(prim, time, UsdGeom)
            if len(a["triangles"]) == 0:
                continue
            M = np.eye(4)
            M[:3, :] = S @ np.asarray(xforms.GetLocalToWorldTransform(prim), np.float64).T[:3, :]
            a = _placed(a, M)
        except ValueError as e:
            raise MeshError(f"{where}: {e}", where=str(path)) from None
        for mat, mask in _material_keys(prim, a["tri_face"], UsdGeom, UsdShade):
            colours = None
            if mat is not None:
                mkey = str(mat.GetPath())
                if mkey not in mat_keys:
                    entry, more = bound_surface_entry(mat, time, UsdShade)
                    mat_keys[mkey] = _unique(mat.GetPrim().GetName(), entries)
                    entries[mat_keys[mkey]] = entry
                    notes += more
                key = mat_keys[mkey]
            else:  # the default surface, displayColor its diffuse colour
                d, colours = a["display"], a.get("display_vertex")
                colour = (0.18, 0.18, 0.18) if d is None else tuple(round(float(x), 6) for x in d)
                if colours is not None:  # per-vertex colours multiply a white diffuse colour
                    colour = (1.0, 1.0, 1.0)
                mkey = ("displayColor", colour)
                if mkey not in mat_keys:
                    mat_keys[mkey] = _unique("default" if d is None and colours is None else "displayColor", entries)
                    entries[mat_keys[mkey]] = preview_entry({"diffuseColor": colour}, mat_keys[mkey])[0]
                key = mat_keys[mkey]
            parts.append(_part(prim, a, mask, key, colours, len(parts)))
    if skipped:
        kinds = ", ".join(f"{k} ('{p}')" for k, p in sorted(skipped.items()))
        notes.append(f"{path.name}: prims of kind {kinds} are not rendered (only UsdGeom.Mesh is read)")
    if animated:
        notes.append(f"{path.name}: the stage is animated; its earliest time sample is rendered")
    if not parts:
        raise MeshError("the USD stage has no UsdGeom.Mesh with faces" + (f" (it has {', '.join(sorted(skipped))})"
                                                                        if skipped else ""), where=str(path))
    return UsdAsset(path=path, parts=parts, entries=entries, notes=notes)


def _unique(name: str, taken: dict) -> str:
    key, k = name, 1
    while key in taken:
        k += 1
        key = f"{name}#{k}"
    return key


def _part(prim, a: dict, mask: np.ndarray, material: str, colours, n: int) -> GltfPart:
    """The triangles of ``mask`` with the vertices they use."""
    tri = a["triangles"][mask]
    used = np.unique(tri)
    remap = np.full(len(a["vertices"]), -1, np.int64)
    remap[used] = np.arange(len(used))
    name = str(prim.GetPath()).lstrip("/") + ("" if mask.all() else f"#{n}")
    col = None if colours is None else np.c_[colours[used], np.ones(len(used))].astype(np.float32)
    return GltfPart(name=name, vertices=a["vertices"][used], triangles=remap[tri], normals=a["normals"][used],
                    uvs=None if a["uvs"] is None else a["uvs"][used].astype(np.float32), tangents=None,
                    material=material, colors=col)


# --------------------------------------------------------------------------------------------
# scene objects
# --------------------------------------------------------------------------------------------
def usd_object_parts(path, label: str, *, materials: bool = True) -> tuple[list, dict]:
    """A USD scene object's pieces, as :func:`warp_sg.scene.importers.gltf.gltf_object_parts`: its
    parts (``name`` = ``label/prim path``, ``material`` = ``label/material``) and ``{key: Material
    kwargs}`` (empty with ``materials=False``). Issues one :class:`AssetWarning` per note."""
    asset = load_usd(path)
    for msg in asset.notes:
        warnings.warn(msg, AssetWarning, stacklevel=3)
    specs = {f"{label}/{k}": gltf_material(e, None, where=str(asset.path)) for k, e in asset.entries.items()} \
        if materials else {}
    parts = []
    for p in asset.parts:
        colors = spec = None
        if materials and p.colors is not None:
            colors, spec = vertex_colour_factors(asset.entries[p.material], p.colors)
        parts.append(GltfPart(name=f"{label}/{p.name}", vertices=p.vertices, triangles=p.triangles, normals=p.normals,
                              uvs=p.uvs, tangents=None, material=f"{label}/{p.material}", colors=colors,
                              specular_colors=spec))
    return parts, specs


__all__ = ["USD_SUFFIXES", "UP_AXIS", "UsdAsset", "is_usd", "open_stage", "stage_matrix", "fan_triangles",
           "corner_values", "mesh_arrays", "load_usd", "usd_object_parts"]

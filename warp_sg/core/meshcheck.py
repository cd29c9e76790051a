"""Mesh validation shared by the scene, the rasterizer and the precompute (base layer).

:func:`check_mesh` is the one check of a triangle mesh's arrays; every problem raises
:class:`~warp_sg.core.errors.MeshError` whose message names the first bad element, prefixed with
``where`` (the object or file) when given:

* ``vertices are not numbers`` / ``vertices must have shape (N, 3), got (...)``;
* ``vertex 3 has a non-finite coordinate [nan, 0.0, 0.0]`` (with the count when several are bad);
* ``triangles must have shape (M, 3), got (...)``;
* ``triangle 4 has a non-integer vertex index [0.0, 1.5, 2.0]``;
* ``triangle 1 references vertex [0, 1, 7] out of range (the mesh has 3 vertices)``;
* ``normals must have shape (N, 3) (one per vertex), got (...)``, ``vertex 3 has a non-finite
  normal [...]``, ``vertex 3 has a zero-length normal``;
* optionally ``mesh has no vertices`` / ``mesh has no triangles``.

:func:`closed_and_oriented` and :func:`signed_volume` tell an inside-out closed mesh (negative
volume) from a good one; :func:`winding_number` whether a point (the eye) is inside one. Like
:mod:`warp_sg.core.errors` it imports nothing else from the project, so
``raster`` and ``precompute`` can use it.
"""
from __future__ import annotations

import numpy as np

from warp_sg.core.errors import MeshError


def _first(bad: np.ndarray) -> int:
    return int(np.argmax(bad))


def check_mesh(vertices, triangles, normals=None, *, where: str | None = None, dtype=np.float64,
               index_dtype=np.int64, require_vertices: bool = False, require_triangles: bool = False):
    """Validate a triangle mesh; returns ``(vertices (N, 3) dtype, triangles (M, 3) index_dtype,
    unit normals (N, 3) float64 or None)``.

    Vertices are checked after conversion to ``dtype`` (a coordinate that overflows float32 is
    non-finite for a float32 consumer); indices are range-checked before the conversion to
    ``index_dtype``. An empty array of any shape is an empty vertex / triangle list. No copy is made
    of arrays that already have the requested dtype.
    """
    try:
        v = np.asarray(vertices, dtype=dtype)
    except (TypeError, ValueError):
        raise MeshError("vertices are not numbers", where=where) from None
    if v.size == 0:
        v = v.reshape(0, 3)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (N, 3), got {v.shape}", where=where)
    n = len(v)
    if require_vertices and n == 0:
        raise MeshError("mesh has no vertices", where=where)
    if v.size and not np.isfinite(v).all():
        bad = ~np.isfinite(v).all(axis=1)
        i = _first(bad)
        count = int(bad.sum())
        more = f" ({count} bad vertices)" if count > 1 else ""
        raise MeshError(f"vertex {i} has a non-finite coordinate {v[i].tolist()}{more}", where=where)

    t = np.asarray(triangles)
    if t.size == 0:
        t = np.zeros((0, 3), index_dtype)
    if t.ndim != 2 or t.shape[1] != 3:
        raise MeshError(f"triangles must have shape (M, 3), got {t.shape}", where=where)
    if t.size and not np.issubdtype(t.dtype, np.integer):
        try:
            tf = t.astype(np.float64)
        except (TypeError, ValueError):
            raise MeshError("triangle indices are not numbers", where=where) from None
        bad = ~(np.isfinite(tf) & (tf == np.round(tf))).all(axis=1)
        if bad.any():
            j = _first(bad)
            raise MeshError(f"triangle {j} has a non-integer vertex index {t[j].tolist()}", where=where)
        t = tf.astype(np.int64)
    if t.size and (t.min() < 0 or t.max() >= n):
        bad = ((t < 0) | (t >= n)).any(axis=1)
        j = _first(bad)
        raise MeshError(f"triangle {j} references vertex {t[j].tolist()} out of range (the mesh has {n} vertices)",
                        where=where)
    if require_triangles and len(t) == 0:
        raise MeshError("mesh has no triangles", where=where)
    t = t.astype(index_dtype, copy=False)

    nn = None
    if normals is not None:
        try:
            nn = np.asarray(normals, dtype=np.float64)
        except (TypeError, ValueError):
            raise MeshError("normals are not numbers", where=where) from None
        if nn.shape != v.shape:
            raise MeshError(f"normals must have shape {v.shape} (one per vertex), got {nn.shape}", where=where)
        bad = ~np.isfinite(nn).all(axis=1)
        if bad.any():
            k = _first(bad)
            raise MeshError(f"vertex {k} has a non-finite normal {nn[k].tolist()}", where=where)
        ln = np.linalg.norm(nn, axis=1)
        if (ln < 1e-12).any():
            raise MeshError(f"vertex {_first(ln < 1e-12)} has a zero-length normal", where=where)
        nn = nn / ln[:, None]
    return v, t, nn


def weld_ids(vertices) -> np.ndarray:
    """(N,) int64: the same id for vertices at exactly the same position (−0.0 counts as 0.0), so
    that edges split by an exporter for normals or UVs are found as one geometric edge."""
    v = np.asarray(vertices) + 0.0
    if v.ndim != 2 or len(v) == 0:
        return np.unique(v, axis=0, return_inverse=True)[1].reshape(-1).astype(np.int64)
    # np.unique(v, axis=0, return_inverse=True)[1], from a lexicographic sort of the columns (the
    # same order of the same rows, ids the ranks of the distinct rows) at a fraction of its cost
    order = np.lexsort(v.T[::-1])
    s = v[order]
    new_row = np.empty(len(v), bool)
    new_row[0] = True
    np.any(s[1:] != s[:-1], axis=1, out=new_row[1:])
    ids = np.empty(len(v), np.int64)
    ids[order] = np.cumsum(new_row) - 1
    return ids


def closed_and_oriented(triangles, ids) -> bool:
    """Whether the mesh is closed and consistently oriented: every directed edge ``a→b`` of the
    triangles (vertices identified by ``ids``, :func:`weld_ids`) occurs exactly once and so does
    its reverse ``b→a`` (each edge is shared by two triangles that traverse it in opposite
    directions; no boundary, no non-manifold or flipped neighbour)."""
    t = np.asarray(ids, np.int64)[np.asarray(triangles, np.int64)]
    a = t.reshape(-1)
    b = t[:, [1, 2, 0]].reshape(-1)
    keep = a != b  # an edge collapsed by welding belongs to a degenerate triangle
    a, b = a[keep], b[keep]
    if len(a) == 0:
        return False
    n = int(t.max()) + 1
    fwd = np.sort(a * n + b)
    if np.any(fwd[1:] == fwd[:-1]):
        return False
    return bool(np.array_equal(fwd, np.sort(b * n + a)))


def closed_parts(triangles, ids, part, n_parts: int) -> np.ndarray:
    """(n_parts,) bool: :func:`closed_and_oriented` of each part's triangles (``part``: the part of
    each triangle, ``0 ≤ part < n_parts``), all parts in one pass: a directed edge of part k is the
    key ``(k·n + a)·n + b`` (n the number of welded ids; per part when that would overflow)."""
    t = np.asarray(ids, np.int64)[np.asarray(triangles, np.int64).reshape(-1, 3)]
    part = np.asarray(part, np.int64)
    ok = np.zeros(int(n_parts), bool)
    if len(t) == 0:
        return ok
    n = int(t.max()) + 1
    if float(n_parts) * n * n >= 2.0 ** 62:  # keys would overflow int64: one part at a time
        for k in np.unique(part):
            ok[k] = closed_and_oriented(t[part == k], np.arange(n))
        return ok
    a = t.reshape(-1)
    b = t[:, [1, 2, 0]].reshape(-1)
    o = np.repeat(part, 3)
    keep = a != b  # an edge collapsed by welding belongs to a degenerate triangle
    a, b, o = a[keep], b[keep], o[keep]
    ok[np.unique(o)] = True  # parts with an edge; those that fail a test below are cleared
    fwd = np.sort((o * n + a) * n + b)
    ok[fwd[1:][fwd[1:] == fwd[:-1]] // (n * n)] = False  # a directed edge twice
    rev = (o * n + b) * n + a
    at = np.minimum(np.searchsorted(fwd, rev), len(fwd) - 1)
    ok[o[fwd[at] != rev]] = False  # a directed edge without its reverse
    return ok


def signed_volume(vertices, triangles) -> float:
    """``V = Σ v0 · (v1 × v2) / 6`` over the triangles (divergence theorem; about the vertices'
    centroid for precision): positive for a closed mesh whose triangles wind counter-clockwise seen
    from outside (outward normals), negative for one that is inside out."""
    v = np.asarray(vertices, np.float64)
    v = v - v.mean(axis=0)
    t = np.asarray(triangles, np.int64)
    return float(np.einsum("ij,ij->", v[t[:, 0]], np.cross(v[t[:, 1]], v[t[:, 2]])) / 6.0)


def part_volumes(vertices, triangles, part, n_parts: int, origin) -> np.ndarray:
    """(n_parts,) float64: :func:`signed_volume` of each part's triangles (``part``: the part of
    each triangle) about its own ``origin`` (n_parts, 3) — e.g. the centre of its box, for
    precision — all parts in one pass."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    part = np.asarray(part, np.int64)
    c = np.asarray(origin, np.float64)[part]
    a, b, d = v[t[:, 0]] - c, v[t[:, 1]] - c, v[t[:, 2]] - c
    return np.bincount(part, weights=np.einsum("ij,ij->i", a, np.cross(b, d)), minlength=n_parts)[:n_parts] / 6.0


def winding_number(vertices, triangles, point) -> float:
    """Generalised winding number of ``point``: ``Σ Ω_t / 4π`` over the triangles' signed solid
    angles seen from it (van Oosterom & Strackee 1983, ``tan(Ω/2) = a·(b × c) / (|a||b||c| +
    (a·b)|c| + (a·c)|b| + (b·c)|a|)`` with ``a, b, c`` the corners relative to the point). For a
    closed mesh: ±1 inside (the sign of its orientation), 0 outside."""
    v = np.asarray(vertices, np.float64) - np.asarray(point, np.float64)
    t = np.asarray(triangles, np.int64)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb
           + np.einsum("ij,ij->i", b, c) * la)
    return float(2.0 * np.arctan2(num, den).sum() / (4.0 * np.pi))


__all__ = ["check_mesh", "weld_ids", "closed_and_oriented", "closed_parts", "part_volumes", "signed_volume", "winding_number"]


r"""Conforming newest-vertex bisection of a triangle mesh: the split machinery of
:mod:`precompute.visibility.refine` (its module docstring says why this scheme).

Each triangle keeps a refinement edge (``T[:, 0]``, ``T[:, 1]``; initially its longest); a triangle
bisects across it and its children's refinement edges are the parent's other two edges. The
closure "a triangle with any marked edge has its refinement edge marked" is iterated to a fixed
point, so every marked edge is split on both sides in the same step (no T-junctions). Edges are
identified by position (``weld_ids``), so a UV seam's two copies of an edge split together.
"""
from __future__ import annotations

import numpy as np

from warp_sg.core.meshcheck import weld_ids

#: index-edge key stride: edge (lo, hi) -> lo * EDGE_KEY_STRIDE + hi
EDGE_KEY_STRIDE = np.int64(1) << np.int64(31)
_S = EDGE_KEY_STRIDE


class BisectionMesh:
    """Refined mesh under construction: triangles store their refinement edge as (T[:,0], T[:,1])."""

    def __init__(self, v, f, n):
        self.V = v
        self.N = n
        self.vparent = np.full(len(v), -1, np.int64)
        self.vbary = np.zeros((len(v), 3))
        self.vbary[:, 0] = 1.0
        # initial refinement edge: the longest edge (edge k = (f[k], f[k+1]))
        d = v[np.roll(f, -1, axis=1)] - v[f]
        k = np.argmax(np.einsum("mkj,mkj->mk", d, d), axis=1) if len(f) else np.zeros(0, np.int64)
        perm = (k[:, None] + np.arange(3)[None, :]) % 3
        self.T = np.take_along_axis(f, perm, axis=1)
        self.tparent = np.arange(len(f), dtype=np.int64)
        eye = np.eye(3)
        self.tbary = eye[perm]  # (M, 3 corners, 3 weights over the parent's corners)

    @property
    def nv(self):
        return len(self.V)

    # -- edges -----------------------------------------------------------------------------
    def edges(self):
        """Per triangle edge k = (T[k], T[k+1]) (k = 0: refinement edge): index keys (M, 3),
        geometric edge ids (M, 3) into the unique geometric edges, and their lengths."""
        a = self.T
        b = np.roll(self.T, -1, axis=1)
        ikey = np.minimum(a, b) * _S + np.maximum(a, b)
        gid = weld_ids(self.V)  # by exact position, for the geometric edge ids
        ga, gb = gid[a], gid[b]
        gkey = np.minimum(ga, gb) * _S + np.maximum(ga, gb)
        _, first, geid = np.unique(gkey.ravel(), return_index=True, return_inverse=True)
        geid = geid.reshape(-1, 3)
        fa, fb = a.ravel()[first], b.ravel()[first]
        glen = np.linalg.norm(self.V[fa] - self.V[fb], axis=1)
        return ikey, geid, glen

    @staticmethod
    def closure(geid, marked):
        """Fixed point of: a triangle with any marked edge has its refinement edge marked."""
        marked = marked.copy()
        if not len(geid):
            return marked
        while True:
            ref = geid[marked[geid].any(axis=1), 0]
            new = ref[~marked[ref]]
            if not new.size:
                return marked
            marked[new] = True

    @staticmethod
    def split_keys(ikey, geid, marked):
        """Sorted unique index keys of the edges that the (closed) geometric marks split."""
        return np.unique(ikey[marked[geid]])

    def bisect(self, split):
        """Split every index edge in ``split`` (sorted keys, closed under the refinement-edge rule):
        at most two bisection rounds; a midpoint is created once per index edge."""
        mid_keys = np.zeros(0, np.int64)
        mid_vals = np.zeros(0, np.int64)
        for _ in range(3):
            a, b, c = self.T[:, 0], self.T[:, 1], self.T[:, 2]
            rk = np.minimum(a, b) * _S + np.maximum(a, b)
            sel = isin_sorted(rk, split)
            if not sel.any():
                return
            idx = np.flatnonzero(sel)
            keys = rk[idx]
            m = np.empty(len(idx), np.int64)
            known = isin_sorted(keys, mid_keys)
            if known.any():
                m[known] = mid_vals[np.searchsorted(mid_keys, keys[known])]
            if (~known).any():
                ukeys, first, inv = np.unique(keys[~known], return_index=True, return_inverse=True)
                tri = idx[~known][first]  # the triangle that creates each new vertex
                lo, hi = ukeys // _S, ukeys % _S
                pos = 0.5 * (self.V[lo] + self.V[hi])
                nrm = self.N[lo] + self.N[hi]
                ln = np.linalg.norm(nrm, axis=1)
                nrm = np.where(ln[:, None] > 1e-12, nrm / np.maximum(ln, 1e-300)[:, None], self.N[lo])
                new_ids = self.nv + np.arange(len(ukeys), dtype=np.int64)
                self.V = np.concatenate([self.V, pos])
                self.N = np.concatenate([self.N, nrm])
                self.vparent = np.concatenate([self.vparent, self.tparent[tri]])
                self.vbary = np.concatenate([self.vbary, 0.5 * (self.tbary[tri, 0] + self.tbary[tri, 1])])
                m[~known] = new_ids[inv.reshape(-1)]
                order = np.argsort(np.concatenate([mid_keys, ukeys]), kind="stable")
                mid_keys = np.concatenate([mid_keys, ukeys])[order]
                mid_vals = np.concatenate([mid_vals, new_ids])[order]
            tb = self.tbary[idx]
            mb = 0.5 * (tb[:, 0] + tb[:, 1])
            c1 = np.stack([c[idx], a[idx], m], axis=1)  # refinement edge c–a
            c2 = np.stack([b[idx], c[idx], m], axis=1)  # refinement edge b–c
            b1 = np.stack([tb[:, 2], tb[:, 0], mb], axis=1)
            b2 = np.stack([tb[:, 1], tb[:, 2], mb], axis=1)
            keep = ~sel
            self.T = np.concatenate([self.T[keep], c1, c2])
            self.tbary = np.concatenate([self.tbary[keep], b1, b2])
            self.tparent = np.concatenate([self.tparent[keep], self.tparent[idx], self.tparent[idx]])
        raise RuntimeError("refine: bisection did not terminate (closure violated)")  # pragma: no cover

    def fit_marks(self, edges, marked, score, room):
        """The marks of the highest-``score`` marked geometric edges whose closed split adds at
        most ``room`` vertices (all of ``marked`` when they fit), and the index keys they split."""
        ikey, geid, _ = edges
        split = self.split_keys(ikey, geid, self.closure(geid, marked))
        if len(split) <= room:
            return marked, split
        cand = np.flatnonzero(marked)
        cand = cand[np.argsort(-score[cand], kind="stable")]

        def fits(k):
            mk = np.zeros_like(marked)
            mk[cand[:k]] = True
            s = self.split_keys(ikey, geid, self.closure(geid, mk))
            return len(s) <= room, s, mk

        lo, hi = 0, len(cand)
        best, best_mk = np.zeros(0, np.int64), np.zeros_like(marked)
        while lo < hi:  # largest k that fits (the count is monotone in k)
            mid = (lo + hi + 1) // 2
            ok, s, mk = fits(mid)
            if ok:
                lo, best, best_mk = mid, s, mk
            else:
                hi = mid - 1
        return best_mk, best

    def refine_step(self, edges, marked, score, room):
        """Split the marked geometric edges (``marked`` bool per geometric edge of ``edges`` =
        :meth:`edges`), at most ``room`` new vertices; if all do not fit, the highest ``score``
        first. Returns the number of vertices added."""
        if room <= 0:
            return 0
        _, split = self.fit_marks(edges, marked, score, room)
        if not len(split):
            return 0
        n0 = self.nv
        self.bisect(split)
        return self.nv - n0


def isin_sorted(x, sorted_keys):
    """Per entry of ``x``, whether it is in the ascending array ``sorted_keys``."""
    if not len(sorted_keys):
        return np.zeros(len(x), bool)
    p = np.minimum(np.searchsorted(sorted_keys, x), len(sorted_keys) - 1)
    return sorted_keys[p] == x


__all__ = ["EDGE_KEY_STRIDE", "BisectionMesh", "isin_sorted"]

r"""PCA compression of per-vertex SSDFs (paper §5.2 eq. 24).

Math layer: a generic PCA of the rows of a matrix, used by the SSDF precompute and by the
measured-BRDF shadowing basis.

``V^d_x(i) ≈ mean(i) + Σ_{j=1..NV} w_{x,j} 𝕍_j(i)``: rows of ``X`` (V, D) are the SSDF images of the
vertices (D = R²). ``mean`` is the row mean, ``𝕍_j`` the leading right singular vectors of the
centred data (orthonormal, D-vectors), ``w = (X − mean) 𝕍ᵀ``.

Method: for ``D ≤ 4096`` the D×D covariance ``CᵀC`` is accumulated in float64 over row chunks and
diagonalised (leading eigenpairs by block subspace iteration, exact ``eigh`` when small) — exact and cheap for any V;
above, a randomized range finder
(Halko, Martinsson & Tropp 2011; 2 power iterations, oversampling 10) is used. Reconstruction
RMS error for every number of terms 0..NV comes from the eigenvalues:
``rms(k) = sqrt((Σ_all σ² − Σ_{j≤k} σ²) / (V·D))``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PCAResult:
    mean: np.ndarray      # (D,) float32
    basis: np.ndarray     # (NV, D) float32, orthonormal rows
    weights: np.ndarray   # (V, NV) float32
    rms_error: np.ndarray  # (NV + 1,) float64: reconstruction RMS error with 0..NV terms

    def reconstruct(self, rows=None) -> np.ndarray:
        w = self.weights if rows is None else self.weights[np.asarray(rows)]
        return self.mean + w @ self.basis


def _chunks(n, size):
    return [(s, min(s + size, n)) for s in range(0, n, size)]


def _leading_eigenpairs(cov, k: int, seed: int = 0, iters: int = 10):
    """Top-k eigenpairs of a symmetric PSD matrix: full ``eigh`` when small, else block subspace
    iteration (oversampling 2k + 10, ``iters`` steps) + Rayleigh–Ritz. The subspace iteration uses
    only matrix products and thin QRs, which stay fast when BLAS threads are oversubscribed
    (LAPACK ``eigh`` of a 1024² matrix was measured 20× slower then). The captured energy of the
    returned basis is exactly the sum of the returned eigenvalues."""
    D = cov.shape[0]
    p = min(D, 2 * k + 10)
    if D <= 256 or p >= D // 2:
        evals, evecs = np.linalg.eigh(cov)
        order = np.argsort(evals)[::-1][:k]
        return evecs[:, order].T, np.maximum(evals[order], 0.0)
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(cov @ rng.standard_normal((D, p)))[0]
    for _ in range(iters):
        Q = np.linalg.qr(cov @ Q)[0]
    evals, evecs = np.linalg.eigh(Q.T @ cov @ Q)
    order = np.argsort(evals)[::-1][:k]
    return (Q @ evecs[:, order]).T, np.maximum(evals[order], 0.0)


def pca(X, n_terms: int, *, chunk: int = 8192, seed: int = 0) -> PCAResult:
    """PCA of the rows of ``X`` (V, D) keeping ``n_terms`` (clamped to ≤ min(V, D)) components.

    BLAS runs on one thread here (``threadpoolctl``): the products are large enough for one core,
    and OpenBLAS's spinning worker threads cost 2.6–7× the CPU time (20 k × 1024 rows: 0.8 CPU-s
    on one thread, 2.1–7.1 on two, while other threads of the precompute or other programs share
    the cores)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _pca(X, n_terms, chunk, seed)


def _pca(X, n_terms: int, chunk: int, seed: int) -> PCAResult:
    X = np.asarray(X)
    V, D = X.shape
    k = int(max(0, min(n_terms, V, D)))
    mean = X.mean(axis=0, dtype=np.float64)
    total = 0.0
    if D <= 4096:
        cov = np.zeros((D, D), np.float64)
        for s, e in _chunks(V, chunk):
            c = X[s:e].astype(np.float64) - mean
            cov += c.T @ c
        total = float(np.trace(cov))
        if k == 0:
            basis = np.zeros((0, D))
            energy = np.zeros(0)
        else:
            basis, energy = _leading_eigenpairs(cov, k, seed)
    else:  # randomized SVD of the centred data
        rng = np.random.default_rng(seed)
        p = min(D, k + 10)
        Q = rng.standard_normal((D, p))
        for s, e in _chunks(V, chunk):
            c = X[s:e].astype(np.float64) - mean
            total += float(np.sum(c * c))

        def mult(M):  # C @ M  (V, p)
            return np.concatenate([(X[s:e].astype(np.float64) - mean) @ M for s, e in _chunks(V, chunk)])

        def tmult(Y):  # Cᵀ @ Y  (D, p)
            out = np.zeros((D, Y.shape[1]))
            for s, e in _chunks(V, chunk):
                out += (X[s:e].astype(np.float64) - mean).T @ Y[s:e]
            return out

        Y = mult(Q)
        for _ in range(2):
            Y, _ = np.linalg.qr(Y)
            Y = mult(np.linalg.qr(tmult(Y))[0])
        Qy, _ = np.linalg.qr(Y)
        B = tmult(Qy).T  # (p, D) = Qyᵀ C
        _, s, vt = np.linalg.svd(B, full_matrices=False)
        basis = vt[:k]
        energy = s[:k] ** 2
    basis = basis.astype(np.float32)
    weights = np.empty((V, k), np.float32)
    for s, e in _chunks(V, chunk):
        weights[s:e] = ((X[s:e].astype(np.float64) - mean) @ basis.T.astype(np.float64)).astype(np.float32)
    resid = np.maximum(total - np.concatenate([[0.0], np.cumsum(energy)]), 0.0)
    rms = np.sqrt(resid / max(V * D, 1))
    if k < n_terms:  # pad so that callers always get n_terms rows
        pad = n_terms - k
        basis = np.concatenate([basis, np.zeros((pad, D), np.float32)])
        weights = np.concatenate([weights, np.zeros((V, pad), np.float32)], axis=1)
        rms = np.concatenate([rms, np.full(pad, rms[-1])])
    return PCAResult(mean.astype(np.float32), basis, weights, rms)


class DeferredPCA:
    """A :class:`PCAResult` that is computed on first use: :func:`pca` of the rows ``X`` to
    ``n_terms`` terms, once (thread-safe), when :meth:`result` is first called; or one given
    (:meth:`of`). For data whose consumers may never need the compressed form (the renderer reads
    uncompressed SSDF maps where they fit its budget): the PCA then costs nothing.
    ``n_terms`` and ``n_rows`` are known without computing it. Pickles as its inputs (or result)."""

    def __init__(self, X=None, n_terms: int = 0, result: PCAResult | None = None):
        import threading

        if result is None and X is None:
            raise ValueError("DeferredPCA needs the rows X or a result")
        self._X = None if result is not None else X
        self._result = result
        self.n_terms = int(result.basis.shape[0] if result is not None else n_terms)
        self.n_rows = int(result.weights.shape[0] if result is not None else np.shape(X)[0])
        self._lock = threading.Lock()

    @classmethod
    def of(cls, result: PCAResult) -> "DeferredPCA":
        return cls(result=result)

    @property
    def pending(self) -> bool:
        """Whether the PCA has not been computed yet."""
        return self._result is None

    def result(self) -> PCAResult:
        if self._result is None:
            with self._lock:
                if self._result is None:
                    self._result = pca(self._X, self.n_terms)
                    self._X = None  # (the rows stay with their owner)
        return self._result

    def __getstate__(self):
        return {"X": self._X, "n_terms": self.n_terms, "n_rows": self.n_rows, "result": self._result}

    def __setstate__(self, st):
        import threading

        self._X, self._result = st["X"], st["result"]
        self.n_terms, self.n_rows = st["n_terms"], st["n_rows"]
        self._lock = threading.Lock()


__all__ = ["PCAResult", "pca", "DeferredPCA"]

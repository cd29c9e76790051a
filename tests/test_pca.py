"""warp_sg.numeric.pca (re-exported as warp_sg.numeric.pca): exact recovery of low-rank data, reported errors, randomized path."""
from __future__ import annotations

import numpy as np
import pytest

from warp_sg.numeric import pca as pca_module
from warp_sg.numeric.pca import DeferredPCA, pca


def _low_rank(V, D, rank, seed=0, noise=0.0):
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((V, rank)) @ rng.standard_normal((rank, D)) + rng.standard_normal(D)
    return (X + noise * rng.standard_normal((V, D))).astype(np.float32)


@pytest.mark.parametrize("D", [64, 4100])  # covariance path and randomized path
def test_pca_recovers_low_rank_data(D):
    X = _low_rank(300, D, 5)
    p = pca(X, 5)
    assert p.basis.shape == (5, D) and p.weights.shape == (300, 5)
    np.testing.assert_allclose(p.basis @ p.basis.T, np.eye(5), atol=1e-4)
    assert np.abs(p.reconstruct() - X).max() < 1e-3 * np.abs(X).max()
    assert p.rms_error[-1] < 1e-3


def test_reported_rms_error_matches_reconstruction():
    X = _low_rank(500, 100, 12, noise=0.1)
    p = pca(X, 8)
    for k in (0, 3, 8):
        rec = p.mean + p.weights[:, :k] @ p.basis[:k]
        rms = np.sqrt(np.mean((rec - X) ** 2))
        assert p.rms_error[k] == pytest.approx(rms, rel=1e-3)
    assert np.all(np.diff(p.rms_error) <= 1e-9)  # more terms never hurt


def test_more_terms_than_rank_are_zero_padded():
    X = _low_rank(4, 30, 2)
    p = pca(X, 10)
    assert p.basis.shape == (10, 30) and p.weights.shape == (4, 10)
    np.testing.assert_allclose(p.reconstruct(), X, atol=1e-4)


def test_deferred_pca_is_computed_once_on_first_use_and_pickles(monkeypatch):
    """DeferredPCA: nothing is computed until result() is called; then pca() runs once however many
    threads ask at the same time, and gives what pca() gives; it pickles before and after."""
    import pickle
    from concurrent.futures import ThreadPoolExecutor

    X = _low_rank(400, 64, 6, noise=0.05)
    calls = []
    real = pca_module.pca
    monkeypatch.setattr(pca_module, "pca", lambda *a, **k: calls.append(1) or real(*a, **k))
    d = DeferredPCA(X, 6)
    assert d.pending and d.n_terms == 6 and d.n_rows == 400 and calls == []
    early = pickle.loads(pickle.dumps(d))
    with ThreadPoolExecutor(4) as ex:
        results = list(ex.map(lambda _: d.result(), range(8)))
    assert len(calls) == 1 and all(r is results[0] for r in results) and not d.pending
    ref = real(X, 6)
    for k in ("mean", "basis", "weights", "rms_error"):
        np.testing.assert_array_equal(getattr(results[0], k), getattr(ref, k))
    np.testing.assert_array_equal(early.result().weights, ref.weights)
    late = pickle.loads(pickle.dumps(d))
    assert not late.pending and np.array_equal(late.result().basis, ref.basis)
    given = DeferredPCA.of(ref)
    assert not given.pending and given.n_terms == 6 and given.n_rows == 400 and given.result() is ref
    with pytest.raises(ValueError):
        DeferredPCA()

r"""Variable projection with non-negative linear amplitudes (Golub & Pereyra 1973; O'Leary & Rust
2013, "Variable projection for nonlinear least squares problems", Comput. Optim. Appl. 54).

The fit ``min_{x, μ ≥ 0} ‖A(x) μ − B‖²`` (``B`` with C columns, one amplitude vector per
column) is reduced to ``x`` alone: for given ``x`` the amplitudes are the non-negative least
squares solution, computed on the triangular factor (``A = QR``: ``‖Aμ − b‖² = ‖Rμ − Qᵀb‖² +
const``, so NNLS of the K × K system has the same minimiser), and the residual is
``r(x) = A μ(x) − B``.

Jacobian. With the NNLS free set ``F`` (``μ_F > 0``) held fixed, ``μ_F = A_F⁺ b`` and
``r = −P⊥ b`` with ``P⊥ = I − A_F A_F⁺``; differentiating the projector (Golub–Pereyra)::

    ∂r/∂x_i = P⊥ (∂A/∂x_i) μ − (A_F⁺)ᵀ (∂A/∂x_i)ᵀ r.

The second term is the one Kaufman's approximation drops; it is kept here (it costs one more
thin product), so the Jacobian is the exact derivative of ``r(x)`` wherever the free set does not
change. Here each parameter ``x_i`` moves one column ``k_i`` of ``A`` (``∂A/∂x_i = a'_i e_kᵀ``),
so with ``A_F = Q_F R_F``::

    ∂r/∂x_i = P⊥ a'_i μ_k − Q_F R_F⁺ᵀ e_k (a'_i · r)      (0 when k ∉ F).

:class:`Projection` evaluates ``A(x)`` once per ``x`` and keeps the last evaluation, so the
Jacobian at the accepted point reuses the residual's work.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls


def solve_nonnegative(A, B):
    """``μ = argmin_{μ ≥ 0} ‖A μ − B[:, c]‖`` per column of ``B`` (K, C), by NNLS on ``R`` of
    ``A = QR`` (module docstring)."""
    q, r = np.linalg.qr(A)
    qtb = q.T @ B
    mu = np.zeros((A.shape[1], B.shape[1]))
    for c in range(B.shape[1]):  # a few colour channels
        mu[:, c] = nnls(r, qtb[:, c], maxiter=50 * A.shape[1])[0]
    return mu, q, r


class Projection:
    """``r(x) = A(x) μ(x) − B`` (raveled, rows × C) and its Jacobian (module docstring).

    ``design(x) -> (A (N, K), state)`` and ``derivative(state) -> (N, P)`` (column ``i`` is
    ``∂A[:, lobe[i]]/∂x_i``); ``lobe`` (P,) is the column of ``A`` each parameter moves."""

    def __init__(self, design, derivative, B, lobe):
        self.design, self.derivative = design, derivative
        self.B = np.asarray(B, np.float64)
        self.lobe = np.asarray(lobe, int)
        self._x = None

    def evaluate(self, x):
        """``(A, μ, r (N, C))`` at ``x`` (kept: a second call at the same ``x`` is free)."""
        x = np.asarray(x, np.float64)
        if self._x is None or not np.array_equal(x, self._x):
            A, state = self.design(x)
            mu, q, r = solve_nonnegative(A, self.B)
            self._x, self._last = x.copy(), (A, mu, A @ mu - self.B, q, r, state)
        return self._last[:3]

    def residual(self, x):
        """``r(x)`` raveled channel by channel (C·N,)."""
        return self.evaluate(x)[2].T.ravel()

    def jacobian(self, x):
        """``∂r/∂x`` (C·N, P), rows in the order of :meth:`residual`. The channels that share a
        free set share ``Q_F``."""
        self.evaluate(x)
        A, mu, res, q, r, state = self._last
        dA = self.derivative(state)  # (N, P)
        n, n_ch = res.shape
        s = dA.T @ res  # (P, C): a'_i · r_c
        mu_p = mu[self.lobe]  # (P, C): the amplitude each parameter's column carries
        J = np.empty((n_ch, n, len(self.lobe)))
        free_sets = {}
        for c in range(n_ch):  # a few colour channels
            np.multiply(dA, mu_p[:, c], out=J[c])  # ∂A/∂x_i μ  (0 where the column is not free)
            free_sets.setdefault(tuple(np.flatnonzero(mu[:, c] > 0)), []).append(c)
        for free, chans in free_sets.items():
            if not free:
                continue  # r = −b: no dependence on x
            free = np.asarray(free)
            q2, r_f = np.linalg.qr(r[:, free])  # A_F = Q R_F = (Q q2) r_f
            q_f = q @ q2
            pos = np.full(A.shape[1], -1)
            pos[free] = np.arange(len(free))
            moves = pos[self.lobe] >= 0  # parameters of free columns
            t = np.zeros((len(free), len(self.lobe)))
            t[:, moves] = np.linalg.pinv(r_f).T[:, pos[self.lobe[moves]]]  # R_F⁺ᵀ e_k
            y = q_f.T @ dA
            for c in chans:
                J[c] -= q_f @ (y * mu_p[:, c] + t * s[:, c])
        return J.reshape(n_ch * n, -1)

r"""Adam (Kingma & Ba 2015, "Adam: a method for stochastic optimization", Algorithm 1) on numpy
arrays, one state per free parameter::

    m ← β1 m + (1 − β1) g,   v ← β2 v + (1 − β2) g²,   x ← x − η m̂ / (√v̂ + ε)

with the bias corrections ``m̂ = m/(1 − β1ᵗ)``, ``v̂ = v/(1 − β2ᵗ)``. The state is plain arrays
(:meth:`Adam.state` / :meth:`Adam.load`): a fit's checkpoint holds it, so a resumed fit takes the
same steps as one that was never stopped.
"""
from __future__ import annotations

import numpy as np


class Adam:
    """Adam over a list of arrays ``xs`` (updated in place by :meth:`step`) with learning rates ``lrs``."""

    def __init__(self, shapes, lrs, beta1: float = 0.9, beta2: float = 0.999, eps: float = 1e-8):
        self.lrs = [float(x) for x in lrs]
        self.b1, self.b2, self.eps = float(beta1), float(beta2), float(eps)
        self.m = [np.zeros(s) for s in shapes]
        self.v = [np.zeros(s) for s in shapes]
        self.t = 0

    def step(self, xs, grads) -> None:
        self.t += 1
        c1 = 1.0 - self.b1 ** self.t
        c2 = 1.0 - self.b2 ** self.t
        for x, g, m, v, lr in zip(xs, grads, self.m, self.v, self.lrs):
            g = np.asarray(g, np.float64).reshape(m.shape)
            m *= self.b1
            m += (1.0 - self.b1) * g
            v *= self.b2
            v += (1.0 - self.b2) * g * g
            x -= lr * (m / c1) / (np.sqrt(v / c2) + self.eps)

    def state(self) -> dict:
        out = {"adam_t": np.array(self.t)}
        for i, (m, v) in enumerate(zip(self.m, self.v)):
            out[f"adam_m{i}"], out[f"adam_v{i}"] = m, v
        return out

    def load(self, st) -> None:
        self.t = int(st["adam_t"])
        for i in range(len(self.m)):
            self.m[i] = np.array(st[f"adam_m{i}"], np.float64).reshape(self.m[i].shape)
            self.v[i] = np.array(st[f"adam_v{i}"], np.float64).reshape(self.v[i].shape)


__all__ = ["Adam"]

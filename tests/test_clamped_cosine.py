"""Clamped-cosine SG fits: the 1-lobe L2 optimum reproduces paper eq. 40, the error falls with
the number of lobes, the stored constants are the least-squares optimum (re-fit), errors against
an independent scipy quadrature."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from warp_sg.core.errors import InputError
from warp_sg.sg import cosine_lobes as C


def quad_rel_error(lam, mu):
    f = lambda x: max(x, 0.0)  # noqa: E731
    g = lambda x: float(np.sum(mu * np.exp(lam * (x - 1.0))))  # noqa: E731
    num = integrate.quad(lambda x: (f(x) - g(x)) ** 2, -1, 0, epsabs=0, epsrel=1e-11)[0] + \
        integrate.quad(lambda x: (f(x) - g(x)) ** 2, 0, 1, epsabs=0, epsrel=1e-11)[0]
    return np.sqrt(num / (1.0 / 3.0))


def test_single_lobe_is_paper_eq40():
    lam, mu = C.lobes(1)
    assert lam[0] == pytest.approx(2.133, rel=6e-3)
    assert mu[0] == pytest.approx(1.170, rel=6e-3)
    # and it is a (slightly) better L2 fit than the rounded paper values
    assert C.relative_l2_error(lam, mu) <= C.relative_l2_error(*C.PAPER_LOBE)


def test_error_decreases_with_lobes_and_matches_quadrature():
    rep = C.error_report()
    errs = [rep[k][0] for k in range(1, 5)]
    assert all(b < a for a, b in zip(errs, errs[1:]))
    assert errs[0] == pytest.approx(0.1774, abs=2e-4)
    assert errs[1] < 0.12 and errs[3] < 0.097
    for k in range(1, 5):
        lam, mu = C.lobes(k)
        assert quad_rel_error(lam, mu) == pytest.approx(errs[k - 1], rel=1e-6)
        assert np.all(np.abs(mu) <= C.MAX_AMPLITUDE + 1e-9)


@pytest.mark.parametrize("k", [1, 2])
def test_stored_constants_are_the_least_squares_optimum(k):
    lam, mu = C.fit(k)
    assert C.relative_l2_error(lam, mu) == pytest.approx(C.relative_l2_error(*C.LOBES[k]), rel=1e-6)


def test_bad_lobe_count_raises():
    for bad in (0, 5, 1.5):
        with pytest.raises(InputError, match="n_lobes"):
            C.lobes(bad)

"""Anisotropic BRDFs with N-lobe SG mixtures: the error falls as N grows (supplement Fig. 5-6)."""
from __future__ import annotations

import numpy as np
import pytest

from warp_sg.sg import anisotropy as A

Q = dict(n_o=12, n_phi_o=4, n_th=48, n_ph=32)  # small eq. 11 quadrature


@pytest.mark.parametrize("name", ["ashikhmin_shirley", "ward"])
def test_fitted_sg_mixture_error_decreases_with_lobe_count(name):
    exact = A.render_sphere(A.make(name, 1), None, res=24, quad=(16, 32))
    ndf, render = [], []
    for n in (1, 3, 5):
        m = A.make(name, n)
        ndf.append(A.ndf_error(m, n, "fit", **Q))
        render.append(A.render_error(m, n, "fit", exact=exact, res=24, quad=(16, 32)))
    assert np.all(np.diff(ndf) < 0) and np.all(np.diff(render) < 0)
    # one lobe cannot represent the anisotropic NDF; five lobes get within a few percent
    assert ndf[0] > 0.2
    assert ndf[2] < 0.05 and render[2] < 0.03


def test_analytic_construction_improves_from_one_to_seven_lobes():
    m1, m7 = A.make("ashikhmin_shirley", 1), A.make("ashikhmin_shirley", 7)
    e1 = A.ndf_error(m1, 1, "analytic", **Q)
    e7 = A.ndf_error(m7, 7, "analytic", **Q)
    assert e7 < 0.05 < 0.3 < e1


def test_warped_slice_error_tracks_ndf_error():
    m = A.make("ward", 5)
    e_ndf = A.ndf_error(m, 5, "analytic", **Q)
    e_slice = A.slice_error(m, 5, "analytic", res=(96, 96))
    # the spherical warp adds error but does not change its magnitude
    assert 0.5 * e_ndf < e_slice < 3 * e_ndf + 0.05

"""The polynomial atan2 / asin of ``warp_sg.numeric.fastmath`` against numpy's libm on dense grids,
including the axes, the quadrant boundaries and the ends of asin's domain."""
import numpy as np
import pytest
import warp as wp

from warp_sg.numeric.fastmath import fast_asin, fast_atan2


@wp.kernel
def _eval(y: wp.array(dtype=float), x: wp.array(dtype=float), atan2_out: wp.array(dtype=float),
          asin_out: wp.array(dtype=float)):
    i = wp.tid()
    atan2_out[i] = fast_atan2(y[i], x[i])
    asin_out[i] = fast_asin(x[i])


def test_fast_atan2_and_asin_match_libm_within_3_microradians():
    rng = np.random.default_rng(0)
    ang = np.concatenate([np.linspace(-np.pi, np.pi, 20001), np.arange(-4, 5) * np.pi / 4])
    rad = np.concatenate([rng.uniform(1e-6, 1e3, len(ang) - 9), np.ones(9)])
    y = (rad * np.sin(ang)).astype(np.float32)
    x = (rad * np.cos(ang)).astype(np.float32)
    # asin on its own grid in [-1, 1] (ends included), reusing the x slot
    s = np.concatenate([np.linspace(-1.0, 1.0, len(ang) - 4), [-1.0, 1.0, 0.0, 0.999999]]).astype(np.float32)
    a2 = wp.zeros(len(ang), dtype=float, device="cpu")
    as_ = wp.zeros(len(ang), dtype=float, device="cpu")
    wp.launch(_eval, dim=len(ang), inputs=[wp.array(y, device="cpu"), wp.array(x, device="cpu"), a2, as_],
              device="cpu")
    want = np.arctan2(y.astype(np.float64), x.astype(np.float64))
    got = a2.numpy().astype(np.float64)
    d = np.abs(np.angle(np.exp(1j * (got - want))))  # ±π are the same angle
    assert d.max() < 3e-6, d.max()
    wp.launch(_eval, dim=len(s), inputs=[wp.array(s, device="cpu"), wp.array(s, device="cpu"), a2, as_],
              device="cpu")
    e = np.abs(as_.numpy().astype(np.float64) - np.arcsin(s.astype(np.float64)))
    assert e.max() < 1e-6, e.max()
    assert as_.numpy()[-3] == pytest.approx(np.pi / 2, abs=1e-6)  # asin(1)

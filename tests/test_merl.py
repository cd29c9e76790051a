"""MERL file reader/writer, validation and the lookup (numpy and the Warp kernel)."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_sg.brdf import CookTorrance, merl
from warp_sg.brdf.kernel.measured_wp import merl_eval, merl_index
from warp_sg.core.errors import InputError


@pytest.fixture(scope="module")
def ct_table():
    return merl.tabulate(CookTorrance(kd=(0.2, 0.1, 0.05), ks=(20.0, 25.0, 30.0), m=0.15, fresnel={"eta": 1.33}))


def _random_pairs(n, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2]) + 0.05
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return v[0], v[1]


def test_cell_centres_map_back_to_their_own_cells():
    o, i = merl.cell_directions()
    up = (o[..., 2] > 0) & (i[..., 2] > 0)
    idx = merl.merl_index(o, i)
    expect = np.arange(merl.N_CELLS).reshape(merl.SHAPE)
    assert up.mean() > 0.7
    assert np.array_equal(idx[up], expect[up])


# --- MERL's reference code (BRDFRead.cpp, Matusik et al. 2003), transcribed, vectorised over pairs ---
def _ref_rotate(v, axis, angle):
    """rotate_vector(): Rodrigues' rotation of v about a unit axis."""
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    axis = np.broadcast_to(axis, v.shape)
    return v * c + axis * np.sum(axis * v, -1, keepdims=True) * (1 - c) + np.cross(axis, v) * s


def _ref_index(i, o):
    """lookup_brdf_val()'s flat index: std_coords_to_half_diff_coords() then the three index functions."""
    half = (i + o) / 2.0
    half /= np.linalg.norm(half, axis=-1, keepdims=True)
    theta_half = np.arccos(np.clip(half[..., 2], -1, 1))
    fi_half = np.arctan2(half[..., 1], half[..., 0])
    tmp = _ref_rotate(i, np.array([0.0, 0.0, 1.0]), -fi_half)
    diff = _ref_rotate(tmp, np.array([0.0, 1.0, 0.0]), -theta_half)
    theta_diff = np.arccos(np.clip(diff[..., 2], -1, 1))
    fi_diff = np.arctan2(diff[..., 1], diff[..., 0])
    # theta_half_index: sqrt((θh / (π/2)) · 90 · 90), 0 for θh <= 0
    ih = np.where(theta_half <= 0, 0, np.sqrt(theta_half / (np.pi / 2) * 90 * 90).astype(int).clip(0, 89))
    idd = (theta_diff / (np.pi * 0.5) * 90).astype(int).clip(0, 89)
    fd = np.where(fi_diff < 0, fi_diff + np.pi, fi_diff)
    ip = (fd / np.pi * 360 / 2).astype(int).clip(0, 179)
    return ip + idd * 180 + ih * 180 * 90


def test_lookup_is_reciprocal_and_matches_the_reference_code_indexing():
    o, i = _random_pairs(20000)
    idx = merl.merl_index(o, i)
    assert np.array_equal(idx, merl.merl_index(i, o))
    ref = _ref_index(i, o)
    # a different float path may round differently exactly at a bin edge: allow a handful of those
    same = idx == ref
    assert same.mean() > 0.9995, same.mean()
    # the specular configuration (h = n): θh bin 0, θd = angle of incidence, as in the reference code
    o1, i1 = np.array([[0.6, 0.0, 0.8]]), np.array([[-0.6, 0.0, 0.8]])
    assert merl.merl_index(o1, i1)[0] == _ref_index(i1, o1)[0]
    assert _ref_index(i1, o1)[0] // (180 * 90) == 0


def test_written_file_reads_back_with_merl_scales(tmp_path, ct_table):
    p = merl.write_merl(tmp_path / "ct.binary", ct_table)
    raw = p.read_bytes()
    assert len(raw) == 12 + 3 * 90 * 90 * 180 * 8
    assert tuple(np.frombuffer(raw[:12], "<i4")) == (90, 90, 180)
    # stored unscaled, with the reference code's RED/GREEN/BLUE_SCALE = 1/1500, 1.15/1500, 1.66/1500
    stored = np.frombuffer(raw, "<f8", offset=12).reshape(3, 90, 90, 180)
    for c, scale in enumerate((1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0)):
        np.testing.assert_allclose(stored[c] * scale, ct_table[c], rtol=1e-12, atol=1e-15)
    back = merl.read_merl(p)
    np.testing.assert_allclose(back, ct_table, rtol=1e-12, atol=1e-15)


def test_lookup_returns_the_brdf_at_the_centre_of_the_reference_codes_cell(ct_table):
    """A lookup at any pair gives the analytic BRDF at the centre of the cell the reference code puts
    the pair in; the centre (and a pair of directions with those angles) is built here from the
    MERL parameterisation: θh = ((ih + ½)/90)² π/2, θd = (id + ½)/90 · π/2, φd = (ip + ½)/180 · π."""
    ct = CookTorrance(kd=(0.2, 0.1, 0.05), ks=(20.0, 25.0, 30.0), m=0.15, fresnel={"eta": 1.33})
    o, i = _random_pairs(3000, seed=5)
    ref = _ref_index(i, o)
    ih, rest = np.divmod(ref, 180 * 90)
    idd, ip = np.divmod(rest, 180)
    th = ((ih + 0.5) / 90) ** 2 * (np.pi / 2)
    td = (idd + 0.5) / 90 * (np.pi / 2)
    pd = (ip + 0.5) / 180 * np.pi
    # the inverse of the reference code's transform (φh = 0: the BRDF is isotropic)
    diff = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
    ic = _ref_rotate(diff, np.array([0.0, 1.0, 0.0]), th)
    h = np.stack([np.sin(th), 0 * th, np.cos(th)], -1)
    oc = 2 * np.sum(ic * h, -1, keepdims=True) * h - ic
    up = (oc[:, 2] > 0) & (ic[:, 2] > 0)  # centres above the horizon (the table holds 0 below it)
    assert up.mean() > 0.9
    got = merl.merl_lookup(ct_table, o, i)
    same = merl.merl_index(o, i) == ref
    assert same.mean() > 0.999
    np.testing.assert_allclose(got[same & up], ct.eval(oc[same & up], ic[same & up]), rtol=1e-9, atol=1e-12)
    # below the horizon: zero
    assert np.all(merl.merl_lookup(ct_table, [0, 0, 1.0], [0.0, 0.6, -0.8]) == 0)


@pytest.mark.parametrize("case", ["short", "dims", "size", "nan", "negative"])
def test_bad_files_raise_input_error_naming_the_file(tmp_path, ct_table, case):
    p = tmp_path / f"bad_{case}.binary"
    header = np.asarray((90, 90, 180), "<i4").tobytes()
    body = (ct_table / merl.SCALE[:, None, None, None]).astype("<f8")
    if case == "short":
        p.write_bytes(b"\x00" * 7)
        msg = "header"
    elif case == "dims":
        p.write_bytes(np.asarray((90, 90, 360), "<i4").tobytes() + body.tobytes())
        msg = "dimensions"
    elif case == "size":
        p.write_bytes(header + body.tobytes()[:-8])
        msg = "size mismatch"
    elif case == "nan":
        body[2, 10, 10, 10] = np.nan
        p.write_bytes(header + body.tobytes())
        msg = "NaN"
    else:
        body[0, 5, 5, 5] = -0.5  # a well-lit cell
        p.write_bytes(header + body.tobytes())
        msg = "negative"
    with pytest.raises(InputError, match=msg) as ei:
        merl.read_merl(p)
    assert str(p) in str(ei.value)


def test_missing_file_raises_input_error(tmp_path):
    with pytest.raises(InputError, match="not found"):
        merl.read_merl(tmp_path / "nope.binary")


def test_negative_below_horizon_markers_are_accepted_as_zero(tmp_path, ct_table):
    tab = merl.tabulate(CookTorrance(kd=0.1, ks=10.0, m=0.2), below_horizon=-1.0 / 1500)
    below = merl.horizon_cells()
    assert (tab[0][below] < 0).any()
    back = merl.read_merl(merl.write_merl(tmp_path / "h.binary", tab))
    assert back.min() == 0.0
    np.testing.assert_allclose(back[:, ~below], tab[:, ~below], rtol=1e-12)


@wp.kernel
def _lookup_kernel(data: wp.array(dtype=float), o: wp.array(dtype=wp.vec3), i: wp.array(dtype=wp.vec3),
                   out: wp.array(dtype=wp.vec3), idx: wp.array(dtype=int)):
    t = wp.tid()
    out[t] = merl_eval(data, 3, o[t], i[t])
    idx[t] = merl_index(o[t], i[t])


def test_kernel_lookup_matches_numpy(device, ct_table):
    o, i = _random_pairs(4000, seed=3)
    # keep away from bin edges where float32 and float64 may round differently
    th, td, pd = merl.half_diff_angles(o, i)
    frac = lambda x: np.abs(x - np.round(x))  # noqa: E731
    safe = (frac(np.sqrt(th / (np.pi / 2)) * 90) > 1e-3) & (frac(td / (np.pi / 2) * 90) > 1e-3) & (frac(pd / np.pi * 180) > 1e-3)
    o, i = o[safe], i[safe]
    flat = np.concatenate([np.zeros(3), ct_table.reshape(-1)]).astype(np.float32)
    d = wp.array(flat, dtype=float, device=device)
    n = len(o)
    out = wp.zeros(n, dtype=wp.vec3, device=device)
    idx = wp.zeros(n, dtype=int, device=device)
    wp.launch(_lookup_kernel, n, inputs=[d, wp.array(o.astype(np.float32), dtype=wp.vec3, device=device),
                                         wp.array(i.astype(np.float32), dtype=wp.vec3, device=device), out, idx],
              device=device)
    same = idx.numpy() == merl.merl_index(o, i)
    assert same.mean() > 0.995
    np.testing.assert_allclose(out.numpy()[same], merl.merl_lookup(ct_table, o, i)[same], rtol=1e-5, atol=1e-7)

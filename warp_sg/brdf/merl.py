r"""MERL measured-BRDF files (Matusik et al. 2003, "A data-driven reflectance model"): reader,
writer, vectorized lookup and the cell geometry.

File format (the MERL reference code ``BRDFRead.cpp``): three little-endian int32 dimensions
``90, 90, 180`` (θh, θd, φd), then ``3 · 90 · 90 · 180`` float64 values, the R block, then G,
then B, each in C order over (θh, θd, φd). Values are stored unscaled; the BRDF is
``value · scale`` with the per-channel scales ``1/1500, 1.15/1500, 1.66/1500``.

Parameterisation (Rusinkiewicz 1998; lecture "Regular halfangle format"): half vector
``h = (o+i)/‖o+i‖`` with angles (θh, φh); difference vector ``d = Ry(−θh) Rz(−φh) i`` with angles
(θd, φd). Isotropy drops φh; reciprocity folds φd into ``[0, π)``. Cells::

    ih = ⌊√(θh / (π/2)) · 90⌋,  id = ⌊θd / (π/2) · 90⌋,  ip = ⌊φd / π · 180⌋   (clamped)

The square root in θh puts more cells near the specular peak. The cell centres used by
:func:`cell_angles` are ``θh = ((ih + ½)/90)² π/2``, ``θd = (id + ½)/90 · π/2``,
``φd = (ip + ½)/180 · π``.

Validation (all raise :class:`~warp_sg.core.errors.InputError` naming the file): missing/unreadable
file, short header, dimensions other than 90·90·180, a data size that does not match the
dimensions, NaN or infinite values, negative values. Real MERL files mark configurations below
the horizon with negative values; those are accepted (and replaced by 0) only in cells whose centre
lies within :data:`HORIZON_MARGIN` of the horizon or below it — a negative value anywhere else is
an error.

Tables in memory are float64 arrays of shape ``(3, 90, 90, 180)`` holding the *scaled* BRDF.
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.files import atomic_output

N_THETA_H = 90
N_THETA_D = 90
N_PHI_D = 180
SHAPE = (N_THETA_H, N_THETA_D, N_PHI_D)
N_CELLS = N_THETA_H * N_THETA_D * N_PHI_D
#: per-channel scale factors of the MERL reference code (RED_SCALE, GREEN_SCALE, BLUE_SCALE)
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
#: cells whose centre has min(cos θi, cos θo) below this count as "at/below the horizon"
HORIZON_MARGIN = np.sin(np.radians(2.0))
_HEADER = 12


# --------------------------------------------------------------------------------------------
# geometry
# --------------------------------------------------------------------------------------------
def half_diff_angles(o, i):
    """(θh, θd, φd) of direction pairs (..., 3) — φd folded to ``[0, π)`` (module docstring)."""
    o = np.asarray(o, dtype=np.float64)
    i = np.asarray(i, dtype=np.float64)
    o, i = np.broadcast_arrays(o, i)
    hs = o + i
    hl = np.linalg.norm(hs, axis=-1, keepdims=True)
    h = hs / np.where(hl > 0, hl, 1.0)
    r = np.sqrt(h[..., 0] ** 2 + h[..., 1] ** 2)
    th = np.arctan2(r, h[..., 2])
    safe = r > 1e-12
    cp = np.where(safe, h[..., 0] / np.where(safe, r, 1.0), 1.0)
    sp = np.where(safe, h[..., 1] / np.where(safe, r, 1.0), 0.0)
    ct, st = h[..., 2], r
    dx = i[..., 0] * cp * ct + i[..., 1] * sp * ct - i[..., 2] * st
    dy = -i[..., 0] * sp + i[..., 1] * cp
    dz = np.sum(i * h, axis=-1)
    td = np.arctan2(np.sqrt(dx * dx + dy * dy), dz)
    pd = np.arctan2(dy, dx)
    pd = np.where(pd < 0, pd + np.pi, pd)
    return th, td, pd


def angle_indices(th, td, pd):
    """MERL cell indices (ih, id, ip) of angles, the reference code's rounding and clamping."""
    ih = np.clip((np.sqrt(np.maximum(th, 0.0) / (np.pi / 2)) * N_THETA_H).astype(np.int64), 0, N_THETA_H - 1)
    idd = np.clip((np.asarray(td) / (np.pi / 2) * N_THETA_D).astype(np.int64), 0, N_THETA_D - 1)
    ip = np.clip((np.asarray(pd) / np.pi * N_PHI_D).astype(np.int64), 0, N_PHI_D - 1)
    return ih, idd, ip


def merl_index(o, i):
    """Flat cell index ``ip + 180 (id + 90 ih)`` (within one channel block) of direction pairs."""
    ih, idd, ip = angle_indices(*half_diff_angles(o, i))
    return ip + N_PHI_D * (idd + N_THETA_D * ih)


def cell_angles():
    """Cell-centre angles (θh, θd, φd), each (90, 90, 180) float64 (broadcast views)."""
    th = ((np.arange(N_THETA_H) + 0.5) / N_THETA_H) ** 2 * (np.pi / 2)
    td = (np.arange(N_THETA_D) + 0.5) / N_THETA_D * (np.pi / 2)
    pd = (np.arange(N_PHI_D) + 0.5) / N_PHI_D * np.pi
    return np.broadcast_arrays(th[:, None, None], td[None, :, None], pd[None, None, :])


def directions_from_angles(th, td, pd, phi_h=0.0):
    """(o, i) of half/difference angles: ``i = Rz(φh) Ry(θh) d``, ``o = 2(i·h) h − i``."""
    th, td, pd = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (th, td, pd)))
    sd = np.sin(td)
    dx, dy, dz = sd * np.cos(pd), sd * np.sin(pd), np.cos(td)
    ct, st = np.cos(th), np.sin(th)
    ix = dx * ct + dz * st
    iz = -dx * st + dz * ct
    cph, sph = np.cos(phi_h), np.sin(phi_h)
    i = np.stack([ix * cph - dy * sph, ix * sph + dy * cph, iz], -1)
    h = np.stack(np.broadcast_arrays(st * cph, st * sph, ct), -1)
    o = 2.0 * np.sum(i * h, axis=-1, keepdims=True) * h - i
    return o, i


@functools.lru_cache(maxsize=1)
def cell_directions():
    """(o, i) at every cell centre, each (90, 90, 180, 3) float64, read-only (cached)."""
    o, i = directions_from_angles(*cell_angles())
    o.setflags(write=False)
    i.setflags(write=False)
    return o, i


@functools.lru_cache(maxsize=1)
def horizon_cells():
    """Boolean (90, 90, 180): cell centre at or below the horizon (within HORIZON_MARGIN)."""
    o, i = cell_directions()
    m = np.minimum(o[..., 2], i[..., 2]) < HORIZON_MARGIN
    m.setflags(write=False)
    return m


# --------------------------------------------------------------------------------------------
# lookup
# --------------------------------------------------------------------------------------------
def merl_lookup(table, o, i):
    """Measured BRDF (..., 3) at direction pairs (o, i) (local frame) by nearest-cell lookup, the
    indexing of the MERL reference code; zero where o or i is below the horizon, negative cells
    clamped to 0. ``table``: (3, 90, 90, 180) scaled values (e.g. from :func:`read_merl`)."""
    table = np.asarray(table)
    if table.shape != (3,) + SHAPE:
        raise InputError(f"expected a (3, 90, 90, 180) table, got shape {table.shape}", where="table")
    o = np.asarray(o, dtype=np.float64)
    i = np.asarray(i, dtype=np.float64)
    o, i = np.broadcast_arrays(o, i)
    idx = merl_index(o, i)
    flat = table.reshape(3, -1)
    val = np.maximum(np.moveaxis(flat[:, idx], 0, -1), 0.0)
    up = (o[..., 2] > 0) & (i[..., 2] > 0)
    return np.where(up[..., None], val, 0.0)


def tabulate(brdf, below_horizon=0.0):
    """MERL table (3, 90, 90, 180) of a BRDF at the cell centres.

    ``brdf``: a callable ``(o, i) -> (..., 3)`` or an object with ``eval(o, i)`` (e.g. any
    :mod:`warp_sg.brdf` model). Cells whose centre is below the horizon get ``below_horizon``
    (real MERL files hold negative markers there). Vectorized over the 1.46 M cells, evaluated in
    θh slabs to bound memory."""
    f = brdf.eval if hasattr(brdf, "eval") else brdf
    o, i = cell_directions()
    out = np.empty((3,) + SHAPE)
    step = 15
    for a in range(0, N_THETA_H, step):  # 6 slabs of 243 000 cells each
        v = np.asarray(f(o[a:a + step], i[a:a + step]), dtype=np.float64)
        out[:, a:a + step] = np.moveaxis(v, -1, 0)
    below = (o[..., 2] <= 0) | (i[..., 2] <= 0)
    out[:, below] = below_horizon
    return out


# --------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------
def read_merl(path):
    """Read a MERL ``.binary`` file -> (3, 90, 90, 180) float64 scaled BRDF (module docstring for
    the format and the validation; errors are :class:`InputError` naming the file)."""
    path = Path(path)
    where = str(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("MERL file not found", where=where) from None
    except OSError as e:
        raise InputError(f"cannot read MERL file ({e.strerror or e})", where=where) from None
    if len(raw) < _HEADER:
        raise InputError(f"not a MERL BRDF file: {len(raw)} bytes, shorter than the 12-byte header", where=where)
    dims = np.frombuffer(raw, dtype="<i4", count=3)
    if tuple(int(d) for d in dims) != SHAPE:
        raise InputError(f"MERL dimensions {tuple(int(d) for d in dims)} do not match the expected {SHAPE}",
                         where=where)
    n_bytes = len(raw) - _HEADER
    expect = 3 * N_CELLS * 8
    if n_bytes != expect:
        raise InputError(f"MERL data size mismatch: {n_bytes} bytes after the header, expected {expect} "
                         f"(3 x 90 x 90 x 180 float64)", where=where)
    data = np.frombuffer(raw, dtype="<f8", offset=_HEADER).reshape((3,) + SHAPE)
    finite = np.isfinite(data)
    if not finite.all():
        bad = np.argwhere(~finite)[0]
        raise InputError(f"MERL data contains {int((~finite).sum())} NaN/infinite values "
                         f"(first at channel {bad[0]}, cell {tuple(int(b) for b in bad[1:])})", where=where)
    neg = data < 0
    if neg.any():
        inside = neg & ~horizon_cells()[None]
        if inside.any():
            bad = np.argwhere(inside)[0]
            raise InputError(f"MERL data contains {int(inside.sum())} negative values above the horizon "
                             f"(first {data[tuple(bad)]:.4g} at channel {bad[0]}, cell "
                             f"{tuple(int(b) for b in bad[1:])})", where=where)
        data = np.where(neg, 0.0, data)
    return data * SCALE[:, None, None, None]


def write_merl(path, table):
    """Write a (3, 90, 90, 180) scaled table as a MERL ``.binary`` file (atomically: temporary file
    in the same folder, then ``os.replace``). Values are divided by the channel scales."""
    table = np.asarray(table, dtype=np.float64)
    if table.shape != (3,) + SHAPE:
        raise InputError(f"expected a (3, 90, 90, 180) table, got shape {table.shape}", where=str(path))
    path = Path(path)
    raw = (table / SCALE[:, None, None, None]).astype("<f8")
    with atomic_output(path) as tmp, open(tmp, "wb") as fh:
        fh.write(np.asarray(SHAPE, dtype="<i4").tobytes())
        fh.write(raw.tobytes())
    return path

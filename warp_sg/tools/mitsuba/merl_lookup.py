r"""MERL measured BRDFs for the Mitsuba peer: the file read and looked up as MERL's own reader does.

Written from the format's published reader (Matusik et al. 2003, ``BRDFRead.cpp`` of the MERL BRDF
database), not from the renderer's ``warp_sg.brdf.merl``: three int32 sizes (90, 90, 180), then
``90·90·180`` float64 values per channel (R, G, B blocks), scaled by (1, 1.15, 1.66)/1500.
A direction pair is turned into Rusinkiewicz half/difference angles — ``h = (o + i)/‖o + i‖``,
``θh = acos(hz)``, ``φh = atan2(hy, hx)``; ``d`` = ``i`` turned by ``−φh`` about the normal, then
by ``−θh`` about the binormal; ``θd = acos(dz)``, ``φd = atan2(dy, dx)`` — and looked up in the
nearest cell: ``θh`` index ``⌊√(θh/(π/2) · 90 · 90)⌋``, ``θd`` index ``⌊θd/(π/2) · 90⌋``, ``φd``
index ``⌊(φd mod π)/π · 180⌋`` (reciprocity folds φd onto [0, π)), each clamped to its range.
Values below zero (the database marks missing cells with −1) count as zero.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

N_TH, N_TD, N_PD = 90, 90, 180
SCALE = (1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0)


def read_merl_file(path) -> np.ndarray:
    """The file's values as float64 ``(3, 90·90·180)`` (R, G, B), unscaled."""
    raw = Path(path).read_bytes()
    dims = np.frombuffer(raw[:12], dtype="<i4")
    n = int(np.prod(dims))
    if tuple(int(x) for x in dims) != (N_TH, N_TD, N_PD) or len(raw) != 12 + 3 * n * 8:
        raise ValueError(f"{path}: not a MERL .binary BRDF (sizes {dims.tolist()}, {len(raw)} bytes)")
    return np.frombuffer(raw[12:], dtype="<f8").reshape(3, n)


def merl_brdf(p: dict):
    """A BRDF function ``f(p, o, i)`` (as :data:`warp_sg.tools.mitsuba.formulas.MODELS`) of the MERL
    file ``p["path"]`` (an absolute path)."""
    import drjit as dr
    import mitsuba as mi

    vals = read_merl_file(p["path"])
    table = np.maximum(vals, 0.0) * np.asarray(SCALE)[:, None]
    flat = table.astype(np.float32).ravel()
    n = N_TH * N_TD * N_PD
    if dr.is_jit_v(mi.Float):  # vectorised variants: one gather per channel
        data = mi.Float(flat)

        def get(idx):
            return dr.gather(mi.Float, data, idx)
    else:  # scalar variant: one lookup

        def get(idx):
            return float(flat[int(idx)])

    def rotate(v, axis, ang):
        c, s = dr.cos(ang), dr.sin(ang)
        return v * c + axis * dr.dot(axis, v) * (1.0 - c) + dr.cross(axis, v) * s

    def f(_p, o, i):
        h = dr.normalize(o + i)
        th = dr.acos(dr.clip(h.z, -1.0, 1.0))
        ph = dr.atan2(h.y, h.x)
        d = rotate(i, mi.Vector3f(0, 0, 1), -ph)
        d = rotate(d, mi.Vector3f(0, 1, 0), -th)
        td = dr.acos(dr.clip(d.z, -1.0, 1.0))
        pd = dr.atan2(d.y, d.x)
        pd = dr.select(pd < 0.0, pd + math.pi, pd)
        ith = mi.Int32(dr.sqrt(dr.maximum(th, 0.0) / (0.5 * math.pi) * N_TH * N_TH))
        itd = mi.Int32(td / (0.5 * math.pi) * N_TD)
        ipd = mi.Int32(pd / math.pi * N_PD)
        ith = dr.clip(ith, 0, N_TH - 1)
        itd = dr.clip(itd, 0, N_TD - 1)
        ipd = dr.clip(ipd, 0, N_PD - 1)
        idx = mi.UInt32(ipd + itd * N_PD + ith * N_PD * N_TD)
        return mi.Color3f(get(idx), get(idx + n), get(idx + 2 * n))

    return f


__all__ = ["read_merl_file", "merl_brdf", "SCALE"]

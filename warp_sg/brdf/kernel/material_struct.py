"""The kernel-side material record: the ``Material`` ``@wp.struct``, its Fresnel codes, and
:func:`pack_materials` (BRDF models → a :class:`MaterialTable` on a device). Part of the BRDF
contract of :mod:`warp_sg.brdf.kernel.material_wp`, which re-exports every name; the ``@wp.func``s that
read the struct are in :mod:`~warp_sg.brdf.kernel.material_eval_wp` and :mod:`~warp_sg.brdf.kernel.material_sample_wp`.
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func / struct annotations.
import math

import numpy as np
import warp as wp

from ...core.errors import InputError
from ...sg import EPSILON
from ..fitting.fit import is_anisotropic as _is_anisotropic
from ..registry import analytic_codes

FRESNEL_NONE = wp.constant(0)
FRESNEL_SCHLICK = wp.constant(1)
FRESNEL_DIELECTRIC = wp.constant(2)
FRESNEL_CONDUCTOR = wp.constant(3)

PI = wp.constant(3.141592653589793)
INV_PI = wp.constant(0.3183098861837907)
TWO_PI = wp.constant(6.283185307179586)
#: ln ε of the anisotropic construction (supplement eq. 14; ε: :data:`warp_sg.sg.EPSILON`)
LN_EPS = wp.constant(math.log(EPSILON))
#: grazing guard of the spherical warp (|pD·o| ≥ 1e-4)
WARP_COS_EPS = wp.constant(1.0e-4)

@wp.struct
class Material:
    model: int
    kd: wp.vec3
    ks: wp.vec3
    params: wp.vec4
    fresnel_kind: int
    fresnel_a: wp.vec3
    fresnel_b: wp.vec3
    lobe_start: int
    lobe_count: int
    table_index: int
    data_offset: int
    analytic: int
    lobe_axis: wp.array(dtype=wp.vec3)
    lobe_sharpness: wp.array(dtype=float)
    lobe_amplitude: wp.array(dtype=float)
    merl_data: wp.array(dtype=float)
    mo_tables: wp.array3d(dtype=float)
    #: the environment-specular energy correction (``warp_sg.brdf.kernel.albedo``): entries of this
    #: material in the shared ``albedo`` array, layout ``albedo_kind`` / ``albedo_nq`` (0: none)
    #: and the range of its textured first parameter as ``albedo_q0 = ln q0``,
    #: ``albedo_q1 = 1/ln(q1/q0)``
    albedo: wp.array(dtype=wp.vec3)
    albedo_offset: int
    albedo_nq: int
    albedo_kind: int
    albedo_q0: float
    albedo_q1: float


# ------------------------------------------------------------------------------------------------
# packing
# ------------------------------------------------------------------------------------------------
class MaterialTable:
    """Kernel-side materials: ``materials`` (wp.array(Material)) plus the shared tables
    ``lobe_axis``, ``lobe_sharpness``, ``lobe_amplitude``, ``merl_data``, ``mo_tables`` (also
    referenced from every Material) and ``records`` (the python dicts)."""

    def __init__(self, materials, lobe_axis, lobe_sharpness, lobe_amplitude, merl_data, mo_tables, records, device,
                 structs=()):
        self.materials = materials
        self.structs = list(structs)  # the Material structs behind ``materials`` (``rebuild``)
        self.lobe_axis = lobe_axis
        self.lobe_sharpness = lobe_sharpness
        self.lobe_amplitude = lobe_amplitude
        self.merl_data = merl_data
        self.mo_tables = mo_tables
        self.records = records
        self.device = device

    @property
    def models(self) -> tuple:
        """The sorted model codes of the table (the kernel variant's ``shading.kernel.Features.models``)."""
        return tuple(sorted({int(r["model"]) for r in self.records}))

    def __len__(self):
        return len(self.records)

    def rebuild(self):
        """Copy ``structs`` (edited fields, e.g. ``warp_sg.brdf.kernel.albedo.attach``) to ``materials``."""
        if self.structs:
            self.materials = wp.array(self.structs, dtype=Material, device=self.device)


def material_lobes(model, n_lobes=1, method="analytic"):
    """NDF lobes stored in the table for ``model``: (axes (K,3), sharpness (K,), amplitude (K,))."""
    if not model.is_specular:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0)
    return model.table_lobes(n_lobes, method)  # the model's hook (base.SpecularBRDF.table_lobes)


def pack_materials(models, n_lobes=1, device="cpu", method="analytic"):
    """Pack BRDF models into a :class:`MaterialTable` on ``device``.

    ``n_lobes``: NDF lobes per isotropic model (an int, or one per model); models with their own
    count (Ashikhmin–Shirley ``lobes``, measured ``lobes``, Lafortune) keep theirs. ``method``:
    "analytic" (in-kernel lobes from the parameters, textured parameters allowed) or "fit"
    (nonlinear fits stored in the table)."""
    from ...core.device import resolve_device

    device = resolve_device(device)
    models = list(models)
    if method not in ("analytic", "fit"):
        raise InputError(f"unknown fit method '{method}' (use analytic or fit)", where="method")
    if isinstance(n_lobes, (list, tuple, np.ndarray)):
        if len(n_lobes) != len(models):
            raise InputError(f"expected {len(models)} lobe counts, got {len(n_lobes)}", where="n_lobes")
        counts = [int(n) for n in n_lobes]
    else:
        counts = [int(n_lobes)] * len(models)
    for n in counts:
        if n < 1:
            raise InputError(f"must be >= 1, got {n}", where="n_lobes")
    axes_all, lam_all, amp_all, merl_parts, mo_parts, records = [], [], [], [], [], []
    start = 0
    merl_off = 0
    for model, n in zip(models, counts):
        rec = dict(model.material_record())
        ax, lam, amp = material_lobes(model, n, method)
        ax = np.asarray(ax, np.float64).reshape(-1, 3)
        rec["lobe_start"] = start
        rec["lobe_count"] = len(lam)
        # in-kernel lobes only where they equal the numpy analytic construction: one isotropic
        # lobe, or the anisotropic construction (multi-lobe isotropic "analytic" falls back to fits)
        aniso = _is_anisotropic(model)
        rec["analytic"] = 1 if (method == "analytic" and rec["model"] in analytic_codes()
                                and (aniso or len(lam) == 1)) else 0
        rec["anisotropic"] = bool(aniso)
        table = model.kernel_lobe_table(method) if hasattr(model, "kernel_lobe_table") else None
        if table is not None:  # GGX: the node table itself; the kernel interpolates it at the texel's α
            lam, amp = table
            ax = np.tile([0.0, 0.0, 1.0], (len(lam), 1))
            rec["analytic"] = 1
        start += len(lam)
        axes_all.append(ax)
        lam_all.append(np.asarray(lam, np.float64).reshape(-1))
        amp_all.append(np.asarray(amp, np.float64).reshape(-1))
        if hasattr(model, "merl_table"):
            data = np.asarray(model.merl_table(), np.float32).reshape(-1)
            rec["data_offset"] = merl_off
            merl_parts.append(data)
            merl_off += len(data)
        if hasattr(model, "mo_table"):
            tab = np.asarray(model.mo_table(), np.float32)
            if tab.ndim != 2:
                raise InputError(f"mo_table() must be 2-D, got shape {tab.shape}", where="measured")
            rec["table_index"] = len(mo_parts)
            mo_parts.append(tab)
        records.append(rec)

    def cat(parts, shape):
        return np.concatenate(parts) if parts and sum(len(p) for p in parts) else np.zeros(shape)

    lobe_axis = wp.array(cat(axes_all, (1, 3)).astype(np.float32), dtype=wp.vec3, device=device)
    lobe_sharp = wp.array(cat(lam_all, (1,)).astype(np.float32), dtype=float, device=device)
    lobe_amp = wp.array(cat(amp_all, (1,)).astype(np.float32), dtype=float, device=device)
    merl = wp.array(np.concatenate(merl_parts) if merl_parts else np.zeros(1, np.float32), dtype=float, device=device)
    if mo_parts:
        shapes = {p.shape for p in mo_parts}
        if len(shapes) != 1:
            raise InputError(f"all mo_table() shapes must agree, got {sorted(shapes)}", where="measured")
        mo = wp.array(np.stack(mo_parts), dtype=float, device=device)
    else:
        mo = wp.zeros((1, 1, 1), dtype=float, device=device)

    structs = []
    no_albedo = wp.ones(1, dtype=wp.vec3, device=device)
    for rec in records:
        s = Material()
        s.model = int(rec["model"])
        s.kd = wp.vec3(*rec["kd"])
        s.ks = wp.vec3(*rec["ks"])
        s.params = wp.vec4(*rec["params"])
        s.fresnel_kind = int(rec["fresnel_kind"])
        s.fresnel_a = wp.vec3(*rec["fresnel_a"])
        s.fresnel_b = wp.vec3(*rec["fresnel_b"])
        s.lobe_start = int(rec["lobe_start"])
        s.lobe_count = int(rec["lobe_count"])
        s.table_index = int(rec.get("table_index", 0))
        s.data_offset = int(rec.get("data_offset", 0))
        s.analytic = int(rec["analytic"])
        s.lobe_axis = lobe_axis
        s.lobe_sharpness = lobe_sharp
        s.lobe_amplitude = lobe_amp
        s.merl_data = merl
        s.mo_tables = mo
        s.albedo = no_albedo
        s.albedo_offset, s.albedo_nq, s.albedo_kind, s.albedo_q0, s.albedo_q1 = 0, 0, 0, 0.0, 0.0
        structs.append(s)
    if structs:
        mats = wp.array(structs, dtype=Material, device=device)
    else:
        mats = wp.empty(0, dtype=Material, device=device)
    return MaterialTable(mats, lobe_axis, lobe_sharp, lobe_amp, merl, mo, records, device, structs)


__all__ = ["Material", "MaterialTable", "material_lobes", "pack_materials"]

r"""Measured BRDFs (paper §4.2, supplement §4): a general microfacet model fitted to a MERL table,
then an SG mixture fitted to its NDF.

Model (paper eq. 13–14, Wang et al. 2008; Ngan et al. 2005)::

    ρ(o, i) = kd/π + ks ∘ ρs(o, i),
    ρs(o, i) = F(|i·h|)/F(1) · S(θo) S(θi) / (π cos θo cos θi) · D(h) = Mo(o, i) · D(h)

* ``F`` — Cook–Torrance Fresnel of paper eq. 14 with relative index of refraction ``eta``
  (paper: constant η = 1.33), divided by its value at normal incidence so that ``ks`` is the
  specular scale at normal incidence (this only rescales ``ks``; it is eq. 14 otherwise).
* ``S`` — an isotropic 1-D shadowing factor (paper: "we constrain the shadowing factor to be
  isotropic"), tabulated on 90 nodes ``θ_a = a/89 · π/2`` (``S(0) = 1``) and PCA-compressed
  90-D → ``pca_terms``-D (paper: 8-D) against a basis learnt from a family of physical shadowing
  curves (Smith G1 for Beckmann and GGX roughness 0.005..3, see :func:`shadowing_basis`).
* ``D`` — the NDF, tabulated on the 90 θh bins of the MERL table (``D(first bin) = 1``), then fitted by
  an SG mixture ``D*(h) = Σk μk exp(λk (h·z − 1))`` with 1–2 lobes about z+ by Levenberg–Marquardt
  (``scipy.optimize.least_squares(method="lm")``, solid-angle weights of the θh bins), lobes
  sorted by increasing sharpness (paper §4.2). :func:`fit_ndf_sg_anisotropic` fits lobes with free
  axes by L-BFGS-B (anisotropic NDFs; MERL data are isotropic).

Fit of (kd, ks, S, D) — vectorized over the MERL cells, alternating 3 times:

1. with ``kd`` fixed, ``y = (Σc ρc − Σc kdc/π) · π cos θi cos θo / F`` satisfies
   ``log y = log(ks D(θh)) + log S(θi) + log S(θo)``: linear least squares in the 180 unknowns
   ``log D[bin]``, ``log S[node]`` (S linear between nodes), weighted by
   ``J · ((ρ − kd/π) cos θi cos θo)²`` so the log residual approximates the absolute residual of
   supplement eq. 11; ``J = cos θd sin θd sin θh · √(θh/(π/2))`` is the measure of a cell
   (``dωi dωo = 4 cos θd dωh dωd``; √θh spacing). A small second-difference penalty regularises
   bins/nodes with little data. Normal equations are accumulated with ``np.bincount``.
2. with the shape ``Φ = F S S D/(π cos cos)`` fixed, ``kd``, ``ks`` per channel by weighted linear
   least squares (``kd ≥ 0``).

``kd`` starts at π × the 5th percentile of the data over well-lit cells. Cells with
``min(cos θi, cos θo) < 0.05`` are left out.

Errors (:meth:`Measured.errors`) use supplement eq. 11 over the MERL cells (measure ``J``)::

    E = Σ (ρ − ρ^R)² (cos θi cos θo)² / Σ (ρ cos θi cos θo)²

for the full BRDF (``ρ`` the data) and the approximations ``microfacet`` (tabulated D and S),
``sg`` (SG NDF) and ``sg_pca`` (SG NDF and PCA-compressed S: what the renderer uses).

The microfacet fit and the PCA are cached with :func:`warp_sg.core.cache.load_or_build` (kind
``measured_fit``, keyed by the table's content hash, ``eta`` and ``pca_terms``); the SG fit of the
NDF (milliseconds) is redone for each lobe count.

Kernel side: ``brdf_eval`` is the data itself (``merl_eval``), ``Mo`` the PCA-compressed shadowing
table (``measured_mo``), the NDF and its sampling the SG mixture of the lobe table
(``1 − cos θ = −log1p(−u (1 − e^{−2λ}))/λ``, one lobe drawn by its weight).

Files: this module holds the model class :class:`Measured` and the report; the fit itself is in
:mod:`warp_sg.brdf.fitting.measured_fit` (re-exported here).
"""
# NOTE: no ``from __future__ import annotations`` — Warp reads the @wp.func annotations.
import hashlib
from pathlib import Path

import numpy as np
import warp as wp

from ...core.cache import content_key, load_or_build
from ...core.errors import InputError
from .. import merl
from ..base import SpecularBRDF, as_scalar, dirs, half_vector, upper
from ..fitting.measured_fit import (  # noqa: F401  (the fit, re-exported)
    COS_MIN,
    D_SOLID_ANGLE,
    D_THETA,
    FIT_VERSION,
    N_S,
    S_THETA,
    _cell_geometry,
    _hat,
    _interp_S,
    compress_shadowing,
    eq11,
    fit_microfacet,
    fit_ndf_sg,
    fit_ndf_sg_anisotropic,
    sg_mixture,
    shadowing_basis,
)
from ..fresnel import fresnel_eq14, fresnel_normalised  # noqa: F401  (eq. 14, normalised at normal incidence)
from ..kernel.material_sample_wp import cosine_dir, reflect_about, sg_lobe_weight, sg_mixture_pdf, sg_sample_dir
from ..kernel.material_struct import Material
from ..kernel.measured_wp import measured_mo, merl_eval
from ..params import Param
from ..registry import Kernel, register


@wp.func
def measured_ndf(mat: Material, h: wp.vec3) -> float:
    """The NDF SG mixture of the lobe table."""
    d = float(0.0)
    for k in range(mat.lobe_count):
        j = mat.lobe_start + k
        a = mat.lobe_axis[j]
        dd = h - a
        d += mat.lobe_amplitude[j] * wp.exp(-mat.lobe_sharpness[j] * 0.5 * wp.dot(dd, dd))
    return d


@wp.func
def measured_mo_of(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    return measured_mo(mat.mo_tables, mat.table_index, mat.fresnel_a, o, i)


@wp.func
def measured_eval(mat: Material, o: wp.vec3, i: wp.vec3) -> wp.vec3:
    """The tabulated data (zero below the horizon)."""
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0, 0.0, 0.0)
    return merl_eval(mat.merl_data, mat.data_offset, o, i)


@wp.func
def measured_sample(mat: Material, o: wp.vec3, u: wp.vec2) -> wp.vec3:
    """A half vector from the SG mixture (one lobe drawn by its weight), reflected."""
    total = float(0.0)
    for k in range(mat.lobe_count):
        total += sg_lobe_weight(mat, mat.lobe_start + k)
    if total <= 0.0:
        return cosine_dir(u)
    t = u[0] * total
    chosen = mat.lobe_start
    acc = float(0.0)
    lo = float(0.0)
    found = int(0)
    for k in range(mat.lobe_count):
        w = sg_lobe_weight(mat, mat.lobe_start + k)
        if found == 0 and (t < acc + w or k == mat.lobe_count - 1):
            chosen = mat.lobe_start + k
            lo = acc
            found = 1
        acc += w
    wsel = sg_lobe_weight(mat, chosen)
    uu = wp.vec2(wp.clamp((t - lo) / wp.max(wsel, 1.0e-30), 0.0, 0.99999994), u[1])
    h = sg_sample_dir(mat.lobe_axis[chosen], mat.lobe_sharpness[chosen], uu)
    return reflect_about(o, h)


@wp.func
def measured_pdf_h(mat: Material, h: wp.vec3) -> float:
    return sg_mixture_pdf(mat, h)


# --------------------------------------------------------------------------------------------
# the model class
# --------------------------------------------------------------------------------------------
@register
class Measured(SpecularBRDF):
    """A measured (MERL) BRDF with its fitted microfacet model and NDF SG mixture.

    ``Measured(file="x.binary", lobes=1, eta=1.33, pca_terms=8)`` or ``Measured(table=(3,90,90,180))``.

    * ``eval(o, i)`` — the exact data (nearest MERL cell, :func:`warp_sg.brdf.merl.merl_lookup`).
    * ``mo(o, i)`` — ``F(|i·h|)/F(1) · S(θo)S(θi)/(π cos θo cos θi)`` (without ks), S the
      PCA-compressed shadowing, bilinear in (θo, θi) from :meth:`mo_table` exactly like the kernel.
    * ``ndf(h)`` — the SG mixture ``D*`` (what the renderer uses); ``ndf_tabulated(h)`` the fitted
      table (linear in √θh).
    * ``ndf_sg(n_lobes=None, method="fit")`` — the LM fit about z+ (``n_lobes`` defaults to ``lobes``).
    * ``fitted_eval(o, i, which="sg_pca"|"sg"|"microfacet")`` — ``kd/π + ks ∘ Mo · D``.
    * ``errors()`` — supplement eq. 11 of each approximation against the data.
    * ``merl_table()`` (flat float32, R, G, B blocks) and ``mo_table()`` ((90, 90) float32 of
      ``S(θo_a) S(θi_b)``) for ``material_wp.pack_materials``.
    """

    NAME = "measured"
    CODE = 9
    KERNEL = Kernel(ndf=measured_ndf, mo=measured_mo_of, eval=measured_eval, sample=measured_sample,
                    pdf_h=measured_pdf_h)
    PARAMS = {"file": Param("file", "MERL .binary file, relative to the scene file"),
              "lobes": Param("integer", "number of SG lobes of the NDF fit", lo=1),
              "eta": Param("number", "index of refraction used for the microfacet fit", lo=0, lo_open=True),
              "pca_terms": Param("integer", "PCA terms of the shadowing fit", lo=0)}

    def __init__(self, file=None, lobes=1, eta=1.33, pca_terms=8, *, table=None, cache=True):
        if file is None and table is None:
            raise InputError("is required: a MERL .binary file (from Python, Measured(table=array) also works)",
                             where="file")
        if file is not None and table is not None:
            raise InputError("give a file or, from Python, a table, not both", where="file")
        try:
            n = int(lobes)
        except (TypeError, ValueError):
            raise InputError(f"expected a positive integer, got {lobes!r}", where="lobes") from None
        if n < 1 or n != lobes:
            raise InputError(f"must be a positive integer, got {lobes!r}", where="lobes")
        self.lobes = n
        self.own_lobes = n
        self.eta = as_scalar(eta, "eta", lo=0.0, lo_open=True)
        try:
            self.pca_terms = int(pca_terms)
        except (TypeError, ValueError):
            raise InputError(f"expected an integer, got {pca_terms!r}", where="pca_terms") from None
        if not 0 <= self.pca_terms <= N_S:
            raise InputError(f"must be in 0..{N_S}, got {pca_terms!r}", where="pca_terms")
        self.file = None if file is None else str(file)
        if file is not None:
            self.table = merl.read_merl(file)
        else:
            t = np.asarray(table, dtype=np.float64)
            if t.shape != (3,) + merl.SHAPE:
                raise InputError(f"expected shape (3, 90, 90, 180), got {t.shape}", where="table")
            if not np.all(np.isfinite(t)):
                raise InputError("table contains NaN/infinite values", where="table")
            self.table = np.maximum(t, 0.0)
        self.table.setflags(write=False)
        fit = self._fit(cache)
        self.kd = fit["kd"].copy()
        self.ks = fit["ks"].copy()
        self.ndf_table = fit["ndf"].copy()
        self.ndf_support = fit["ndf_support"].copy()
        self.shadowing = fit["shadowing"].copy()
        self.shadowing_coeffs = fit["shadowing_coeffs"].copy()
        self.shadowing_pca = fit["shadowing_pca"].copy()
        # the SG fit of the NDF is cheap (LM on 90 samples): not cached, so the cached microfacet
        # fit serves every lobe count
        self.lobe_axes, self.lobe_sharpness, self.lobe_amplitude = fit_ndf_sg(
            D_THETA, self.ndf_table, self._fit_weights(), self.lobes)
        self._mo_table = np.outer(self.shadowing_pca, self.shadowing_pca)

    # -- fitting ----------------------------------------------------------------------------
    def _fit_weights(self):
        w = D_SOLID_ANGLE * (self.ndf_support > 1e-9 * max(self.ndf_support.max(), 1e-300))
        return w

    def _build(self):
        fit = fit_microfacet(self.table, self.eta)
        coeffs, S_pca = compress_shadowing(fit["shadowing"], self.pca_terms)
        fit.update(shadowing_coeffs=coeffs, shadowing_pca=S_pca)
        return {k: np.asarray(v, dtype=np.float64) for k, v in fit.items()}

    def _fit(self, cache):
        if not cache:
            return self._build()
        digest = hashlib.sha256(np.ascontiguousarray(self.table).tobytes()).hexdigest()
        key = content_key("measured_fit", FIT_VERSION, digest, self.eta, self.pca_terms)
        return load_or_build("measured_fit", key, self._build)

    # -- contract ---------------------------------------------------------------------------
    def table_lobes(self, n_lobes=1, method="analytic"):
        """The kernel's lobe table: the fitted NDF SG mixture with the model's own lobe count."""
        return self.ndf_sg(getattr(self, "lobes", n_lobes) or n_lobes, "fit")

    def merl_table(self):
        """The scaled data as one flat float32 array: R, G, B blocks of 90·90·180 (``merl_eval``)."""
        return self.table.astype(np.float32).reshape(-1)

    def mo_table(self):
        """(90, 90) float32 ``S(θo_a) S(θi_b)`` on the nodes :data:`S_THETA` (``measured_mo``)."""
        return self._mo_table.astype(np.float32)

    def kernel_params(self):
        return (float(self.lobes), float(self.eta), 0.0, 0.0)

    def fresnel_record(self):
        return 2, (self.eta, self.eta, self.eta), (0.0, 0.0, 0.0)

    def ndf_analytic_lambda(self):
        return float(self.lobe_sharpness[np.argmax(self.lobe_amplitude)])

    @property
    def equivalent_m(self):
        """Cook–Torrance roughness of the single-lobe fit, ``m = √(2/λ)`` (paper eq. 12)."""
        _, lam, _ = self.ndf_sg(1)
        return float(np.sqrt(2.0 / lam[0]))

    # -- evaluation -------------------------------------------------------------------------
    def eval(self, o, i):
        """The measured BRDF (..., 3) by nearest-cell lookup; zero below the horizon."""
        o, i = dirs(o, i)
        return merl.merl_lookup(self.table, o, i)

    def _shadow(self, o, i, S):
        to = np.arctan2(np.hypot(o[..., 0], o[..., 1]), o[..., 2])
        ti = np.arctan2(np.hypot(i[..., 0], i[..., 1]), i[..., 2])
        if S is None:  # bilinear in the (90, 90) table, as in the kernel
            T = self._mo_table
            a0, a1, wa0, wa1 = _hat(to)
            b0, b1, wb0, wb1 = _hat(ti)
            return wa0 * (wb0 * T[a0, b0] + wb1 * T[a0, b1]) + wa1 * (wb0 * T[a1, b0] + wb1 * T[a1, b1])
        return _interp_S(S, to) * _interp_S(S, ti)

    def mo(self, o, i, shadowing=None):
        """``Mo(o, i)`` (..., 3) without ks; ``shadowing``: a (90,) S to use instead of the PCA one."""
        o, i = dirs(o, i)
        h = half_vector(o, i)
        c = np.abs(np.sum(i * h, axis=-1))
        ss = self._shadow(o, i, shadowing)
        val = fresnel_normalised(self.eta, c) * ss / (np.pi * np.maximum(o[..., 2], 1e-3) * np.maximum(i[..., 2], 1e-3))
        val = np.where(upper(o, i), val, 0.0)
        return np.repeat(val[..., None], 3, axis=-1)

    def ndf(self, h):
        """The SG mixture ``D*(h)`` of the ``lobes``-lobe fit (zero below the horizon)."""
        h = np.asarray(h, dtype=np.float64)
        return np.where(h[..., 2] > 0, sg_mixture(h, self.lobe_axes, self.lobe_sharpness, self.lobe_amplitude), 0.0)

    def ndf_tabulated(self, h):
        """The fitted NDF table, linear in √θh between bin centres."""
        h = np.asarray(h, dtype=np.float64)
        th = np.arctan2(np.hypot(h[..., 0], h[..., 1]), h[..., 2])
        u = np.sqrt(np.clip(th / (np.pi / 2), 0, 1)) * merl.N_THETA_H - 0.5
        return np.where(h[..., 2] > 0, np.interp(u, np.arange(merl.N_THETA_H), self.ndf_table), 0.0)

    def ndf_sg(self, n_lobes=None, method="fit"):
        """``(axes (K,3), λ (K,), μ (K,))``: LM fit about z+ of the tabulated NDF (``method`` is
        accepted for the common API; measured NDFs are always fitted)."""
        n = self.lobes if n_lobes is None else int(n_lobes)
        if n == self.lobes:
            return self.lobe_axes.copy(), self.lobe_sharpness.copy(), self.lobe_amplitude.copy()
        return fit_ndf_sg(D_THETA, self.ndf_table, self._fit_weights(), n)

    def specular(self, o, i):
        """``Mo · D*`` without ks (the SG approximation the renderer uses)."""
        o, i = dirs(o, i)
        return self.mo(o, i) * self.ndf(half_vector(o, i))[..., None]

    def fitted_eval(self, o, i, which="sg_pca", lobes=None):
        """``kd/π + ks ∘ Mo · D`` of an approximation: ``microfacet`` (tabulated D, full S),
        ``sg`` (SG D*, full S) or ``sg_pca`` (SG D*, PCA S — the renderer's); ``lobes``: SG lobe
        count (default ``self.lobes``)."""
        o, i = dirs(o, i)
        h = half_vector(o, i)
        if which == "microfacet":
            d = self.ndf_tabulated(h)
        elif which in ("sg", "sg_pca"):
            ax, lam, mu = self.ndf_sg(lobes)
            d = np.where(h[..., 2] > 0, sg_mixture(h, ax, lam, mu), 0.0)
        else:
            raise InputError(f"unknown approximation '{which}' (microfacet, sg, sg_pca)", where="which")
        mo = self.mo(o, i) if which == "sg_pca" else self.mo(o, i, self.shadowing)
        val = self.kd / np.pi + self.ks * (mo * d[..., None])
        return np.where(upper(o, i)[..., None], val, 0.0)

    def errors(self, lobes=None):
        """Supplement eq. 11 (all channels, MERL cells, full BRDF) of each approximation:
        ``{"microfacet": .., "sg": .., "sg_pca": ..}`` (``lobes``: SG lobe count, default ``self.lobes``)."""
        g = _cell_geometry()
        o, i = merl.cell_directions()
        O = o.reshape(-1, 3)[g["idx"]]
        I = i.reshape(-1, 3)[g["idx"]]
        data = self.table.reshape(3, -1)[:, g["idx"]]
        out = {}
        for which in ("microfacet", "sg", "sg_pca"):
            approx = self.fitted_eval(O, I, which, lobes).T
            out[which] = eq11(data, approx)
        return out

    def __repr__(self):
        src = self.file if self.file else "<table>"
        return f"Measured(file={src!r}, lobes={self.lobes}, eta={self.eta}, pca_terms={self.pca_terms})"


def fit_file(path, lobes=1, eta=1.33, pca_terms=8):
    """Convenience: ``Measured(file=path, ...)``."""
    return Measured(file=Path(path), lobes=lobes, eta=eta, pca_terms=pca_terms)


# --------------------------------------------------------------------------------------------
# report (docs/measured.md): python -m warp_sg.brdf.models.measured [OUT_DIR]
# --------------------------------------------------------------------------------------------
def synthetic_materials():
    """Analytic BRDFs standing in for MERL measurements (no downloads): name -> (model, note)."""
    from .microfacet import CookTorrance, TorranceSparrow
    from .phong import BlinnPhong
    from .ward import Ward

    return {
        "ct_m0.05": CookTorrance(kd=(0.02, 0.02, 0.02), ks=(30, 25, 20), m=0.05, fresnel={"eta": 1.33}),
        "ct_m0.1": CookTorrance(kd=(0.1, 0.05, 0.02), ks=(20, 25, 30), m=0.1, fresnel={"eta": 1.33}),
        "ct_m0.2": CookTorrance(kd=(0.1, 0.05, 0.02), ks=(20, 25, 30), m=0.2, fresnel={"eta": 1.33}),
        "ct_m0.4": CookTorrance(kd=(0.2, 0.2, 0.2), ks=(20, 20, 20), m=0.4, fresnel={"eta": 1.33}),
        "ts_m0.15": TorranceSparrow(kd=(0.3, 0.1, 0.1), ks=(1.0, 1.0, 1.0), m=0.15, fresnel={"eta": 1.5}),
        "ward_a0.12": Ward(kd=(0.05, 0.1, 0.2), ks=(0.3, 0.3, 0.3), alpha=0.12),
        "blinn_phong_n200": BlinnPhong(kd=(0.2, 0.2, 0.1), ks=(0.6, 0.6, 0.6), n=200),
    }


def error_table(models, lobes=(1, 2), eta=1.33, pca_terms=8):
    """Rows ``{material, lobes, kd.., ks.., lambda, m_equiv, err_microfacet, err_sg, err_sg_pca}``
    for named BRDF models (or (3,90,90,180) tables) tabulated as MERL tables and fitted."""
    rows = []
    for name, model in models.items():
        table = model if isinstance(model, np.ndarray) else merl.tabulate(model)
        meas = Measured(table=table, lobes=1, eta=eta, pca_terms=pca_terms)
        for k in lobes:
            e = meas.errors(k)
            _, lam, mu = meas.ndf_sg(k)
            rows.append(dict(material=name, lobes=k, kd=" ".join(f"{v:.3f}" for v in meas.kd),
                             ks=" ".join(f"{v:.3f}" for v in meas.ks),
                             sharpness=" ".join(f"{v:.1f}" for v in lam),
                             amplitude=" ".join(f"{v:.3f}" for v in mu),
                             err_microfacet=e["microfacet"], err_sg=e["sg"], err_sg_pca=e["sg_pca"]))
    return rows


def plot_fit(meas, path=None, ax=None, lobes=(1, 2), title=None):
    """NDF table and its SG fits against θh (and the shadowing S, full and PCA) — matplotlib."""
    import matplotlib.pyplot as plt

    own = ax is None
    if own:
        fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    th = np.degrees(D_THETA)
    ax[0].semilogy(th, np.maximum(meas.ndf_table, 1e-6), "k.", ms=3, label="fitted NDF table")
    for k in lobes:
        a, lam, mu = meas.ndf_sg(k)
        d = (mu * np.exp(-lam * (1 - np.cos(D_THETA))[:, None])).sum(-1)
        ax[0].semilogy(th, np.maximum(d, 1e-6), label=f"{k} SG lobe{'s' if k > 1 else ''}")
    ax[0].set_ylim(1e-4, 2)
    ax[0].set_xlabel("θh (degrees)")
    ax[0].set_title(title or "NDF D(θh)")
    ax[0].legend(fontsize=8)
    ax[1].plot(np.degrees(S_THETA), meas.shadowing, "k-", label="S (90-D)")
    ax[1].plot(np.degrees(S_THETA), meas.shadowing_pca, "r--", label=f"S PCA ({meas.pca_terms}-D)")
    ax[1].set_xlabel("θ (degrees)")
    ax[1].set_title("shadowing S(θ)")
    ax[1].legend(fontsize=8)
    if own:
        fig.tight_layout()
        if path:
            fig.savefig(path, dpi=110)
            plt.close(fig)
    return ax


def _main(out_dir):
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mats = synthetic_materials()
    rows = error_table(mats)
    with open(out / "measured_errors.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.3e}" if isinstance(v, float) else v) for k, v in r.items()})
    names = ["ct_m0.1", "ts_m0.15", "blinn_phong_n200"]
    fig, axs = plt.subplots(len(names), 2, figsize=(9, 3.0 * len(names)))
    for r, name in enumerate(names):
        plot_fit(Measured(table=merl.tabulate(mats[name]), lobes=1), ax=axs[r], title=f"{name}: NDF")
    fig.tight_layout()
    fig.savefig(out / "measured_fit.png", dpi=110)
    plt.close(fig)
    for r in rows:
        print(f"| {r['material']} | {r['lobes']} | {r['sharpness']} | {r['err_microfacet']:.2e} | "
              f"{r['err_sg']:.2e} | {r['err_sg_pca']:.2e} |")


if __name__ == "__main__":
    import sys

    _main(sys.argv[1] if len(sys.argv) > 1 else "docs/figures")

r"""Anisotropic reflectance with N-lobe SG mixtures: error against N (supplement §3, Fig. 5–6).

Two anisotropic models, Ashikhmin–Shirley (supplement eq. 12–13) and anisotropic Ward
(lecture; supplement eq. 4–6 with ``αx ≠ αy``), their NDFs approximated by N SG lobes
(odd N; the construction of supplement eq. 14 — ``method="analytic"`` — or the L-BFGS-B fit of
:func:`warp_sg.brdf.fitting.fit.fit_anisotropic` started from it — ``method="fit"``). Three errors:

* ``ndf``: supplement eq. 11 of ``Mo(o, i) · D*(h)`` against ``ρs`` over all (o, i)
  (:func:`warp_sg.brdf.fitting.fit.fit_error`; what supplement Fig. 5c plots);
* ``slice``: eq. 11 of the warped slice (paper eq. 17–22, :func:`warp_sg.brdf.slice_lobes_numpy`)
  against ``ρs(o, ·)`` for a fixed set of view directions — adds the spherical-warp error;
* ``render``: a rendered sphere (orthographic view along z, tangent = ``(0, 1, 0) × n``) lit by one SG
  light ``G(i; l, λL, 1)``: ``R(x) = ∫ ks ρs(o, i) cos θi L(i) di`` by the same quadrature for the
  exact BRDF and for the SG slice, relative squared image error ``Σ (R − R*)² / Σ R²`` (Fig. 6 style).

:func:`study` tabulates all three for N = 1, 3, …, 15; ``scripts/anisotropic_error.py`` writes
``docs/figures/aniso_error.csv`` and ``aniso_error.png``.
"""
from __future__ import annotations

import numpy as np

from warp_sg.brdf import AshikhminShirley, Ward, slice_lobes_numpy
from warp_sg.brdf.fitting.fit import fit_error

#: default models of the study
DEFAULT_MODELS = {
    "ashikhmin_shirley": dict(nu=20.0, nv=400.0),
    "ward": dict(alpha_x=0.3, alpha_y=0.06),
}


def make(name, n_lobes, **params):
    """The model ``name`` (``ashikhmin_shirley`` | ``ward``) set up for ``n_lobes`` NDF lobes."""
    p = dict(DEFAULT_MODELS[name])
    p.update(params)
    if name == "ashikhmin_shirley":
        return AshikhminShirley(ks=1.0, lobes=int(n_lobes), **p)
    if name == "ward":
        return Ward(ks=1.0, **p)
    raise ValueError(f"unknown anisotropic model {name!r}")


def ndf_error(model, n_lobes, method="analytic", **quadrature):
    """Supplement eq. 11 of ``Mo · D*`` (N-lobe NDF) against ``ρs`` (``quadrature``: ``n_o``,
    ``n_phi_o``, ``n_th``, ``n_ph`` of :func:`warp_sg.brdf.fitting.fit.eq11_error`)."""
    return fit_error(model, n_lobes, method, **quadrature)


def _hemisphere(n_theta, n_phi, theta_max=np.pi / 2):
    t = (np.arange(n_theta) + 0.5) / n_theta
    th = theta_max * t
    ph = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(TH) * np.cos(PH), np.sin(TH) * np.sin(PH), np.cos(TH)], -1).reshape(-1, 3)
    w = (np.sin(TH) * theta_max / n_theta * 2 * np.pi / n_phi).reshape(-1)
    return d, w


def slice_error(model, n_lobes, method="analytic", views=((20, 0), (45, 30), (60, 90), (70, 135)), res=(160, 160)):
    """Eq. 11 of the warped SG slice against ``ρs(o, ·)`` summed over ``views`` (θo, φo in degrees),
    i on a (θ, φ) grid of ``res`` over the hemisphere (green channel)."""
    i, wi = _hemisphere(*res)
    num = den = 0.0
    for tdeg, pdeg in views:
        t, p = np.radians(tdeg), np.radians(pdeg)
        o = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
        ax, lam, amp = slice_lobes_numpy(model, o, n_lobes, method)
        d = i[:, None, :] - ax
        approx = np.sum(np.exp(-lam * 0.5 * np.sum(d * d, -1)) * amp[:, 1], -1)
        exact = model.specular(np.broadcast_to(o, i.shape), i)[:, 1]
        cc = (i[:, 2] * o[2]) ** 2
        num += np.sum(wi * cc * (exact - approx) ** 2)
        den += np.sum(wi * cc * exact**2)
    return float(num / den)


def sphere_frames(res):
    """Pixels of an orthographic sphere image: (mask (res, res), n, t, b (m, 3))."""
    c = (np.arange(res) + 0.5) / res * 2 - 1
    X, Y = np.meshgrid(c, -c)
    r2 = X * X + Y * Y
    mask = r2 < 0.97
    n = np.stack([X[mask], Y[mask], np.sqrt(1 - r2[mask])], -1)
    t = np.cross([0.0, 1.0, 0.0], n)
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    b = np.cross(n, t)
    return mask, n, t, b


def render_sphere(model, n_lobes=None, method="analytic", res=48, light=(0.5, 0.6, 0.62), light_sharpness=150.0,
                  quad=(24, 48)):
    """Specular radiance (res, res) (green) of a sphere under one SG light; ``n_lobes=None``: exact
    BRDF, else the N-lobe warped SG slice. The light integral uses the same quadrature (a cap of
    angle θL around the light axis, ``exp(−λL (1 − cos θL)) = 1e-6``) for both."""
    mask, n, t, b = sphere_frames(res)
    l = np.asarray(light, float)
    l /= np.linalg.norm(l)
    theta_l = np.arccos(max(-1.0, 1 + np.log(1e-6) / light_sharpness))
    dl, wl = _hemisphere(quad[0], quad[1], theta_l)
    # rotate the cap around z to the light axis
    lt = np.cross([0.0, 0.0, 1.0], l) if abs(l[2]) < 0.999 else np.array([1.0, 0, 0])
    lt /= np.linalg.norm(lt)
    lb = np.cross(l, lt)
    iw = dl[:, :1] * lt + dl[:, 1:2] * lb + dl[:, 2:] * l
    L = np.exp(light_sharpness * (iw @ l - 1.0)) * wl
    ow = np.array([0.0, 0.0, 1.0])
    o = np.stack([t @ ow, b @ ow, n @ ow], -1)  # (m, 3) local view
    il = np.stack([iw @ t.T, iw @ b.T, iw @ n.T], -1)  # (q, m, 3) local light dirs
    cos_i = np.maximum(il[..., 2], 0.0)
    if n_lobes is None:
        f = model.specular(np.broadcast_to(o, il.shape), il)[..., 1]
    else:
        ax, lam, amp = slice_lobes_numpy(model, o, n_lobes, method)  # (m, K, ...)
        d = il[..., None, :] - ax[None]
        f = np.sum(np.exp(-lam[None] * 0.5 * np.sum(d * d, -1)) * amp[None, ..., 1], -1)
    f = np.where(il[..., 2] > 0, f, 0.0)
    img = np.zeros((res, res))
    img[mask] = np.sum(f * cos_i * L[:, None], 0) * np.asarray(model.ks)[1]
    return img


def render_error(model, n_lobes, method="analytic", exact=None, **kw):
    """Relative squared image error ``Σ (R − R*)² / Σ R²`` of :func:`render_sphere`."""
    ref = render_sphere(model, None, **kw) if exact is None else exact
    img = render_sphere(model, n_lobes, method, **kw)
    return float(np.sum((ref - img) ** 2) / np.sum(ref**2))


def study(lobes=range(1, 16, 2), methods=("analytic", "fit"), models=("ashikhmin_shirley", "ward"),
          res=48, slice_res=(160, 160)):
    """Rows ``{model, method, lobes, ndf_error, slice_error, render_error}`` for every combination."""
    rows = []
    for name in models:
        exact = render_sphere(make(name, 1), None, res=res)
        for method in methods:
            for n in lobes:
                m = make(name, n)
                rows.append(dict(model=name, method=method, lobes=int(n),
                                 ndf_error=ndf_error(m, n, method),
                                 slice_error=slice_error(m, n, method, res=slice_res),
                                 render_error=render_error(m, n, method, exact=exact, res=res)))
    return rows


def write_csv(rows, path):
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6e}" if isinstance(v, float) else v) for k, v in r.items()})


def plot(rows, path, images=None):
    """Error vs N (log scale), one panel per error kind; optional sphere images row."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = ("ndf_error", "slice_error", "render_error")
    titles = ("NDF fit (supp. eq. 11)", "warped slice (eq. 11)", "rendered sphere (rel. sq. error)")
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, k, title in zip(axs, kinds, titles):
        for name in dict.fromkeys(r["model"] for r in rows):
            for method, style in (("analytic", "--o"), ("fit", "-s")):
                rr = [r for r in rows if r["model"] == name and r["method"] == method]
                if rr:
                    ax.semilogy([r["lobes"] for r in rr], [r[k] for r in rr], style, ms=4,
                                label=f"{name} ({method})")
        ax.set_xlabel("SG lobes N")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axs[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

"""scripts/supplement_figures.py (quick mode) writes the four figures and their trends hold."""
from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "supplement_figures.py"


def _load():
    spec = importlib.util.spec_from_file_location("supplement_figures", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_make_figures_quick(tmp_path):
    files = _load().make_figures(tmp_path, quick=True)
    names = {p.name for p in files}
    for stem in ("fig1_clamped_cosine", "fig2_fitted_lambda", "fig3_fit_error", "fig9_warp_error"):
        assert f"{stem}.png" in names and f"{stem}.csv" in names
        assert (tmp_path / f"{stem}.png").stat().st_size > 5000
    f1 = _rows(tmp_path / "fig1_clamped_cosine.csv")
    e = [float(r["rel_l2_error"]) for r in f1]
    assert all(b < a for a, b in zip(e, e[1:])) and abs(e[0] - 0.1774) < 1e-3
    f2 = _rows(tmp_path / "fig2_fitted_lambda.csv")
    for r in f2:  # analytic tracks the fit (within 50 % for the broadest lobes), converging when sharp
        assert abs(float(r["lambda_fit"]) / float(r["lambda_analytic"]) - 1) < 0.5
    ct = [r for r in f2 if r["model"] == "cook_torrance"]
    bp = [r for r in f2 if r["model"] == "blinn_phong"]
    assert abs(float(ct[0]["lambda_fit"]) / float(ct[0]["lambda_analytic"]) - 1) < 0.01
    assert abs(float(bp[-1]["lambda_fit"]) / float(bp[-1]["lambda_analytic"]) - 1) < 0.01
    f3 = _rows(tmp_path / "fig3_fit_error.csv")
    for r in f3:
        a, f = float(r["eq11_error_analytic"]), float(r["eq11_error_fit"])
        assert np.isfinite(a) and np.isfinite(f) and a < 0.01 and f < 0.01
    f9 = _rows(tmp_path / "fig9_warp_error.csv")
    w = [float(r["eq11_error_warped_slice"]) for r in f9]
    assert all(np.isfinite(w)) and max(w) < 0.3
    assert w[0] <= w[-1]  # sharper lobes are not worse than the roughest

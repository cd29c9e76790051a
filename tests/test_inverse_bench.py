"""The inverse-rendering benchmark (``warp_sg.tools.bench_inverse``) at a tiny size: a sphere on the
floor beside a grey ball, with a known base-colour texture and roughness texture, photographed by our Monte-Carlo
reference (full depth) under one generated sky from 4 views of 32², fitted (environment, base
colour, roughness; coarse to fine) and relit under another sky from 2 novel views. The fit must
recover the base colour the views see (PSNR over a threshold measured on this problem, less a
margin) and relight clearly better than its starting point; our renderer with the true textures
bounds the relighting PSNR from above.
"""
from __future__ import annotations

import math

import pytest

from warp_sg.tools.bench_inverse import quick_problem, run_relighting

#: measured on this problem (CPU, 2026-12-08): albedo PSNR 19.6 dB (start 15.3 dB), relighting 23.0 dB
#: (start 18.6 dB; true textures 28.4 dB), relative MSE 0.056 (start 0.174); the limits leave a margin
ALBEDO_PSNR_MIN = 18.0
RELIGHT_GAIN_MIN = 3.0


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    p = quick_problem(tmp_path_factory.mktemp("inverse"), size=32, views=4)
    out = run_relighting(p, truth="reference", photo_spp=32, levels=((4, 6), (None, 12)), env_lobes=16,
                         floor_stride=2)
    return {r["case"].split(" (")[0].split(",")[0]: r for r in out["rows"]}, out


def test_fit_recovers_the_base_colour_the_views_see(bench):
    rows, _ = bench
    fit, start = rows["warp-sg fit"], rows["start of the fit"]
    assert fit["albedo_psnr_db"] > ALBEDO_PSNR_MIN
    assert fit["albedo_psnr_db"] > start["albedo_psnr_db"] + 3.0
    assert fit["roughness_mae"] < 0.2


def test_relighting_under_another_sky_beats_the_start_and_stays_under_the_true_textures(bench):
    rows, out = bench
    fit, start, true = rows["warp-sg fit"], rows["start of the fit"], rows["warp-sg"]
    assert fit["relight_psnr_db"] > start["relight_psnr_db"] + RELIGHT_GAIN_MIN
    assert fit["relight_rel_mse"] < 0.5 * start["relight_rel_mse"]
    assert fit["relight_psnr_db"] < true["relight_psnr_db"] + 1.0
    assert math.isfinite(fit["fit_s"]) and fit["iterations"] >= 15
    assert out["info"]["seen_texels"] > 0.1

"""``warp-sg bench``: the quick run produces every section with the documented columns."""
from __future__ import annotations

import math

import pytest

from warp_sg.bench import SECTIONS, run_bench, spp_for_error


def test_spp_for_error_interpolates_log_log_and_extrapolates_like_one_over_spp():
    curve = [(1, 1.0, 0.1), (2, 0.5, 0.2), (4, 0.25, 0.4)]
    spp, t = spp_for_error(curve, 0.5)
    assert spp == pytest.approx(2.0) and t == pytest.approx(0.2)
    spp, t = spp_for_error(curve, 0.025)
    assert spp == pytest.approx(40.0) and t == pytest.approx(4.0)
    assert spp_for_error(curve, 2.0)[0] == 1


def test_quick_bench_prints_every_section_with_its_columns(cache_dir):
    printed = []
    res = run_bench(device="cpu", quick=True, print_fn=printed.append)
    assert list(res.sections) == list(SECTIONS)
    assert len(printed) == len(SECTIONS) and all(p.startswith("### ") for p in printed)
    for name, rows in res.sections.items():
        assert rows, name
        assert all("case" in r for r in rows), name
    shading = res.sections["shading cost by scene feature"]
    cases = [r["case"] for r in shading]
    assert cases[:5] == ["full scene", "no environment", "no local lights", "diffuse-only materials", "shadows off"]
    assert shading[0]["shade_ratio"] == 1.0
    assert all(r["shade_s"] > 0 for r in shading[:5])
    eq = res.sections["equal error: SG renderer vs Monte-Carlo reference"]
    assert eq[0]["case"].startswith("bench scene: SG renderer") and "spp" in eq[2]["case"]
    assert eq[4]["case"].startswith("plain inputs: SG renderer") and "spp" in eq[6]["case"]
    assert eq[8]["case"].startswith("plain inputs, point light: SG renderer") and "spp" in eq[10]["case"]
    assert all(math.isfinite(r["rel_mse"]) for r in eq)
    mit = res.sections["equal error: SG renderer vs Mitsuba 3"]
    from warp_sg.peer_mitsuba import mitsuba_status

    if mitsuba_status("cpu")[0]:  # the optional [compare] extra is installed
        assert [r["case"] for r in mit] == ["bench scene, Lambert materials", "plain inputs",
                                            "plain inputs, point light", "setup"]
        assert all(r["frame_s"] > 0 and r["truth_floor"] > 0 for r in mit[:3])
        assert all(r["mitsuba_s"] > 0 and r["mc_s"] > 0 for r in mit[:3] if "mitsuba_s" in r)
        # the same SG frame as the Monte-Carlo section (one measurement per run), a less noisy truth
        assert mit[1]["frame_s"] == eq[4]["seconds"] and mit[1]["truth_floor"] < eq[7]["rel_mse"]
    else:
        assert len(mit) == 1 and mit[0]["note"].startswith("skipped: ") and "[compare]" in mit[0]["note"]
    pre = res.sections["precompute cost"]
    assert all(r["total_s"] > 0 for r in pre)
    sc = res.sections["frame scaling: pixels and triangles"]
    assert [r["grows with"] for r in sc] == ["pixels", "pixels", "triangles", "triangles"]
    assert sc[2]["triangles"] < sc[3]["triangles"] and all(r["new view s"] > 0 and r["re-shade s"] > 0 for r in sc)
    budget = res.sections["SSDF error vs ray budget"]
    full, adaptive = budget[0], budget[1]
    assert full["case"].endswith("full (a ray per texel)") and full["ray_ratio"] == 1.0
    assert adaptive["ray_ratio"] < 0.5 and adaptive["err_vs_full_rad"] < 1e-3
    assert adaptive["err_vs_256_rad"] <= 1.02 * full["err_vs_256_rad"] + 1e-5
    first = res.sections["time to first image"]
    assert first[0]["case"].startswith("generated textured helmet")
    assert all(first[0][k] > 0 for k in ("cold_s", "cold_cpu_s", "first_frame_s", "shadows_s", "warm_s"))
    md = res.to_markdown()
    assert md.count("### ") == len(SECTIONS)

"""The independent Mitsuba 3 peer (warp_sg.tools.mitsuba) is itself right: its BRDFs are reciprocal,
its sampling is consistent with its evaluation, its MERL reader follows the published layout, our mesh
loading agrees with Mitsuba's own loaders, and a stored reference of the accuracy matrix is still
what Mitsuba renders (``scalar_rgb``, no system LLVM needed)."""
from __future__ import annotations

import math

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")  # a [dev] dependency: present in CI
import drjit as dr  # noqa: E402

from warp_sg.groundtruth import accuracy_matrix as AM  # noqa: E402
from warp_sg.tools.mitsuba import formulas as F  # noqa: E402
from warp_sg.tools.mitsuba.plugin import PLUGIN, ensure_registered, register_material  # noqa: E402


@pytest.fixture(autouse=True)
def scalar_variant():
    mi.set_variant("scalar_rgb")
    ensure_registered()


def _dir(theta, phi):
    return mi.Vector3f(math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))


def _table(name):
    from warp_sg.tools.mitsuba.scene_dict import resolve_fresnel

    p = dict(AM.MATERIALS[name])
    if "fresnel" in p:
        p["fresnel"] = resolve_fresnel(p["fresnel"], name)
    return p


ANALYTIC = [m for m in AM.MATERIALS if m != "measured"]


@pytest.mark.parametrize("name", ANALYTIC)
def test_each_peer_brdf_is_reciprocal_and_zero_below_the_horizon(name):
    p = _table(name)
    f = F.MODELS[p["model"]]
    rng = np.random.default_rng(1)
    for _ in range(20):
        t1, t2 = rng.uniform(0.05, 1.5, 2)
        a1, a2 = rng.uniform(0, 2 * math.pi, 2)
        o, i = _dir(t1, a1), _dir(t2, a2)
        x, y = np.array(f(p, o, i)), np.array(f(p, i, o))
        assert np.all(np.isfinite(x)) and np.all(x >= 0)
        np.testing.assert_allclose(x, y, rtol=2e-4, atol=1e-7)


@pytest.mark.parametrize("name", ["oren_nayar_0.8", "phong_8", "blinn_phong_10", "ward_aniso", "lafortune_retro",
                                  "ggx_dielectric_0.4", "torrance_sparrow_0.35"])
def test_peer_sampling_estimates_the_albedo_that_quadrature_of_its_evaluation_gives(name):
    """The plugin's sample() weights (value/pdf) average to the directional albedo ∫ f cos dω that a
    dense quadrature of eval() gives: sampling, pdf and evaluation are one consistent BSDF."""
    p = _table(name)
    register_material("test:" + name, p)
    bsdf = mi.load_dict({"type": PLUGIN, "material": "test:" + name})
    o = _dir(0.6, 0.3)
    si = dr.zeros(mi.SurfaceInteraction3f)
    si.wi = o
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    ctx = mi.BSDFContext()
    # quadrature: midpoint rule in (cos θ, φ), 60 × 120 cells (broad lobes) (numpy over the peer's formula)
    f = F.MODELS[p["model"]]
    n_t, n_p = 60, 120
    ct = (np.arange(n_t) + 0.5) / n_t
    ph = (np.arange(n_p) + 0.5) / n_p * 2 * math.pi
    total = np.zeros(3)
    for c in ct:
        st = math.sqrt(1 - c * c)
        for k in range(0, n_p, 8):
            for q in ph[k:k + 8]:
                total += np.array(f(p, o, mi.Vector3f(st * math.cos(q), st * math.sin(q), c))) * c
    quad = total * (1.0 / n_t) * (2 * math.pi / n_p)
    rng = np.random.default_rng(7)
    n = 3000
    acc = np.zeros(3)
    acc2 = np.zeros(3)
    for _ in range(n):
        u1, u2, u3 = rng.random(3)
        bs, w = bsdf.sample(ctx, si, float(u1), mi.Point2f(float(u2), float(u3)), True)
        w = np.array(w)
        if bs.pdf > 0:
            val = np.array(bsdf.eval(ctx, si, bs.wo, True))
            assert np.allclose(w, val / bs.pdf, rtol=1e-4, atol=1e-6)
        acc += w
        acc2 += w * w
    mean = acc / n
    se = np.sqrt(np.maximum(acc2 / n - mean ** 2, 0) / n)
    assert np.all(np.abs(mean - quad) <= 4 * se + 0.01 * quad + 1e-4), (mean, quad, se)


def test_merl_peer_reads_the_cell_the_published_reader_names(tmp_path):
    """A table whose value is its own cell index is looked up at directions whose half/difference
    angles fall in known cells (BRDFRead.cpp's index rules)."""
    from warp_sg.tools.mitsuba.merl_lookup import N_PD, N_TD, N_TH, SCALE, merl_brdf

    n = N_TH * N_TD * N_PD
    vals = np.arange(n, dtype=np.float64)
    path = tmp_path / "index.binary"
    with open(path, "wb") as fh:
        fh.write(np.array([N_TH, N_TD, N_PD], "<i4").tobytes())
        fh.write(np.concatenate([vals, vals, vals]).astype("<f8").tobytes())
    f = merl_brdf({"path": str(path)})

    def cell(o, i):
        return float(np.array(f({}, o, i))[0]) / SCALE[0]

    # o = i = normal: θh = θd = 0 → cell 0 (φd = 0)
    assert cell(_dir(0, 0), _dir(0, 0)) == pytest.approx(0.0)
    # mirror pair at θ = 40°: h = normal, θd = 40°; φh (so φd) is undefined there: φd cell 0 or 90
    t = math.radians(40.0)
    td = int(t / (math.pi / 2) * N_TD)
    assert round(cell(_dir(t, math.pi), _dir(t, 0.0))) in (td * N_PD, td * N_PD + N_PD // 2)
    # o = normal, i at θ = 60° in the plane y = 0: θh = 30°, θd = 30°; θh index ⌊√(30/90 · 90²)⌋
    ih = int(math.sqrt(30.0 / 90.0 * N_TH * N_TH))
    idd = int(math.radians(30.0) / (math.pi / 2) * N_TD)
    assert cell(_dir(0, 0), _dir(math.radians(60.0), 0.0)) == pytest.approx(ih * N_PD * N_TD + idd * N_PD, abs=N_PD)


def test_our_mesh_loading_agrees_with_mitsubas_own_ply_and_obj_loaders(tmp_path):
    """The peer uses our geometry (scene_dict docstring); here our loading of a PLY with scale, rotation
    and translation and of the floor OBJ is checked against Mitsuba's own loaders and ``to_world``."""
    from warp_sg.scene import load_scene
    from warp_sg.scene.plain_scenes import write_floor_obj, write_sphere_ply

    write_sphere_ply(tmp_path / "s.ply", subdivisions=1)
    write_floor_obj(tmp_path / "f.obj")
    (tmp_path / "scene.toml").write_text(
        "[camera]\norigin = [0, 1, 4]\n[[objects]]\nmesh = \"s.ply\"\nmaterial = \"a\"\nscale = 1.5\n"
        "rotate = [10.0, 35.0, -20.0]\ntranslate = [0.3, 0.1, -0.2]\n[[objects]]\nmesh = \"f.obj\"\nmaterial = \"a\"\n"
        "[materials.a]\nmodel = \"lambert\"\n[[lights]]\ntype = \"point\"\nposition = [0, 3, 0]\n")
    g = load_scene(tmp_path / "scene.toml").geometry()
    tw = (mi.ScalarTransform4f().translate([0.3, 0.1, -0.2]).rotate([0, 0, 1], -20.0).rotate([0, 1, 0], 35.0)
          .rotate([1, 0, 0], 10.0).scale(1.5))
    ply = mi.load_dict({"type": "ply", "filename": str(tmp_path / "s.ply"), "to_world": tw})
    obj = mi.load_dict({"type": "obj", "filename": str(tmp_path / "f.obj")})
    theirs = np.concatenate([np.array(mi.traverse(s)["vertex_positions"]).reshape(-1, 3) for s in (ply, obj)])
    ours = np.asarray(g.vertices, np.float64)
    # the same point sets (the loaders may order and weld vertices differently)
    from scipy.spatial import cKDTree

    d1, _ = cKDTree(theirs).query(ours)
    d2, _ = cKDTree(ours).query(theirs)
    assert max(d1.max(), d2.max()) < 1e-5


def test_a_stored_reference_is_still_mitsubas_answer(tmp_path):
    """Re-render a window of a stored reference with Mitsuba's scalar variant at fewer samples: every
    region's mean agrees within the two renders' noise."""
    from warp_sg.tools.mitsuba.scene_dict import independent_scene_dict

    case = AM.BY_NAME["sphere-point-cook_torrance_0.25"]
    ref = AM.load_reference(case)
    scene, _ = AM.load_case(case, tmp_path)
    d = independent_scene_dict(scene, spp=32)
    x0, y0, w, h = 18, 16, 28, 26  # the ball, its shadow and a piece of the lit floor
    d["sensor"]["film"].update({"crop_offset_x": x0, "crop_offset_y": y0, "crop_width": w, "crop_height": h})
    imgs = [np.array(mi.render(mi.load_dict(d), spp=32, seed=s), np.float64) for s in (11, 12)]
    mine = np.mean(imgs, 0)
    mine_se = np.abs(imgs[0] - imgs[1]) / 2.0
    win = (slice(y0, y0 + h), slice(x0, x0 + w))
    for r in ("object", "lit_floor", "shadow"):
        m = ref["masks"][r][win]
        assert m.sum() > 20, r
        a, b = mine[m].mean(0), ref["image"][win][m].mean(0)
        se = np.sqrt((mine_se[m] ** 2).sum(0)) / m.sum() + np.sqrt((ref["stderr"][win][m] ** 2).sum(0)) / m.sum()
        assert np.all(np.abs(a - b) <= 5 * se + 0.01 * b), (r, a, b, se)


def test_an_old_system_llvm_is_refused_before_mitsuba_can_abort_the_process(monkeypatch):
    # LLVM 14/15 (Debian 12's default) abort the process in Dr.Jit's first kernel that takes a minimum
    # ("Cannot select fminimum"); the version is checked first and the scalar variant taken instead
    import drjit as dr

    from warp_sg.tools.mitsuba import render as R

    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (15, 0, 6), raising=False)
    why = R.llvm_problem()
    assert why is not None and "15.0.6" in why and "libllvm19" in why
    assert R.set_fastest_variant() == "scalar_rgb"
    with pytest.raises(RuntimeError, match="15.0.6"):
        R.set_fastest_variant("llvm_ad_rgb")

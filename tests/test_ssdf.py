"""precompute.visibility.ssdf (eq. 23-24): jump flooding vs brute force, conventions, caching, kernel lookups."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import precompute
from precompute.visibility import ssdf as S
from precompute.visibility import ssdf_wp
from precompute.visibility.reference_checks import bowl_scene, brute_force_ssdf, plane_box_scene

SCENE = plane_box_scene(n=12, size=4.0, box=1.0)
FLOOR_IDS = np.array([0, 13, 27, 40, 50, 53, 70, 90, 100, 118])


@wp.kernel
def _lookup_kernel(mean: wp.array2d(dtype=float), basis: wp.array3d(dtype=float), w: wp.array2d(dtype=float),
                   verts: wp.array(dtype=int), dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=float),
                   out_bary: wp.array(dtype=float)):
    k = wp.tid()
    out[k] = ssdf_wp.ssdf_eval_vertex(mean, basis, w, verts[k], dirs[k])
    out_bary[k] = ssdf_wp.ssdf_eval_bary(mean, basis, w, verts[k], 0, 1, 0.5, 0.25, 0.25, dirs[k])


def test_jump_flooding_matches_brute_force_eq23(device):
    V, F, N = SCENE
    R = 48
    sd, vis = S.compute_ssdf(V, F, N, resolution=R, ray_resolution=R, device=device, vertex_ids=FLOOR_IDS,
                             progress=False, return_visibility=True)
    errs = np.stack([np.abs(brute_force_ssdf(vis[k]) - sd[k]) for k in range(len(FLOOR_IDS))])
    spacing = np.sqrt(2 * np.pi / R**2)  # mean angular texel spacing
    print(f"\n  JFA vs exhaustive eq. 23 at {R}²: mean {errs.mean():.2e} rad, max {errs.max():.3f} rad "
          f"(texel ≈ {spacing:.3f} rad), {100 * (errs > 1e-3).mean():.1f}% texels > 1e-3")
    assert errs.mean() < 1e-3
    assert errs.max() < 0.75 * spacing


def test_coarse_to_fine_search_matches_brute_force_eq23(device):
    """The default rays (64²) are finer than the stored maps (32²): the search floods the 32² grid
    and refines locally (precompute.visibility.jump_flood, "Coarse-to-fine"). Against eq. 23 evaluated
    exhaustively at 64² and box-filtered to 32², on floor vertices around the box and on the bowl."""
    errs = []
    for V, F, N, ids in ((*SCENE, FLOOR_IDS), (*bowl_scene(3), np.arange(0, 300, 5))):
        sd, vis = S.compute_ssdf(V, F, N, resolution=32, ray_resolution=64, device=device, vertex_ids=ids,
                                 progress=False, return_visibility=True)
        ref = np.stack([brute_force_ssdf(m).reshape(32, 2, 32, 2).mean(axis=(1, 3)) for m in vis])
        errs.append(np.abs(ref - sd).ravel())
    errs = np.concatenate(errs)
    spacing = np.sqrt(2 * np.pi / 32**2)  # the stored texel's mean angular size
    print(f"\n  coarse-to-fine vs exhaustive eq. 23 (64² → 32²): mean {errs.mean():.2e} rad, "
          f"max {errs.max():.3f} rad (texel ≈ {spacing:.3f} rad)")
    assert errs.mean() < 5e-4
    assert errs.max() < 0.5 * spacing


def test_fused_fine_pass_gives_the_maps_of_the_separate_kernels(device):
    """``fine_signed_kernel`` (fine seed pass + signed distance + box filter in one kernel, the
    default at 64² → 32²) gives the three separate kernels' maps bit for bit, also in a batch
    with uniform maps (no seed anywhere: the fine pass never reads an empty index); a uniform map
    is −π/2 (all hidden) or its horizon bound (all visible) everywhere: eq. 23 closed form."""
    V, F, N = SCENE
    ids = np.concatenate([FLOOR_IDS, np.arange(0, 144, 7)])
    _, vis = S.compute_ssdf(V, F, N, resolution=32, ray_resolution=64, device=device, vertex_ids=ids,
                            progress=False, return_visibility=True)
    maps = np.concatenate([vis.reshape(len(ids), -1), np.zeros((1, 64 * 64), np.uint8),
                           np.ones((1, 64 * 64), np.uint8)])
    dirs = wp.array(ssdf_wp.texel_directions(64).reshape(-1, 3).astype(np.float32), dtype=wp.vec3, device=device)
    m = wp.array(maps, dtype=wp.uint8, device=device)
    fused = S._fit_maps(m, dirs, 64, 32, device, fused=True)
    apart = S._fit_maps(m, dirs, 64, 32, device, fused=False)
    assert np.array_equal(fused, apart)
    assert 0 < (maps[:-2].min(axis=1) != maps[:-2].max(axis=1)).sum()  # mixed maps are among them
    np.testing.assert_array_equal(fused[-2], np.float32(-np.pi / 2))
    z = ssdf_wp.texel_directions(64)[..., 2].reshape(32, 2, 32, 2)
    np.testing.assert_allclose(fused[-1], np.arcsin(z).mean(axis=(1, 3)).ravel(), atol=2e-6)


def test_ssdf_sign_and_horizon_conventions(device):
    V, F, N = SCENE
    center = int(np.argmin(np.linalg.norm(V[:144], axis=1)))  # under the cube
    sd, vis = S.compute_ssdf(V, F, N, resolution=32, ray_resolution=32, device=device,
                             vertex_ids=[0, 53, center], progress=False, return_visibility=True)
    assert (sd[vis == 1] > 0).all() and (sd[vis == 0] < 0).all()
    assert np.allclose(sd[2], -np.pi / 2)  # nothing visible: clamped to −π/2
    # a vertex that sees only sky: SSDF = elevation (distance to the horizon), exactly
    floor_only = plane_box_scene(n=4)
    Vf, Ff, Nf = floor_only[0][:16], floor_only[1][:18], floor_only[2][:16]
    sky = S.compute_ssdf(Vf, Ff, Nf, resolution=16, ray_resolution=16, device=device, vertex_ids=[5],
                         progress=False)[0]
    elev = np.arcsin(ssdf_wp.texel_directions(16)[..., 2])
    np.testing.assert_allclose(sky, elev, atol=1e-5)


def test_downsampling_is_a_box_filter(device):
    """Step 5: the stored texel is the mean of its f×f ray texels (numpy's block mean as reference)."""
    from precompute.visibility.jump_flood import downsample_kernel

    fine = np.random.default_rng(3).uniform(-1.5, 1.5, (3, 32 * 32)).astype(np.float32)
    for f in (2, 4):
        Rs = 32 // f
        out = wp.empty((3, Rs * Rs), dtype=float, device=device)
        wp.launch(downsample_kernel, dim=(3, Rs * Rs), device=device,
                  inputs=[wp.array(fine, dtype=float, device=device), Rs, f, out])
        ref = fine.reshape(3, Rs, f, Rs, f).mean(axis=(2, 4)).reshape(3, -1)
        np.testing.assert_allclose(out.numpy(), ref, atol=1e-6)


def test_kept_maps_defer_the_pca_until_it_is_read(cache_dir):
    """Where the uncompressed maps are kept (within the decompression budget), ssdf_for_mesh leaves
    the PCA for when it is read: the device form is the ray-cast maps themselves (compute_ssdf's)
    without it; reading the weights computes it, and it is the PCA of those maps; a cache hit
    is deferred the same way."""
    from warp_sg.numeric.pca import pca

    V, F, N = SCENE
    d = precompute.ssdf_for_mesh(V, F, N, resolution=16, ray_resolution=32, pca_terms=12, progress=False)
    assert d.pca.pending and d.pca_terms == 12 and d.n_vertices == len(V) and "pca" not in d.stats
    exact = S.compute_ssdf(V, F, N, resolution=16, ray_resolution=32, progress=False).reshape(len(V), -1)
    _, basis, maps = d.device_arrays("cpu", S.decompress_budget())
    assert basis.shape[2] == 0 and d.pca.pending
    np.testing.assert_array_equal(maps.numpy(), exact)
    ref = pca(exact, 12)
    np.testing.assert_allclose(d.weights, ref.weights, atol=1e-6)
    assert not d.pca.pending and d.basis.shape == (12, 16, 16)
    np.testing.assert_allclose(d.pca_rms_error, ref.rms_error, rtol=1e-6)
    hit = precompute.ssdf_for_mesh(V, F, N, resolution=16, ray_resolution=32, pca_terms=12, progress=False)
    assert hit.pca.pending and hit.stats.get("rays") is None
    np.testing.assert_array_equal(hit.maps, exact)


def test_ssdf_for_mesh_compresses_and_caches(cache_dir, monkeypatch):
    V, F, N = SCENE
    d = precompute.ssdf_for_mesh(V, F, N, resolution=16, ray_resolution=32, pca_terms=12, progress=False)
    assert isinstance(d, precompute.SSDFData)
    assert d.mean.shape == (16, 16) and d.basis.shape == (12, 16, 16) and d.weights.shape == (len(V), 12)
    exact = S.compute_ssdf(V, F, N, resolution=16, ray_resolution=32, progress=False)
    rms = np.sqrt(np.mean((d.reconstruct() - exact) ** 2))
    assert rms == pytest.approx(d.pca_rms_error[12], rel=1e-2)
    assert d.pca_rms_error[12] < 0.25 * d.pca_rms_error[0]
    print("\n  PCA rms error (rad) by terms: " +
          ", ".join(f"{k}: {d.pca_rms_error[k]:.3f}" for k in (0, 2, 4, 8, 12)))
    np.testing.assert_allclose(d.reconstruct([3, 7]), d.reconstruct()[[3, 7]], atol=1e-6)
    # a second call is a cache hit (no recomputation), a parameter change is a miss
    calls = []
    monkeypatch.setattr(S, "compute_ssdf", lambda *a, **k: calls.append(1) or exact.copy())
    d2 = precompute.ssdf_for_mesh(V, F, N, resolution=16, ray_resolution=32, pca_terms=12, progress=False)
    assert calls == [] and d2.key == d.key
    np.testing.assert_array_equal(d2.weights, d.weights)
    precompute.ssdf_for_mesh(V, F, N, resolution=16, ray_resolution=32, pca_terms=8, progress=False)
    assert calls == [1]


def test_kernel_lookup_matches_numpy_reconstruction(device):
    rng = np.random.default_rng(3)
    R, NV, nv = 16, 5, 4
    mean = rng.standard_normal((R, R)).astype(np.float32)
    basis = rng.standard_normal((NV, R, R)).astype(np.float32)
    w = rng.standard_normal((nv, NV)).astype(np.float32)
    m = 300
    dirs = rng.standard_normal((m, 3))
    dirs[: m // 2, 2] = np.abs(dirs[: m // 2, 2])  # half above, the rest anywhere (below: horizon rule)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    verts = rng.integers(0, nv, m)
    out = wp.zeros(m, dtype=float, device=device)
    out_b = wp.zeros(m, dtype=float, device=device)
    wp.launch(_lookup_kernel, dim=m, device=device,
              inputs=[wp.array(mean, dtype=float, device=device),
                      wp.array(np.ascontiguousarray(np.moveaxis(basis, 0, -1)), dtype=float, device=device),  # texel-major
                      wp.array(w, dtype=float, device=device), wp.array(verts.astype(np.int32), device=device),
                      wp.array(dirs.astype(np.float32), dtype=wp.vec3, device=device), out, out_b])
    ref = np.array([ssdf_wp.ssdf_eval_np(mean, basis, w[v], d) for v, d in zip(verts, dirs)])
    np.testing.assert_allclose(out.numpy(), ref, atol=2e-4)
    wb = 0.5 * w[verts] + 0.25 * w[0] + 0.25 * w[1]
    ref_b = np.array([ssdf_wp.ssdf_eval_np(mean, basis, wi, d) for wi, d in zip(wb, dirs)])
    np.testing.assert_allclose(out_b.numpy(), ref_b, atol=2e-4)
    # at texel centres the bilinear lookup returns the texel value
    dc = ssdf_wp.texel_directions(R)[5, 9]
    assert ssdf_wp.ssdf_eval_np(mean, basis, w[0], dc) == pytest.approx(
        mean[5, 9] + w[0] @ basis[:, 5, 9], abs=1e-4)


def test_bad_parameters_are_input_errors():
    V, F, N = SCENE
    with pytest.raises(precompute.visibility.ssdf.InputError, match="multiple"):
        precompute.ssdf_for_mesh(V, F, N, resolution=16, ray_resolution=24, progress=False, use_cache=False)
    with pytest.raises(precompute.visibility.ssdf.InputError, match="pca_terms"):
        precompute.ssdf_for_mesh(V, F, N, resolution=16, pca_terms=0, progress=False, use_cache=False)

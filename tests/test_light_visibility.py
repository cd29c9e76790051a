"""A light's visible fraction behind an SSDF boundary (``warp_sg.shading.visibility_terms``):
the uniform disc of a spherical light cut by the boundary's great circle, against quadrature over
the disc and against ray casts of the sphere light at the floor vertices of the ball's shadow."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_sg.sg.algebra_wp import FA_NUMERATOR
from warp_sg.shading.visibility_terms import Visibility, fh_fraction, light_cap_visible, light_fraction


@wp.kernel
def _cap(theta: wp.array(dtype=float), lam: wp.array(dtype=float), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = light_cap_visible(theta[i], lam[i])


def _sharpness(alpha):
    """The renderer's SG sharpness of a light of angular radius α (``light_irradiance``: λ = fa⁻¹(2π sin²α))."""
    return float(FA_NUMERATOR) / (2.0 * np.pi * np.sin(alpha) ** 2)


def _cap_quadrature(theta, alpha, n=1500):
    """Fraction of the cap of angular radius α about c, c·m = sin θ, on the side i·m ≥ 0: midpoint
    rule in the cap's own polar coordinates (ρ from c, azimuth φ), weight sin ρ."""
    rho = (np.arange(n) + 0.5) / n * alpha
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * 2.0 * np.pi
    R, P = np.meshgrid(rho, ph, indexing="ij")
    # c = (0, 0, 1); m = (cos θ, 0, sin θ); i = (sin ρ cos φ, sin ρ sin φ, cos ρ)
    dot = np.sin(R) * np.cos(P) * np.cos(theta) + np.cos(R) * np.sin(theta)
    w = np.sin(R)
    return float(np.sum(w * (dot >= 0.0)) / np.sum(w))


@pytest.mark.parametrize("alpha", [0.004, 0.04, 0.3, 1.2])
def test_cap_fraction_matches_quadrature_over_the_disc(device, alpha):
    th = np.linspace(-1.2 * alpha, 1.2 * alpha, 25)
    lam = np.full_like(th, _sharpness(alpha))
    out = wp.zeros(len(th), dtype=float, device=device)
    wp.launch(_cap, dim=len(th), device=device,
              inputs=[wp.array(th.astype(np.float32), dtype=float, device=device),
                      wp.array(lam.astype(np.float32), dtype=float, device=device), out])
    ref = np.array([_cap_quadrature(t, alpha) for t in th])
    np.testing.assert_allclose(out.numpy(), ref, atol=2e-3)
    assert out.numpy()[0] == 0.0 and out.numpy()[-1] == 1.0  # outside ±α: exactly dark / lit


@wp.kernel
def _vertex_fractions(vis: Visibility, th_h: wp.array(dtype=float), deficit: wp.array(dtype=float),
                      lam: wp.array(dtype=float), cap: wp.array(dtype=float), sg: wp.array(dtype=float)):
    """Each vertex's visible fraction of the light from its cached SSDF deficit, as the shading
    kernel takes it (θd = θh + deficit): the disc (``light_fraction``) and the SG's fh ratio."""
    i = wp.tid()
    cap[i] = light_fraction(0, vis, th_h[i] + deficit[i], th_h[i], lam[i])
    sg[i] = fh_fraction(0, vis, th_h[i] + deficit[i], th_h[i], lam[i])


def _ray_cast_fraction(mesh_v, mesh_f, P, N, light, radius, k=512, seed=1):
    """Cosine-weighted fraction of the sphere light's cone of directions that escapes the mesh,
    per point (k directions uniform in the cone, the same for every point; ``ray_visibility``)."""
    from precompute.visibility.rays import ray_visibility

    rng = np.random.default_rng(seed)
    u1, u2 = rng.random((2, k))
    rel = light[None, :] - P
    dist = np.linalg.norm(rel, axis=1)
    ax = rel / dist[:, None]
    omc = 1.0 - np.sqrt(1.0 - (radius / dist) ** 2)
    ct = 1.0 - u1[None, :] * omc[:, None]
    st = np.sqrt(np.maximum(1.0 - ct ** 2, 0.0))
    ph = 2.0 * np.pi * u2[None, :]
    t = np.cross(ax, [0.0, 0.0, 1.0])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(ax, t)
    d = (ax[:, None] * ct[..., None] + t[:, None] * (st * np.cos(ph))[..., None]
         + b[:, None] * (st * np.sin(ph))[..., None])
    cosw = np.maximum(np.einsum("pkj,pj->pk", d, N), 0.0)
    hit = ray_visibility(mesh_v, mesh_f, np.repeat(P, k, axis=0), np.repeat(N, k, axis=0), d.reshape(-1, 3))
    return (hit.reshape(len(P), k) * cosw).sum(1) / cosw.sum(1)


@pytest.mark.slow
def test_point_light_penumbra_at_the_floor_vertices_matches_ray_casts(tmp_path, device):
    """The ball's shadow on the 2-triangle floor under the spherical point light (radius 0.15,
    ~0.04 rad seen from the floor): at the refined floor vertices within 1.5 light radii of the
    shadow's edge, the per-vertex visible fraction (cached SSDF deficit → the disc's fraction)
    against a ray cast of the sphere light. The SG's fh ratio on the same SSDF values is the old
    model: its Gaussian tails leave light in the umbra and take it from the lit side."""
    import warp_sg as ws
    from warp_sg.scene.plain_scenes import write_plain_scene

    path = write_plain_scene(tmp_path, obj="sphere", light="point", material="lambert", size=32)
    r = ws.Renderer(ws.load_scene(path), device=device)
    r.render()
    V = np.asarray(r.geometry.vertices, np.float64)
    N = np.asarray(r.geometry.normals, np.float64)
    light, radius = np.array([1.6, 3.0, 1.4]), 0.15
    rel = light[None, :] - V
    dist = np.linalg.norm(rel, axis=1)
    alpha = np.arcsin(radius / dist)
    # the ball (radius 0.5 about (0, 0.5, 0)): signed angle of the light's centre off its silhouette
    c = np.array([0.0, 0.5, 0.0]) - V
    dc = np.linalg.norm(c, axis=1)
    gap = np.arccos(np.clip(np.einsum("ij,ij->i", rel / dist[:, None], c / dc[:, None]), -1, 1)) - np.arcsin(
        np.clip(0.5 / dc, 0, 1))
    ids = np.flatnonzero((np.abs(V[:, 1]) < 1e-9) & (np.abs(gap) < 1.5 * alpha))
    assert len(ids) > 300  # the refinement put vertices along the shadow's edge
    truth = _ray_cast_fraction(V, np.asarray(r.geometry.triangles), V[ids], N[ids], light, radius)
    th_h = np.arcsin(np.clip(np.einsum("ij,ij->i", rel[ids] / dist[ids, None], N[ids]), -1, 1))
    lam = float(FA_NUMERATOR) / (2.0 * np.pi * (radius / dist[ids]) ** 2)
    from warp_sg.shading.vertex_visibility import light_vertex_deficit

    # the SSDF's deficits (the path of moving vertices; a static scene's cache holds ray-cast ones)
    nv = len(r.geometry.vertices)
    deficit = light_vertex_deficit(r.vis, r.geo_arrays.positions, r.light_arrays, nv, False, device).numpy()[ids, 0]
    arr = lambda a: wp.array(np.asarray(a, np.float32), dtype=float, device=device)  # noqa: E731

    def fractions(dd):
        cap = wp.zeros(len(ids), dtype=float, device=device)
        sg = wp.zeros(len(ids), dtype=float, device=device)
        wp.launch(_vertex_fractions, dim=len(ids), device=device, inputs=[r.vis, arr(th_h), arr(dd), arr(lam), cap, sg])
        return cap.numpy(), sg.numpy()

    cap, sg = fractions(deficit)
    rays, _ = fractions(r.vis.light_deficit.numpy()[ids, 0])  # the cache: ray-cast fractions (light_rays)
    umbra, lit = truth == 0.0, truth == 1.0
    assert umbra.sum() > 30 and lit.sum() > 30
    # measured (2026-12-02; 1169 vertices, 86 dark, 104 lit in the ray cast): the disc leaves 0.013
    # of the light in the umbra (the SG 0.052), lets 0.997 through on the lit side (the SG 0.968);
    # mean error over all +0.009 (the SSDF's own error at this light size, 0.2 light radii RMS)
    assert cap[umbra].mean() <= 0.02 < 0.03 <= sg[umbra].mean()
    assert cap[lit].mean() >= 0.99 > 0.98 >= sg[lit].mean()
    assert abs(np.mean(cap - truth)) <= 0.015
    # the cached deficits, from rays over the light's cone, are closer still
    assert np.abs(rays - truth).mean() < np.abs(cap - truth).mean() and abs(np.mean(rays - truth)) <= 0.01

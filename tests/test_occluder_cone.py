"""Per-vertex occluder cones (``precompute.visibility.occluder_cone``): they contain every ray-cast occluded
direction, a lobe they declare clear is fully visible by ray-cast quadrature, an open plane has
none, and skipping the lookups leaves the image as it was."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from precompute.visibility.occluder_cone import no_cones, occluder_cones, texel_half_diagonal
from precompute.visibility.rays import hemisphere_visibility
from precompute.visibility.ssdf import compute_ssdf
from precompute.visibility.ssdf_wp import texel_directions
from warp_sg.numeric.onb import frame_from_normal
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene.model import Material, Scene, SceneObject
from warp_sg.scene.primitives import plane, sphere
from warp_sg.scene.render_settings import RenderSettings
from warp_sg.sg.fh import fh_theta_max

R, RR = 16, 32


@pytest.fixture(scope="module")
def ball_on_floor():
    s = sphere(radius=0.4, resolution=(10, 20), center=(0.0, 0.42, 0.0))
    p = plane(size=(3.0, 3.0), resolution=(12, 12))
    V = np.concatenate([s.vertices, p.vertices]).astype(np.float64)
    F = np.concatenate([s.triangles, p.triangles + len(s.vertices)])
    N = np.concatenate([s.normals, p.normals]).astype(np.float64)
    X = compute_ssdf(V, F, N, resolution=R, ray_resolution=RR, progress=False)
    return V, F, N, occluder_cones(X, N, R)


def _world_dirs(N, res):
    n = N / np.linalg.norm(N, axis=1, keepdims=True)
    t, b = frame_from_normal(n)
    d = texel_directions(res).reshape(-1, 3)
    return n, d[None, :, 0, None] * t[:, None] + d[None, :, 1, None] * b[:, None] + d[None, :, 2, None] * n[:, None]


def test_every_ray_cast_occluded_direction_lies_inside_its_vertex_cone(ball_on_floor):
    V, F, N, cones = ball_on_floor
    vis = hemisphere_visibility(V, F, N, resolution=64).reshape(len(V), -1)
    _, dw = _world_dirs(N, 64)
    inside = np.einsum("vkc,vc->vk", dw, cones[:, :3]) >= np.cos(np.minimum(cones[:, 3], np.pi))[:, None]
    occluded = vis == 0
    has = cones[:, 3] >= 0
    assert occluded[has].sum() > 1000, "the scene must occlude"
    # occluded directions of vertices with a cone: inside it; vertices without one: (nearly) unoccluded
    assert (occluded & ~inside)[has].sum() <= 1e-3 * occluded[has].sum()
    assert occluded[~has].mean() < 2e-3


def test_a_lobe_declared_clear_is_visible_by_ray_cast_and_by_the_uncompressed_ssdf(ball_on_floor):
    """The kernel skips a lookup where ∠(p, c) − α ≥ min(θh(p), θmax(λ)) + h. There the exact SSDF
    (ray cast + distance transform, no PCA) is ≥ min(θh, θmax) up to its own error (0.3 h), so the lookup
    would have returned a ratio of 1; and where the cone is θmax(λ) + h away (the lobe's support),
    the ray-cast visible fraction ∫G V / ∫G H is ≥ 0.998."""
    from precompute.visibility.ssdf_wp import lookup_np

    V, F, N, cones = ball_on_floor
    rng = np.random.default_rng(4)
    res = 64
    vis = hemisphere_visibility(V, F, N, resolution=res).reshape(len(V), -1)
    X = compute_ssdf(V, F, N, resolution=R, ray_resolution=RR, progress=False)
    n, dw = _world_dirs(N, res)
    t, b = frame_from_normal(n)
    h = texel_half_diagonal(R)
    n_skip = n_support = 0
    ssdf_short, worst = 0.0, 1.0
    for lam in (3.0, 30.0, 300.0, 3000.0):
        p = rng.normal(size=(len(V), 3))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        p = np.where(np.sum(p * n, 1, keepdims=True) < 0, -p, p)  # lobes above the vertex horizon
        th_h = np.arcsin(np.clip(np.sum(p * n, 1), -1, 1))
        tmax = float(fh_theta_max(lam))
        gap = np.where(cones[:, 3] < 0, np.inf, np.arccos(np.clip(np.sum(p * cones[:, :3], 1), -1, 1)) - cones[:, 3])
        need = np.clip(np.minimum(th_h, tmax), 0, None)
        skip = gap >= need + h
        local = np.stack([np.sum(p * t, 1), np.sum(p * b, 1), np.sum(p * n, 1)], 1)
        theta_d = np.array([lookup_np(X[i], local[i]) for i in np.flatnonzero(skip)])
        n_skip += skip.sum()
        ssdf_short = max(ssdf_short, float(np.max(need[skip] - theta_d, initial=0.0)))
        support = gap >= tmax + h
        G = np.exp(lam * (np.einsum("vkc,vc->vk", dw, p) - 1.0))
        ok = support & (G.sum(1) > 1e-6 * G.max())
        ratio = (G * vis).sum(1) / np.maximum(G.sum(1), 1e-300)
        n_support += ok.sum()
        worst = min(worst, float(ratio[ok].min()))
    assert n_skip > 500 and n_support > 200
    assert ssdf_short <= 0.3 * h, (ssdf_short, h)  # the transform's own error on an open plane: 0.17 h
    assert worst >= 0.998, worst  # 64² binary quadrature: a stray occluded texel at the support edge


def test_an_open_plane_has_no_occluder_cones():
    p = plane(size=(3.0, 3.0), resolution=(4, 4))
    X = compute_ssdf(p.vertices, p.triangles, p.normals, resolution=R, ray_resolution=RR, progress=False)
    assert (occluder_cones(X, p.normals, R)[:, 3] < 0).all()


def test_skipping_clear_lookups_leaves_the_image_as_the_full_lookups_make_it():
    cam = Camera(origin=(0.0, 1.6, 2.6), target=(0.0, 0.25, 0.0), fov=45.0, width=48, height=40)
    objects = [SceneObject(material="ball", primitive="sphere", params={"radius": 0.4, "resolution": (12, 24),
                                                                         "center": (0.0, 0.42, 0.0)}),
               SceneObject(material="floor", primitive="plane", params={"size": (3.0, 3.0), "resolution": (16, 16)})]
    mats = {"ball": Material("blinn_phong", {"kd": [0.5, 0.4, 0.3], "ks": [0.3, 0.3, 0.3], "n": 40.0}),
            "floor": Material("lambert", {"kd": [0.5, 0.5, 0.5]})}
    lights = [EnvironmentLight(procedural="sky", options={"width": 64, "height": 32}),
              DirectionalLight(direction=(-0.4, -1.0, -0.3), intensity=(2.0, 2.0, 2.0), radius=0.02)]
    rs = RenderSettings(shadows=True, ssdf_resolution=16, pca_terms=16, visibility_budget=0, env_lobes=4,
                        antialias=1)
    r = Renderer(Scene(camera=cam, objects=objects, materials=mats, lights=lights, render=rs), device="cpu")
    assert (r.ssdf.cones[:, 3] < 0).mean() > 0.05  # some vertices are clear of everything
    with_skip = r.render()
    # the same cone axes (the specular lobes' visible side reads them) with α beyond every skip
    never = np.array(r.ssdf.cones, np.float32)
    never[:, 3] = np.where(never[:, 3] < 0, 4.0, 3.8)
    never[never[:, 3] == 4.0] = no_cones(1)[0]
    r.vis.cones = wp.array(never, dtype=wp.vec4, device="cpu")
    r.set_environment_scale(1.0)
    full = r.render()
    assert np.abs(with_skip - full).mean() < 2e-3 * full.mean()
    assert np.abs(with_skip - full).max() < 0.05 * full.max()

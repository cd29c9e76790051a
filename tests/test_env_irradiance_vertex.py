"""The diffuse environment sum taken per vertex and interpolated where a triangle's check allows it
(``warp_sg.vertex_visibility.env_vertex_irradiance``): the rendered diffuse image against the
exact irradiance of the environment's SG mixture by quadrature (``sg_irradiance.e_exact``) at
each pixel's interpolated normal, on a fine and on a coarse sphere, and the check against the
same scene with every triangle forced onto the per-vertex values."""
from __future__ import annotations

import numpy as np
import pytest

from warp_sg import vertex_visibility as VV
from warp_sg.render import Renderer
from warp_sg.scene import Camera, EnvironmentLight, Material, RenderSettings, Scene
from warp_sg.scene import SceneObject
from warp_sg.sg_irradiance import e_exact

KD = np.array([0.6, 0.5, 0.4])


def _scene(resolution, sampling="vertex"):
    cam = Camera(origin=(0.0, 0.4, 2.2), target=(0.0, 0.0, 0.0), fov=40.0, width=48, height=48)
    ball = SceneObject(material="ball", primitive="sphere", params={"radius": 0.6, "resolution": resolution})
    # a sky with its sun left in the SG mixture (env_peaks = 0): a sharp lobe, the hard case
    env = EnvironmentLight(procedural="sky", options={"width": 128, "height": 64})
    rs = RenderSettings(shadows=False, antialias=1, env_lobes=8, env_peaks=0, visibility_budget=0,
                        visibility_sampling=sampling, background=False)
    return Scene(camera=cam, objects=[ball], materials={"ball": Material("lambert", {"kd": KD.tolist()})},
                 lights=[env], render=rs)


def _exact_image(r):
    """kd/π Σ_j μ_j ∫G_j e(n·p_j, λ_j) at every covered pixel (float64 quadrature; the renderer's
    own fit, its interpolated normal), and the covered-pixel mask."""
    vb = r.rasterize()
    tri = vb.tri_id.numpy()
    bary = vb.bary.numpy()
    g = r.geometry
    cov = tri >= 0
    t = g.triangles[tri[cov]]
    b1, b2 = bary[cov, 0], bary[cov, 1]
    w = np.stack([1.0 - b1 - b2, b1, b2], 1)
    n = np.einsum("pk,pkc->pc", w, np.asarray(g.normals, np.float64)[t])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    ax, lam, mu = r._env_sg_base
    R = r.env_light.rotation_matrix()
    ax = ax @ R.T
    power = mu * (2.0 * np.pi * -np.expm1(-2.0 * lam) / lam)[:, None]
    e = e_exact(n @ ax.T, lam[None, :])  # (pixels, lobes)
    img = np.zeros(tri.shape + (3,))
    img[cov] = (e @ power) * KD / np.pi
    return img, cov


def _error(img, ref, cov):
    """Largest per-pixel error relative to the brightest reference pixel."""
    return float(np.abs(img[cov] - ref[cov]).max() / ref[cov].max())


@pytest.mark.parametrize("resolution, max_err", [((48, 96), 0.01), ((6, 12), 0.01)])
def test_diffuse_environment_matches_the_exact_sg_irradiance_on_fine_and_coarse_spheres(resolution, max_err):
    r = Renderer(_scene(resolution), device="cpu")
    img = r.render()
    assert r.features().env_irradiance_vertex
    ref, cov = _exact_image(r)
    assert _error(img, ref, cov) < max_err


def test_fine_triangles_take_the_vertex_values_and_a_coarse_sphere_keeps_the_per_pixel_sum():
    fine = Renderer(_scene((48, 96)), device="cpu")
    fine.render()
    coarse = Renderer(_scene((6, 12)), device="cpu")
    coarse.render()
    f = fine._env_arrays().gouraud.numpy().mean()
    c = coarse._env_arrays().gouraud.numpy().mean()
    assert f > 0.9  # the saving applies to the meshes it is meant for
    assert c < 0.5  # 30° between neighbouring normals: the check refuses most triangles


def test_the_triangle_check_is_what_keeps_a_coarse_sphere_accurate(monkeypatch):
    """Forcing every triangle onto the interpolated per-vertex values (no check) puts the coarse
    sphere well off the exact irradiance; the checked render above stays within 1 %."""
    real = VV.env_vertex_irradiance

    def unchecked(irr, env, normals, tris, use_vis, device, tol=VV.GOURAUD_TOLERANCE):
        return real(irr, env, normals, tris, use_vis, device, tol=1e30)

    monkeypatch.setattr(VV, "env_vertex_irradiance", unchecked)
    r = Renderer(_scene((6, 12)), device="cpu")
    img = r.render()
    assert r._env_arrays().gouraud.numpy().all()
    ref, cov = _exact_image(r)
    assert _error(img, ref, cov) > 0.03


def test_an_environment_scale_edit_rescales_the_vertex_values_without_a_rebuild():
    r = Renderer(_scene((24, 48)), device="cpu")
    a = r.render()
    builds = r.env_irr_cache.builds
    r.set_environment_scale(2.5)
    b = r.render()
    assert r.env_irr_cache.builds == builds
    np.testing.assert_allclose(b, 2.5 * a, rtol=1e-5, atol=1e-7)
    fresh = Renderer(_scene((24, 48)), device="cpu")
    fresh.set_environment_scale(2.5)
    np.testing.assert_allclose(b, fresh.render(), rtol=1e-5, atol=1e-7)
    r.set_environment_scale(0.0)
    assert np.abs(r.render()).max() == 0.0
    r.set_environment_scale(1e-39)  # (built at unit scale: no overflow of a ratio of scales)
    assert np.isfinite(r.render()).all()
    r.set_environment_scale(1.0)
    np.testing.assert_allclose(r.render(), a, rtol=1e-5, atol=1e-7)
    assert r.env_irr_cache.builds == builds


def test_pixel_sampling_and_oren_nayar_keep_the_per_pixel_sum():
    r = Renderer(_scene((24, 48), sampling="pixel"), device="cpu")
    r.render()
    assert not r.features().env_irradiance_vertex and r.env_irr_cache.builds == 0
    s = _scene((24, 48))
    s.materials["ball"] = Material("oren_nayar", {"kd": KD.tolist(), "sigma": 0.3})
    r = Renderer(s, device="cpu")
    r.render()
    assert not r.features().env_irradiance_vertex and r.env_irr_cache.builds == 0

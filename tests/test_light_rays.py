"""Lights' visibility at the vertices by ray casting (warp_sg.shading.light_rays): a thin occluder's
shadow is as dark as a slab-test ray cast of the bar says, where the SSDF (which cannot hold an occluder a texel
wide) let 20-70 % of the light through. In images: the accuracy matrix's bunny under a point light
(ear shadows), tests/test_accuracy_matrix.py."""
from __future__ import annotations

import math

import numpy as np
import trimesh

import warp_sg as ws
from warp_sg.scene.camera import Camera
from warp_sg.scene.lights import PointLight
from warp_sg.scene.model import Material, Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings

LIGHT = np.array([0.3, 2.5, 0.2])
RADIUS = 0.08


def _bar() -> trimesh.Trimesh:
    bar = trimesh.creation.box(extents=(1.2, 0.04, 0.04))
    bar.apply_translation((0.0, 0.4, 0.0))
    return bar


def _bar_scene(size=64):
    """A 2-triangle floor and a thin bar (4 cm × 4 cm × 1.2 m) 40 cm above it, a small point light."""
    bar = _bar()
    floor_v = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], np.float32)
    floor_t = np.array([[0, 3, 2], [0, 2, 1]], np.int32)
    objs = [SceneObject(material="m", vertices=np.asarray(bar.vertices, np.float32),
                        triangles=np.asarray(bar.faces, np.int32), name="bar"),
            SceneObject(material="m", vertices=floor_v, triangles=floor_t, name="floor")]
    cam = Camera(origin=(0.0, 2.2, 2.2), target=(0.0, 0.0, 0.0), fov=40.0, width=size, height=size)
    return Scene(camera=cam, objects=objs, materials={"m": Material("lambert", {"kd": [0.7, 0.7, 0.7]})},
                 lights=[PointLight(position=LIGHT, radius=RADIUS, intensity=[8.0, 8.0, 8.0])],
                 render=RenderSettings(background=False))


def _slab_fraction(points: np.ndarray, n: int = 4096) -> np.ndarray:
    """Visible fraction of the light sphere from each point: rays uniform in its cone (cosine weights
    are ~1 over so small a cone) against the bar's axis-aligned box by the slab test."""
    lo, hi = np.array([-0.6, 0.38, -0.02]), np.array([0.6, 0.42, 0.02])
    rng = np.random.default_rng(3)
    out = np.empty(len(points))
    for k, p in enumerate(points):
        axis = LIGHT - p
        dist = np.linalg.norm(axis)
        axis /= dist
        ca = np.sqrt(1 - (RADIUS / dist) ** 2)
        u, v = rng.random(n), rng.random(n)
        ct = 1 - u * (1 - ca)
        st = np.sqrt(1 - ct * ct)
        t = np.cross(axis, [1.0, 0, 0])
        t /= np.linalg.norm(t)
        b = np.cross(axis, t)
        d = axis * ct[:, None] + (t * np.cos(2 * np.pi * v)[:, None] + b * np.sin(2 * np.pi * v)[:, None]) * st[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (lo - p) / d, (hi - p) / d
        near = np.nanmax(np.minimum(t0, t1), axis=1)
        far = np.nanmin(np.maximum(t0, t1), axis=1)
        out[k] = 1.0 - np.mean((near <= far) & (far > 0))
    return out


def test_the_vertices_light_fraction_is_the_ray_cast_one_under_a_thin_bar():
    scene = _bar_scene()
    r = ws.Renderer(scene, device="cpu")
    r.render()
    ci = r.cache_inputs()
    deficit = r.vis.light_deficit.numpy()[:, 0]
    pos = r.geometry.vertices
    floor = np.abs(pos[:, 1]) < 1e-6
    under = floor & (np.abs(pos[:, 0]) < 0.5) & (deficit < 0)
    assert under.sum() >= 10, "the refinement puts vertices in the bar's shadow"
    # the kernel's fraction at those vertices: cap(θh + deficit)/cap(θh) for the light's disc
    # (visibility_terms.light_cap_visible: the disc's area beyond a boundary θ from its centre)
    p = pos[under].astype(np.float64)
    axis = LIGHT - p
    dist = np.linalg.norm(axis, axis=1)
    sa = RADIUS / dist
    alpha = np.arcsin(sa)
    th_h = np.arcsin(axis[:, 1] / dist)

    def cap(th):
        th = np.clip(th, -alpha, alpha)
        u = np.clip(np.sin(th) / sa, -1, 1)
        c = np.sqrt(1 - sa * sa)
        v = np.clip(-np.tan(th) * c / sa, -1, 1)
        return 2 * (math.pi - np.arccos(u) - c * np.arccos(v)) / (2 * math.pi * sa * sa / (1 + c))

    ours = np.clip(cap(th_h + deficit[under]) / cap(th_h), 0, 1)
    truth = _slab_fraction(p)
    assert truth.min() < 0.05, "the bar's umbra is reached"
    assert np.abs(ours - truth).max() < 0.12 and np.abs(ours - truth).mean() < 0.04, (ours, truth)
    assert ci.occluders is not None

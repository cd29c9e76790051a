"""A moved frame recomputes only the moving vertices' cache rows it reads
(:mod:`warp_sg.renderer.moving_rows`: the vertices of the moving triangles its raster queued):
frames against a renderer that recomputes every moving row (``incremental_raster = False``: no
kept queue of the moving part), bit for bit, through moves and camera moves that show the side
the last frames did not — each row it reads holds the current transforms."""
from __future__ import annotations

import numpy as np
from motion_helpers import apply_step

import warp_sg as ws
from warp_sg.numeric.rigid_motion import motion_about, rotation_about
from warp_sg.scene.plain_scenes import write_plain_scene


def _scene(tmp_path, bounces: int = 0):
    # bounces = 0: light that bounces shades every vertex's direct light each moved frame (the senders),
    # so it reads every row; the rows a frame reads alone are the direct light's
    rs = {"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 4000, "bounces": bounces}
    return ws.load_scene(write_plain_scene(tmp_path, obj="blob", size=48, render=rs, dynamic=True))


def _turn(deg: float) -> np.ndarray:
    return motion_about(rotation_about([0.0, 1.0, 0.0], deg), [0.0, 0.5, 0.0])


def test_frames_that_compute_only_the_rows_they_read_equal_frames_that_compute_all(tmp_path):
    a = ws.Renderer(_scene(tmp_path / "a"))
    b = ws.Renderer(_scene(tmp_path / "b"))
    b.incremental_raster = False
    o = np.asarray(a.scene.camera.origin, np.float64)
    t = np.asarray(a.scene.camera.target, np.float64)
    behind = tuple(t + (t - o) * np.array([1.0, -1.0, 1.0]) + [0.0, 2.0 * (o - t)[1], 0.0])  # the other side
    steps = [("move", _turn(40.0)), ("camera", behind), ("move", _turn(75.0)), ("camera", tuple(o)),
             ("camera", behind), ("move", np.eye(4)), ("camera", tuple(o))]
    first = None
    for kind, value in [("none", None)] + steps:
        for r in (a, b):
            apply_step(r, kind, value)
        ia, ib = a.render().copy(), b.render().copy()
        assert np.array_equal(ia, ib), kind
        first = ia if first is None else first
    assert np.array_equal(ia, first)  # back at the rest pose and the first camera: the first frame
    n = int(a.dynamic.all_ids.shape[0])
    # (a frame read part of the rows: fewer computed than the renderer that computes them all)
    assert a.dynamic.rows.computed < 0.8 * b.dynamic.rows.computed
    assert b.dynamic.rows.computed >= 3 * n  # (its moves: every row of each of the three caches it patches)


def test_with_light_that_bounces_moved_frames_equal_frames_that_compute_every_row(tmp_path):
    # the bounces read every vertex's direct light: a frame computes every row it needs for them
    a = ws.Renderer(_scene(tmp_path / "a", bounces=2))
    b = ws.Renderer(_scene(tmp_path / "b", bounces=2))
    b.incremental_raster = False
    for kind, value in [("none", None), ("move", _turn(40.0)), ("move", np.eye(4))]:
        for r in (a, b):
            apply_step(r, kind, value)
        ia, ib = a.render().copy(), b.render().copy()
        assert np.array_equal(ia, ib), kind
        assert a.timings.get("bounces", 0) > 0  # (the bounces ran)

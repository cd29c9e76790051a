"""Frames after ``set_object_transform`` rasterise only the moving objects
(:mod:`warp_sg.renderer.moving_raster`): the part drawn over the static part's buffer
(``raster.rasterize(over=, tri_ids=)``), its sub-samples (``raster.subsample``, kept by pixel)
and the split contours (:mod:`warp_sg.renderer.antialias_cache`) against a raster of the whole
mesh — bit for bit, ties and clipped triangles included — and whole frames against a renderer
that rasterises everything every frame."""
from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from motion_helpers import apply_step

import warp_sg as ws
from warp_sg.numeric.rigid_motion import motion_matrix, rotation_about
from warp_sg.scene.plain_scenes import write_plain_scene


def _mesh(rng, n=300):
    """Random triangles in front of a camera at the origin looking down −Z: some cross the near
    plane (clipped into several pieces), some are exact copies of others (equal 1/w: the tie goes
    to the lower id), many overlap."""
    c = rng.uniform([-1.5, -1.5, -6.0], [1.5, 1.5, -1.0], size=(n, 1, 3))
    V = (c + rng.normal(scale=0.5, size=(n, 3, 3))).reshape(-1, 3)
    V[:12] = np.array([[-0.3, -0.2, 0.5], [0.4, -0.3, -3.0], [0.0, 0.5, -2.5]] * 4) + rng.normal(scale=0.05,
                                                                                                 size=(12, 3))
    T = np.arange(3 * n).reshape(-1, 3)
    T = np.concatenate([T, T[40:70]])  # copies: the same 1/w at every pixel
    return V.astype(np.float32), T.astype(np.int32)


def _split_raster(V, T, cam, part, cull, a, device):
    import raster

    ids = [np.flatnonzero(~part).astype(np.int32), np.flatnonzero(part).astype(np.int32)]
    bufs = []
    for sel in ids:
        flags = cull if isinstance(cull, bool) else cull[sel]
        bufs.append(raster.rasterize(V, T[sel], cam, device=device, subsamples=a, cull_backfaces=flags,
                                     tri_ids=wp.array(sel, dtype=wp.int32, device=device),
                                     over=bufs[-1] if bufs else None))
    return bufs


@pytest.mark.parametrize("seed, cull", [(0, False), (1, True), (2, "flags")])
def test_a_part_drawn_over_the_others_equals_a_raster_of_the_union(seed, cull, device):
    import raster
    from raster.subsample import KeptSubsamples, subsample

    rng = np.random.default_rng(seed)
    V, T = _mesh(rng)
    cam = raster.Camera(origin=(0, 0, 0), target=(0, 0, -1), up=(0, 1, 0), fov=60.0, width=72, height=56,
                        near=0.3, far=50.0)
    if cull == "flags":
        cull = rng.random(len(T)) < 0.5
        cull[len(T) - 30:] = cull[40:70]  # (a copy culled as its original)
    part = rng.random(len(T)) < 0.4
    part[40:70] = True  # the originals of the copies in one part, the copies in the other
    part[len(T) - 30:] = False
    full = raster.rasterize(V, T, cam, device=device, subsamples=4, cull_backfaces=cull)
    static, moving = _split_raster(V, T, cam, part, cull, 4, device)
    assert full.stats["clipped_extra"] > 0
    assert moving._over is static
    for name in ("tri_id", "bary", "inv_depth"):
        a, b = getattr(moving, name).numpy(), getattr(full, name).numpy()
        assert np.array_equal(a, b), name
    tri = full.tri_id.numpy()
    assert np.isin(np.arange(40, 70), tri).any() and not np.isin(np.arange(len(T) - 30, len(T)), tri).any()
    # sub-samples: walking both queues, and the static part's kept by pixel under the moving one
    kept = KeptSubsamples(static)
    for _ in range(3):
        pix = np.sort(rng.choice(72 * 56, size=400, replace=False)).astype(np.int32)
        idx = wp.array(pix, dtype=int, device=device)
        want = subsample(full, idx)
        for got in (subsample(moving, idx), subsample(moving, idx, kept=kept)):
            for x, y in zip(got[:3], want[:3]):
                assert np.array_equal(x.numpy(), y.numpy())
    assert kept.computed < 3 * 400  # (pixels listed again were copied, not computed)


def test_a_part_drawn_again_over_the_same_buffer_restores_only_the_rows_it_drew(device):
    """The moving part drawn again over the same static buffer, reusing its last buffer's arrays
    (``rasterize(over=, reuse=)`` copies back only the rows of the tiles the last draw queued):
    after each of a sequence of moves — across the image, off it (nothing drawn), back, and to
    rows the previous draw never touched — the same buffers and sub-samples as a raster of the
    whole mesh, bit for bit."""
    import raster
    from raster.subsample import subsample

    rng = np.random.default_rng(5)
    V, T = _mesh(rng, n=200)
    cam = raster.Camera(origin=(0, 0, 0), target=(0, 0, -1), up=(0, 1, 0), fov=60.0, width=80, height=64,
                        near=0.3, far=50.0)
    part = np.zeros(len(T), bool)
    part[150:200] = True
    ids = [wp.array(np.flatnonzero(sel).astype(np.int32), dtype=wp.int32, device=device) for sel in (~part, part)]
    static = raster.rasterize(V, T[~part], cam, device=device, subsamples=4, tri_ids=ids[0])
    moving_v = np.unique(T[part])
    rest = V[moving_v].copy()
    last, drawn = None, []
    for shift in ([0.0, 0.0, 0.0], [0.0, 1.2, 0.0], [40.0, 0.0, 0.0], [0.0, -1.3, 0.0], [0.6, 0.3, 0.5],
                  [0.0, 0.0, 0.0]):
        V[moving_v] = rest + np.asarray(shift, np.float32)
        full = raster.rasterize(V, T, cam, device=device, subsamples=4)
        b = raster.rasterize(V, T[part], cam, device=device, subsamples=4, tri_ids=ids[1], over=static, reuse=last)
        for name in ("tri_id", "bary", "inv_depth"):
            assert np.array_equal(getattr(b, name).numpy(), getattr(full, name).numpy()), (shift, name)
        pix = wp.array(np.sort(rng.choice(80 * 64, size=300, replace=False)).astype(np.int32), dtype=int,
                       device=device)
        for x, y in zip(subsample(b, pix)[:3], subsample(full, pix)[:3]):
            assert np.array_equal(x.numpy(), y.numpy())
        last = b
        drawn.append(b._drawn_rows)
    # (the copy of a part of the rows was exercised: a band, and nothing when the part was off the image)
    assert (0, 0) in drawn and any(0 < y1 - y0 < 64 for y0, y1 in drawn), drawn


def _scene(tmp_path, obj="sphere", size=40):
    rs = {"ssdf_resolution": 16, "pca_terms": 16, "visibility_budget": 4000}
    return ws.load_scene(write_plain_scene(tmp_path, obj=obj, size=size, render=rs, dynamic=True))


def _roll(x: float, z: float = 0.0, radius: float = 0.5) -> np.ndarray:
    c = np.array([0.0, radius, 0.0])
    R = rotation_about([0.0, 0.0, -1.0], np.degrees(x / radius))
    return motion_matrix(R, c - R @ c + [x, 0.0, z])


def test_frames_that_rasterise_only_the_moving_objects_equal_full_rasters(tmp_path):
    """The same scene in two renderers, one rasterising everything every frame
    (``incremental_raster = False``): after each move, a camera move, the ball off the image and
    an antialiased frame, the visibility buffers, the contour marks and the images are equal bit
    for bit; the static objects were rasterised once per camera."""
    a = ws.Renderer(_scene(tmp_path / "a"))
    b = ws.Renderer(_scene(tmp_path / "b"))
    b.incremental_raster = False
    away = np.eye(4)
    away[:3, 3] = [400.0, 0.0, 0.0]
    o = np.asarray(a.scene.camera.origin, np.float64)
    steps = [("move", _roll(0.6, 0.2)), ("move", _roll(-0.4)), ("camera", tuple(o + [0.3, -0.1, 0.2])),
             ("move", _roll(1.2, -0.5)), ("move", away), ("move", _roll(0.1))]
    for kind, value in [("none", None)] + steps:
        for r in (a, b):
            apply_step(r, kind, value)
        ia, ib = a.render().copy(), b.render().copy()
        assert np.array_equal(ia, ib), kind
        for name in ("tri_id", "bary", "inv_depth"):
            assert np.array_equal(getattr(a._vb, name).numpy(), getattr(b._vb, name).numpy()), (kind, name)
        assert np.array_equal(a._aa._contours[2].numpy(), b._aa._contours[2].numpy()), kind
    assert a.dynamic.raster.counts["static"] == 2  # the first camera and the moved one
    assert a.dynamic.raster.counts["moving"] == len(steps) + 1

r"""Dask distributed back end: connecting to a cluster, batch renders and the split Monte-Carlo reference.

Every function here takes ``cluster``: a spec string (``"local"``, ``"local:N"``, a scheduler
address ``"tcp://host:8786"``), a ``distributed.Client``, a ``distributed`` cluster object, or
``None`` (= ``"local"``: a :class:`distributed.LocalCluster` of one single-threaded worker process
per usable core). Dask is imported only inside these functions, so the library and the CLI never
import it unless ``--cluster`` (or this API) is used. The SSDF precompute on a cluster is in
:mod:`warp_sg.distributed.precompute`; the ``warp-sg batch`` job files in :mod:`warp_sg.distributed.batch`.
docs/distributed.md describes real clusters (Slurm/PBS via dask-jobqueue, Kubernetes, GPU
workers with worker resources).

Faults (issue 16):

* every task is a pure function of its arguments (idempotent) and is submitted with ``retries``; a
  worker that dies mid-task has its task re-run elsewhere by the scheduler, so the result is the
  same as an uninterrupted run (nothing is written by workers: the client writes the cache and
  the frames, atomically);
* an unreachable scheduler, a scheduler without workers and a worker of another warp-sg version
  are refused at connect with one line (:mod:`warp_sg.distributed.cluster`).

Batch renders (:func:`render_many`): the client builds the precompute once (refinement and
SSDFs, the SSDFs themselves on the cluster), scatters it and the scene to every worker, and each
task renders one *variant* (camera / material / light / environment changes, dynamic objects'
transforms; see
:func:`normalize_variants`) with a worker-local :class:`~warp_sg.renderer.renderer.Renderer` built from the
scattered precompute and changed through its setters, so no precompute runs per frame.

Monte-Carlo reference (:func:`render_reference_distributed`): the samples 0..spp−1 are split into
ranges; a task returns the per-sub-pixel float64 sums Σ L and Σ L² of its range (the kernel's RNG
stream depends only on the seed, the sample index and the pixel, not on who draws it). The client
adds the sums in sample order and resolves mean and variance exactly as the local run
(``reference._resolve``: s² = (Σ L²/N − mean²)·N/(N−1), pooled over all N samples), so the merged
variance is the variance of the whole sample set, not an average of per-chunk variances. Chunks are
cut at the local run's pass boundaries and summed in order, so the result equals the local one
bit for bit.
"""
from __future__ import annotations

import copy
import itertools
import uuid

import numpy as np

from warp_sg.core.errors import InputError
from warp_sg.distributed.cluster import (
    RETRIES,
    connect,
    ensure_version,
    gather_in_order,
    project_version,
    worker_object,
)

# --------------------------------------------------------------------------------------------
# batch renders
# --------------------------------------------------------------------------------------------
_CAMERA_KEYS = ("origin", "target", "up", "fov", "width", "height")
_LIGHT_KEYS = ("position", "direction", "radius", "intensity")
_ENV_KEYS = ("rotation", "scale")


def _base_value(scene, section, name, key):
    where = f"variant {section}" + (f".{name}" if name is not None else "") + f".{key}"
    if section == "camera":
        if key not in _CAMERA_KEYS:
            raise InputError(f"unknown camera field (use {', '.join(_CAMERA_KEYS)})", where=where)
        return getattr(scene.camera, key)
    if section == "materials":
        if name not in scene.materials:
            raise InputError(f"unknown material (the scene has {', '.join(scene.materials)})", where=where)
        m = scene.materials[name]
        if key in m.params:
            return m.params[key]
        if key in m.textures:
            return m.textures[key]
        if key in ("normal_map", "tangent_map"):
            return getattr(m, key)
        raise InputError("the material has no such parameter", where=where)
    if section == "lights":
        lights = scene.local_lights
        if not 0 <= name < len(lights):
            raise InputError(f"no local light #{name} (the scene has {len(lights)})", where=where)
        if key not in _LIGHT_KEYS or not hasattr(lights[name], key):
            raise InputError("the light has no such field", where=where)
        return getattr(lights[name], key)
    if section == "environment":
        if scene.environment is None:
            raise InputError("the scene has no environment light", where=where)
        if key not in _ENV_KEYS:
            raise InputError(f"unknown environment field (use {', '.join(_ENV_KEYS)})", where=where)
        return getattr(scene.environment, key)
    if section == "objects":  # a dynamic object's motion (warp_sg.numeric.rigid_motion.motion_from_fields)
        from warp_sg.core.errors import SceneError
        from warp_sg.numeric.rigid_motion import MOTION_FIELDS
        from warp_sg.renderer.dynamic_objects import object_index

        try:
            k = object_index(scene, name)
        except SceneError as e:
            raise InputError(str(e).split(": ", 1)[-1], where=where) from None
        if not scene.objects[k].dynamic:
            raise InputError("the object is not dynamic (give its [[objects]] table dynamic = true)", where=where)
        if key not in MOTION_FIELDS:
            raise InputError(f"unknown object field (use {', '.join(MOTION_FIELDS)})", where=where)
        return {"matrix": np.eye(4).tolist(), "scale": 1.0}.get(key, [0.0, 0.0, 0.0])
    raise InputError("unknown variant section (use camera, materials, lights, environment, objects)",
                     where=f"variant {section}")


def _items(variant):
    """(section, name, key, value) of a variant dict."""
    if not isinstance(variant, dict):
        raise InputError(f"a variant must be a table/dict, got {variant!r}", where="variant")
    for section, body in variant.items():
        if not isinstance(body, dict):
            raise InputError(f"must be a table/dict, got {body!r}", where=f"variant {section}")
        if section in ("camera", "environment"):
            for k, v in body.items():
                yield section, None, k, v
        elif section in ("materials", "lights", "objects"):
            for name, fields in body.items():
                if section == "lights":
                    try:
                        name = int(name)
                    except (TypeError, ValueError):
                        raise InputError(f"light keys are indices of the local lights, got {name!r}",
                                         where="variant lights") from None
                if not isinstance(fields, dict):
                    raise InputError(f"must be a table/dict, got {fields!r}", where=f"variant {section}.{name}")
                for k, v in fields.items():
                    yield section, name, k, v
        else:
            _base_value(None, section, None, None)


def normalize_variants(scene, variants) -> list[dict]:
    """Full-state variants: every field any variant changes, set in every variant (its base
    value from ``scene`` where a variant leaves it alone), so a worker renderer can apply them in
    any order. A variant is a dict with any of::

        {"camera": {"origin": (x, y, z), "target": ..., "up": ..., "fov": deg, "width": W, "height": H},
         "materials": {"NAME": {"PARAM": value, ...}},
         "lights": {INDEX: {"position" | "direction" | "radius" | "intensity": value}},  # local lights
         "environment": {"rotation": degrees, "scale": s},
         "objects": {"NAME": {"translate" | "rotate" | "scale" | "pivot" | "matrix": value}}}  # dynamic ones

    Geometry and render settings are shared by the whole batch (one precompute)."""
    variants = list(variants)
    touched = {}
    for v in variants:
        for section, name, key, _ in _items(v):
            touched[(section, name, key)] = _base_value(scene, section, name, key)
    out = []
    for v in variants:
        full = {}
        given = {(s, n, k): val for s, n, k, val in _items(v)}
        for (section, name, key), base in touched.items():
            val = given.get((section, name, key), base)
            full.setdefault(section, {})
            if name is None:
                full[section][key] = val
            else:
                full[section].setdefault(name, {})[key] = val
        out.append(full)
    return out


def check_variants(scene, variants, where: str = "batch") -> None:
    """Every value of every variant checked against ``scene`` before any work (no Dask, no
    renderer): camera fields, material parameters (:meth:`warp_sg.scene.model.Material.updated`),
    light and environment records, dynamic objects' motions (rigid, and within the coordinates
    the renderer shades: :func:`warp_sg.scene.geometry.check_moved_extent`). The first bad value is
    one :class:`InputError` line ``<where>: frame <i>: ...``."""
    from dataclasses import replace

    from warp_sg.numeric.rigid_motion import check_motion, motion_from_fields

    boxes = {}
    for i, v in enumerate(variants):
        at = f"{where}: frame {i}"
        try:
            for section, name, key, _ in _items(v):
                _base_value(scene, section, name, key)
            if v.get("camera"):
                replace(scene.camera, **v["camera"])
            for name, params in v.get("materials", {}).items():
                scene.materials[name].updated(name, **params)
            lights = scene.local_lights
            for index, fields in v.get("lights", {}).items():
                replace(lights[int(index)], **fields)
            if v.get("environment"):
                replace(scene.environment, **v["environment"])
            for name, fields in v.get("objects", {}).items():
                M = motion_from_fields(fields, where=f"objects.{name}")
                check_motion(M, where=f"objects.{name}")
                if name not in boxes:
                    boxes[name] = _object_box(scene, name)
                from warp_sg.scene.geometry import check_moved_extent

                check_moved_extent(boxes[name], M, f"objects.{name}")
        except (InputError, TypeError) as e:
            raise InputError(str(e) if isinstance(e, InputError) else f"bad variant ({e})", where=at) from None


def _object_box(scene, name) -> np.ndarray:
    """The corners of object ``name``'s box in its rest pose (the scene as loaded)."""
    from warp_sg.renderer.dynamic_objects import object_index
    from warp_sg.scene.culling import box_corners

    g = scene.geometry()
    v = np.asarray(g.vertices, np.float64)[np.asarray(g.vertex_object) == object_index(scene, name)]
    return box_corners(v.min(0), v.max(0))


def apply_variant(renderer, variant: dict) -> None:
    """Apply a (full-state) variant through the renderer's setters (no precompute is re-run)."""
    if "camera" in variant:
        renderer.set_camera(**variant["camera"])
    for name, params in variant.get("materials", {}).items():
        renderer.set_material(name, **params)
    for index, fields in sorted(variant.get("lights", {}).items()):
        renderer.update_light(int(index), **fields)
    env = variant.get("environment", {})
    if "rotation" in env:
        renderer.set_environment_rotation(float(env["rotation"]))
    if "scale" in env:
        renderer.set_environment_scale(float(env["scale"]))
    for name, fields in variant.get("objects", {}).items():
        from warp_sg.numeric.rigid_motion import motion_from_fields

        if "matrix" in fields and len(fields) > 1:  # (full state: the base values of the other form)
            ident = np.array_equal(np.asarray(fields["matrix"], np.float64), np.eye(4))
            fields = {k: v for k, v in fields.items() if (k == "matrix") != ident}
        renderer.set_object_transform(name, motion_from_fields(fields, where=f"objects.{name}"))


def _render_variant(scene, pre, token, variant, device, version):
    """Task: one frame of a batch (pure: the same arguments give the same image)."""
    ensure_version(version)
    from warp_sg.renderer.renderer import Renderer

    with worker_object(token, lambda: Renderer(copy.deepcopy(scene), device, precomputed=pre)) as r:
        apply_variant(r, variant)
        return r.render()


def render_many(scene, variants, cluster=None, *, device=None, progress: bool = True, on_frame=None,
                retries: int = RETRIES, resources: dict | None = None) -> list:
    """Render ``scene`` once per variant on a Dask cluster; returns the (H, W, 3) float32 images in
    variant order. ``on_frame(index, image)`` is called on the client as each frame arrives (in
    completion order), e.g. to write it atomically. ``resources`` (e.g. ``{"GPU": 1}``) restricts
    the render tasks to workers that declare them. The precompute (refinement, SSDFs with the
    SSDFs themselves computed on the cluster) is built once on the client and scattered."""
    from warp_sg.distributed.precompute import DaskSSDF
    from warp_sg.renderer.renderer import Renderer

    check_variants(scene, variants)  # every value, before Dask starts (a worker would fail it, with retries)
    variants = normalize_variants(scene, variants)
    if not variants:
        return []
    with connect(cluster) as client:
        # built on ``scene`` itself: the scene then carries its loaded meshes, textures and
        # environment map when it is scattered, so workers need none of its files
        base = Renderer(scene, device, progress=progress,
                        ssdf_compute=DaskSSDF(client, retries=retries, resources=resources))
        device = base.device
        scene_f = client.scatter([scene], broadcast=True)[0]
        pre_f = client.scatter([base.precomputed()], broadcast=True)[0]
        token = uuid.uuid4().hex
        version = project_version()
        futs = [client.submit(_render_variant, scene_f, pre_f, token, v, device, version, retries=retries,
                              key=f"warp-sg-frame-{token}-{i}", resources=resources)
                for i, v in enumerate(variants)]
        bar = _bar(len(futs), "frames", "frame", progress)
        try:
            return gather_in_order(futs, bar, on_frame)
        finally:
            if bar is not None:
                bar.close()


def _bar(total, desc, unit, enabled):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit, leave=False)


# --------------------------------------------------------------------------------------------
# Monte-Carlo reference, samples split across workers
# --------------------------------------------------------------------------------------------
def local_passes(start: int, stop: int, cap: int = 64):
    """The local run's pass schedule (``reference.render_reference_inputs``: 1, 1, 2, 4, … capped at
    ``cap``) restricted to samples ``[start, stop)``: ``[(offset, n), ...]``."""
    out, done = [], 0
    while done < stop:
        n = min(max(done, 1), cap, stop - done)
        if done >= start:
            out.append((done, n))
        done += n
    return out


def sample_chunks(spp: int, chunk_spp: int = 64):
    """Sample ranges ``[(start, stop)]`` covering ``0..spp`` cut at local pass boundaries, each
    about ``chunk_spp`` samples."""
    chunks, cur, size = [], None, 0
    for off, n in local_passes(0, spp):
        if cur is None:
            cur, size = off, 0
        size += n
        if size >= chunk_spp:
            chunks.append((cur, off + n))
            cur = None
    if cur is not None:
        chunks.append((cur, spp))
    return chunks


def _reference_chunk(inputs, token, start, stop, seed, device, version, max_depth):
    """Task: float64 sums Σ L and Σ L² per sub-pixel over samples ``[start, stop)`` (paths of at
    most ``max_depth`` segments)."""
    ensure_version(version)
    from warp_sg.groundtruth.reference import _Prepared

    with worker_object(token, lambda: _Prepared(inputs, device)) as prep:
        acc = np.zeros((prep.n, 3))
        acc2 = np.zeros((prep.n, 3))
        for off, n in local_passes(start, stop):
            s, s2 = prep.launch_pass(n, int(seed), off, 1, max_depth)
            acc += s
            acc2 += s2
        return acc, acc2


def render_reference_distributed(scene, spp: int = 256, cluster=None, *, device=None, seed: int = 0,
                                 progress: bool = True, chunk_spp: int = 64, retries: int = RETRIES,
                                 max_depth: int | None = None):
    """:func:`warp_sg.groundtruth.reference.render_reference` with its samples split across a Dask cluster
    (equal to the local result bit for bit; see the module docstring). ``max_depth``: the paths'
    most segments (default the reference's full depth; 2: direct light only)."""
    import time

    from warp_sg.core.device import resolve_device
    from warp_sg.groundtruth.reference import (
        DEFAULT_MAX_DEPTH,
        ReferenceInputs,
        ReferenceResult,
        _resolve,
        check_max_depth,
        inputs_from_scene,
    )

    max_depth = check_max_depth(DEFAULT_MAX_DEPTH if max_depth is None else max_depth)
    spp = int(spp)
    if spp < 1:
        raise InputError(f"spp must be >= 1, got {spp}", where="--spp")
    t0 = time.perf_counter()
    device = resolve_device(device if device is not None else
                            (scene.render.device if not isinstance(scene, ReferenceInputs) else "cpu"))
    inp = scene if isinstance(scene, ReferenceInputs) else inputs_from_scene(scene, device)
    k = int(inp.supersample)
    kh, kw = inp.ray_directions.shape[:2]
    if kh % k or kw % k:
        raise InputError(f"ray grid {kh}x{kw} is not a multiple of supersampling {k}", where="supersample")
    chunks = sample_chunks(spp, chunk_spp)
    with connect(cluster) as client:
        inp_f = client.scatter([inp], broadcast=True)[0]
        token = uuid.uuid4().hex
        version = project_version()
        futs = [client.submit(_reference_chunk, inp_f, token, s, e, int(seed), device, version, max_depth, retries=retries,
                              key=f"warp-sg-reference-{token}-{s}") for s, e in chunks]
        bar = _bar(len(futs), "reference", "chunk", progress)
        try:
            parts = gather_in_order(futs, bar)
        finally:
            if bar is not None:
                bar.close()
    acc = np.zeros((kh * kw, 3))
    acc2 = np.zeros((kh * kw, 3))
    history = []
    for (_, e), (a, a2) in zip(chunks, parts):  # in sample order: the local run's summation order
        acc += a
        acc2 += a2
        history.append((e, time.perf_counter() - t0))
    img, se = _resolve(acc, acc2, spp, (kh, kw), k)
    return ReferenceResult(img, se, spp, time.perf_counter() - t0, len(chunks), history)


def grid_variants(grid: dict) -> list[dict]:
    """Variants of every combination of ``{"section.name.key": [values...]}`` (dotted keys, the
    last one varying fastest), e.g. ``{"camera.fov": [30, 40], "materials.metal.m": [0.1, 0.3]}``."""
    keys = list(grid)
    for k in keys:
        if not isinstance(grid[k], (list, tuple)) or not grid[k]:
            raise InputError("must be a non-empty list of values", where=f"grid {k}")
    return [dotted_variant(dict(zip(keys, combo))) for combo in itertools.product(*(grid[k] for k in keys))]


def dotted_variant(values: dict) -> dict:
    """``{"camera.fov": 30, "lights.0.radius": 0.1}`` → the nested variant dict."""
    out: dict = {}
    for dotted, v in values.items():
        parts = str(dotted).split(".")
        if parts[0] in ("camera", "environment") and len(parts) == 2:
            out.setdefault(parts[0], {})[parts[1]] = v
        elif parts[0] in ("materials", "lights", "objects") and len(parts) == 3:
            out.setdefault(parts[0], {}).setdefault(parts[1], {})[parts[2]] = v
        else:
            raise InputError("expected camera.FIELD, environment.FIELD, materials.NAME.PARAM, lights.INDEX.FIELD or "
                             "objects.NAME.FIELD",
                             where=f"key {dotted!r}")
    return out


__all__ = ["RETRIES", "connect", "project_version", "render_many", "normalize_variants", "apply_variant",
           "render_reference_distributed", "sample_chunks", "local_passes", "grid_variants",
           "dotted_variant", "gather_in_order", "worker_object"]

"""Dask back end (issue 16) on a LocalCluster of 2 single-threaded worker processes.

The distributed results are compared with independent local runs of the same work: the SSDFs
with ``precompute.compute_ssdf`` / ``ssdf_for_mesh`` on this process (bit for bit: a vertex's SSDF
does not depend on the chunk it is computed in), a batch of frames with 8 fresh local renderers
of scenes edited directly (not through the renderer's setters the workers use), the split
Monte-Carlo reference with the local progressive run (bit for bit: same RNG streams, chunks cut
at the local pass boundaries and summed in the same order).
"""
from __future__ import annotations

import copy
import dataclasses
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from distributed import Client, LocalCluster

ROOT = Path(__file__).resolve().parents[1]

SCENE = """
[camera]
origin = [0.0, 1.0, 3.0]
target = [0.0, 0.3, 0.0]
fov = 35.0
width = 16
height = 12

[[objects]]
primitive = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
resolution = [8, 16]
material = "red"

[[objects]]
primitive = "plane"
size = [3.0, 3.0]
resolution = [6, 6]
material = "grey"

[materials.red]
model = "torrance_sparrow"
kd = [0.6, 0.1, 0.1]
ks = [0.4, 0.4, 0.4]
m = 0.3

[materials.grey]
model = "lambert"
kd = [0.6, 0.6, 0.6]

[[lights]]
type = "point"
position = [1.0, 2.0, 1.0]
radius = 0.2
intensity = [4.0, 4.0, 4.0]

[[lights]]
type = "environment"
procedural = "sky"

[render]
ssdf_resolution = 8
pca_terms = 4
visibility_budget = 0
env_lobes = 2
gamma_resolution = 8
gamma_levels = 3
"""


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("dask")
    old = os.environ.get("WARP_SG_CACHE_DIR")
    os.environ["WARP_SG_CACHE_DIR"] = str(d / "cache")
    (d / "scene.toml").write_text(SCENE)
    yield d
    if old is None:
        os.environ.pop("WARP_SG_CACHE_DIR", None)
    else:
        os.environ["WARP_SG_CACHE_DIR"] = old


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR, env={"WARP_SG_THREADS": "1"}) as c:
        yield c


@pytest.fixture(scope="module")
def client(cluster):
    with Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def mesh():
    from warp_sg.tools import bench_precompute as pb

    return pb.bench_mesh(300)


def _fresh_cache(workdir, name):
    d = workdir / name
    os.environ["WARP_SG_CACHE_DIR"] = str(d)
    return d


def test_distributed_ssdfs_equal_local_ones_bitwise_and_are_the_same_cache_entry(client, mesh, workdir):
    from precompute.visibility.ssdf import compute_ssdf, ssdf_for_mesh
    from warp_sg.core.cache import entry_path, load
    from warp_sg.distributed.precompute import DaskSSDF

    V, F, N = mesh
    local_raw = compute_ssdf(V, F, N, resolution=8, ray_resolution=16, progress=False)
    dask = DaskSSDF(client, chunk=37)  # chunks that do not line up with the local batches
    raw = dask(V, F, N, resolution=8, ray_resolution=16, progress=False)
    assert raw.dtype == np.float32 and raw.shape == local_raw.shape == (len(V), 8, 8)
    assert np.array_equal(raw, local_raw)
    assert dask.stats["tasks"] == -(-len(V) // 37) and dask.stats["bytes_per_chunk"] == 37 * 64 * 4
    ids = np.array([5, len(V) - 1, 0, 17, 150])
    assert np.array_equal(dask(V, F, N, resolution=8, ray_resolution=16, progress=False, vertex_ids=ids),
                          local_raw[ids])

    _fresh_cache(workdir, "cache-local")
    loc = ssdf_for_mesh(V, F, N, resolution=8, pca_terms=4, progress=False)
    _fresh_cache(workdir, "cache-dask")
    dist = ssdf_for_mesh(V, F, N, resolution=8, pca_terms=4, progress=False, compute=dask)
    assert dist.key == loc.key and entry_path("ssdf", dist.key).is_file()
    for name in ("mean", "basis", "weights"):
        assert np.array_equal(getattr(dist, name), getattr(loc, name)), name
    entry = load("ssdf", dist.key)  # the client wrote a complete, verified entry (the maps: their PCA on use)
    assert entry is not None and np.array_equal(entry["maps"], loc.maps) and np.array_equal(entry["cones"], loc.cones)


def test_a_worker_killed_mid_chunk_leaves_the_result_identical(client, mesh, workdir):
    """One worker process dies (os._exit) in the middle of its first SSDF chunk, once (a marker
    file); the scheduler re-runs the chunk elsewhere and the cache entry is the uninterrupted one."""
    from precompute.visibility.ssdf import ssdf_for_mesh
    from warp_sg.core.cache import load
    from warp_sg.distributed.precompute import DaskSSDF

    marker = str(workdir / "killed-once")

    def install(marker=marker):
        import os as _os

        import warp_sg.distributed.precompute as dp

        real = dp._ssdf_rows

        def dying(*a, **k):
            out = real(*a, **k)  # part of the chunk is done ...
            try:
                fd = _os.open(marker, _os.O_CREAT | _os.O_EXCL | _os.O_WRONLY)
            except FileExistsError:
                return out
            _os.close(fd)
            _os._exit(1)  # ... and the worker process dies before the task returns

        dp._ssdf_rows = dying

    V, F, N = mesh
    _fresh_cache(workdir, "cache-kill-ref")
    want = ssdf_for_mesh(V, F, N, resolution=8, pca_terms=4, progress=False)
    client.run(install)
    _fresh_cache(workdir, "cache-kill")
    got = ssdf_for_mesh(V, F, N, resolution=8, pca_terms=4, progress=False,
                        compute=DaskSSDF(client, chunk=50))
    assert Path(marker).exists(), "no worker was killed"
    assert got.key == want.key
    for name in ("mean", "basis", "weights"):
        assert np.array_equal(getattr(got, name), getattr(want, name)), name
    entry = load("ssdf", got.key)
    assert entry is not None and np.array_equal(entry["maps"], want.maps)
    client.wait_for_workers(2, timeout=60)  # the nanny restarted the killed worker


VARIANTS = [
    {},
    {"camera": {"origin": (0.8, 1.2, 2.8)}},
    {"camera": {"fov": 45.0}},
    {"materials": {"red": {"m": 0.12}}},
    {"materials": {"grey": {"kd": (0.2, 0.5, 0.3)}}, "environment": {"rotation": 90.0}},
    {"lights": {0: {"position": (-1.0, 1.5, 1.0)}}},
    {"environment": {"scale": 0.5}},
    {"camera": {"origin": (-0.5, 0.8, 3.2)}, "lights": {0: {"intensity": (1.0, 2.0, 3.0)}},
     "materials": {"red": {"ks": (0.1, 0.1, 0.1)}}},
]


def _edited_scene(scene, variant):
    """The variant applied to a copy of the scene's own data (independent of the setters)."""
    sc = copy.deepcopy(scene)
    if "camera" in variant:
        sc.camera = dataclasses.replace(sc.camera, **variant["camera"])
    for name, params in variant.get("materials", {}).items():
        sc.materials[name].params.update(params)
        sc.materials[name].invalidate()
    from warp_sg.scene.lights import EnvironmentLight

    local = [li for li in sc.lights if not isinstance(li, EnvironmentLight)]
    for i, fields in variant.get("lights", {}).items():
        new = dataclasses.replace(local[i], **fields)
        sc.lights[sc.lights.index(local[i])] = new
    env = sc.environment
    for k, v in variant.get("environment", {}).items():
        setattr(env, k, v)
    return sc


def test_a_batch_of_8_frames_equals_8_local_renders(cluster, workdir):
    import tomllib  # noqa: F401  (the job file below is TOML)

    from warp_sg.core.image_io import load_image
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.loader import load_scene
    from warp_sg.tools.cli import main

    _fresh_cache(workdir, "cache-batch")
    scene = load_scene(workdir / "scene.toml")
    want = [Renderer(_edited_scene(scene, v)).render() for v in VARIANTS]
    assert not np.array_equal(want[0], want[3])  # the variants change the image

    def toml_value(v):
        if isinstance(v, dict):
            return "{ " + ", ".join(f'"{k}" = {toml_value(x)}' for k, x in v.items()) + " }"
        if isinstance(v, (tuple, list)):
            return "[" + ", ".join(toml_value(x) for x in v) + "]"
        return repr(float(v))

    job = ['scene = "scene.toml"', 'output = "frames/f_{index:02d}.exr"']
    for v in VARIANTS:
        job.append("[[frames]]")
        job += [f"{section} = {toml_value(body)}" for section, body in v.items()]
    (workdir / "job.toml").write_text("\n".join(job) + "\n")
    rc = main(["batch", str(workdir / "job.toml"), "--cluster", cluster.scheduler_address, "--no-progress"])
    assert rc == 0
    frames = sorted((workdir / "frames").iterdir())
    assert [f.name for f in frames] == [f"f_{i:02d}.exr" for i in range(8)]  # no temporaries left
    for i, f in enumerate(frames):
        np.testing.assert_array_equal(load_image(f), want[i], err_msg=f.name)


def test_split_reference_equals_the_local_run_with_the_pooled_variance(client, workdir):
    from warp_sg.distributed.rendering import render_reference_distributed, sample_chunks
    from warp_sg.groundtruth.reference import render_reference
    from warp_sg.scene.loader import load_scene

    scene = load_scene(workdir / "scene.toml")
    scene.camera = dataclasses.replace(scene.camera, width=8, height=6)
    assert sample_chunks(70, 16) == [(0, 16), (16, 32), (32, 64), (64, 70)]
    loc = render_reference(scene, spp=70, progress=False, seed=3)
    dist = render_reference_distributed(scene, spp=70, cluster=client, seed=3, progress=False, chunk_spp=16)
    assert dist.spp == 70
    np.testing.assert_array_equal(dist.image, loc.image)
    np.testing.assert_array_equal(dist.stderr, loc.stderr)
    assert dist.stderr.max() > 0  # a real variance estimate, merged over the chunks


def test_a_worker_of_another_version_is_refused_naming_both_versions(client, cluster, workdir, capsys):
    import warp_sg
    from warp_sg.tools.cli import main

    def set_version(v):
        import warp_sg as w

        w.__version__ = v

    client.run(set_version, "0.0.0-other")
    try:
        rc = main(["precompute", str(workdir / "scene.toml"), "--cluster", cluster.scheduler_address,
                   "--no-progress"])
        err = capsys.readouterr().err.strip().splitlines()
    finally:
        client.run(set_version, warp_sg.__version__)
    assert rc == 2 and len(err) == 1, err
    assert "0.0.0-other" in err[0] and warp_sg.__version__ in err[0]


def _run_python(code, **env):
    e = dict(os.environ, PYTHONPATH=str(ROOT), **env)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=e, timeout=300)


def test_an_unreachable_scheduler_exits_2_with_one_line(workdir):
    r = _run_python("import sys; from warp_sg.tools.cli import main; "
                    f"sys.exit(main(['precompute', {str(workdir / 'scene.toml')!r}, '--cluster', "
                    "'tcp://127.0.0.1:1']))", WARP_SG_DASK_TIMEOUT="1")
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("warp-sg: error: --cluster: cannot reach the Dask scheduler at tcp://127.0.0.1:1")


def test_without_cluster_nothing_imports_dask(workdir):
    code = f"""
import sys
from warp_sg.tools.cli import build_parser, main
for cmd in ("render", "precompute", "batch", "report", "bench", "reference"):
    build_parser(cmd)
import warp_sg.distributed.rendering, warp_sg.distributed.precompute, warp_sg.distributed.batch, warp_sg.tools.report, warp_sg.tools.bench
rc = main(["render", {str(workdir / 'scene.toml')!r}, "-o", {str(workdir / 'nodask.png')!r}, "--no-progress"])
rc |= main(["precompute", {str(workdir / 'scene.toml')!r}, "--no-progress"])
bad = sorted(m for m in sys.modules if m.split(".")[0] in ("dask", "distributed"))
print("RC", rc, "DASK", bad)
"""
    r = _run_python(code, WARP_SG_CACHE_DIR=str(workdir / "cache-nodask"))
    assert "RC 0 DASK []" in r.stdout, r.stdout + r.stderr


@pytest.mark.parametrize("text, needle", [
    ('scene = "s.toml"\noutput = "f.png"\n[[frames]]\n', "{index}"),
    ('scene = "s.toml"\noutput = "f{index}.png"\n', "no frames"),
    ('scene = "s.toml"\noutput = "f{index}.png"\nspeed = 3\n[[frames]]\n', "unknown key"),
    ('scene = "s.toml"\noutput = "f{index}.png"\n[grid]\n"camera.fov" = 30\n', "non-empty list"),
    ('scene = "s.toml"\noutput = "f{index}.png"\n[grid]\n"fov" = [30]\n', "camera.FIELD"),
    ('scene = "s.toml"\noutput = "f{index}.png"\n[animate]\nframes = 0\n', "frames"),
])
def test_bad_job_files_name_the_key(tmp_path, text, needle):
    from warp_sg.core.errors import InputError
    from warp_sg.distributed.batch import load_job

    p = tmp_path / "job.toml"
    p.write_text(text)
    with pytest.raises(InputError) as e:
        load_job(p)
    assert needle in str(e.value), str(e.value)


def test_grid_and_animation_expand_to_the_expected_variants(tmp_path):
    from warp_sg.distributed.batch import load_job

    p = tmp_path / "job.toml"
    p.write_text('scene = "s.toml"\noutput = "out/f{index:03d}.png"\n'
                 '[grid]\n"camera.fov" = [30.0, 40.0]\n"materials.red.m" = [0.1, 0.2, 0.3]\n'
                 '[animate]\nframes = 3\n"environment.rotation" = [0.0, 90.0]\n'
                 '"camera.origin" = [[0.0, 0.0, 4.0], [4.0, 0.0, 0.0]]\n')
    job = load_job(p)
    assert len(job.variants) == 6 + 3
    assert job.variants[1] == {"camera": {"fov": 30.0}, "materials": {"red": {"m": 0.2}}}
    assert [v["environment"]["rotation"] for v in job.variants[6:]] == [0.0, 45.0, 90.0]
    assert job.variants[7]["camera"]["origin"] == [2.0, 0.0, 2.0]
    assert job.frame_path(7) == tmp_path / "out" / "f007.png"

r"""``warp-sg batch JOB.toml``: animations and parameter sweeps rendered on a Dask cluster.

A job file (paths relative to the job file)::

    scene = "scene.toml"                        # required
    output = "frames/frame_{index:04d}.png"     # required: .exr (linear) or .png (sRGB); {index}
    cluster = "local:2"                         # optional (default "local"); --cluster overrides
    device = "cpu"                              # optional (default: the scene's [render] device)
    exposure = 0.0                              # optional, stops, applied before writing

    [[frames]]                                  # explicit frames, each a variant:
    camera = { origin = [0.0, 1.6, 4.2], fov = 35.0 }
    environment = { rotation = 30.0, scale = 1.0 }
    [frames.materials.metal]                    # constant parameters of material "metal"
    m = 0.3
    [frames.lights.0]                           # local light #0 (scene order, point/directional)
    position = [1.0, 2.0, 1.0]

    [grid]                                      # every combination (the last key varies fastest)
    "camera.fov" = [30.0, 40.0]
    "materials.metal.m" = [0.1, 0.3]

    [animate]                                   # `frames` frames, each value linear from first to last
    frames = 24
    "environment.rotation" = [0.0, 345.0]
    "camera.origin" = [[0.0, 1.6, 4.2], [4.2, 1.6, 0.0]]

``[[frames]]``, ``[grid]`` and ``[animate]`` may be combined (in that order); the frame index runs
over all of them. Variant keys are those of :func:`warp_sg.distributed.rendering.normalize_variants`
(``camera.FIELD``, ``materials.NAME.PARAM``, ``lights.INDEX.FIELD``, ``environment.KEY`` with KEY rotation or scale);
geometry and ``[render]`` settings are shared by the batch (one precompute). Frames are written
atomically (``save_image``) as they finish, with a progress bar over frames; ``--skip-existing``
resumes an interrupted job. Bad job files raise :class:`~warp_sg.core.errors.InputError` naming the key.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError

_TOP_KEYS = ("scene", "output", "cluster", "device", "exposure", "frames", "grid", "animate")


@dataclass
class Job:
    scene: Path
    output: str
    variants: list
    cluster: str | None = None
    device: str | None = None
    exposure: float = 0.0
    path: Path | None = None

    def frame_path(self, index: int) -> Path:
        return Path(self.output.format(index=index))


def _lerp(a, b, t):
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    v = (1.0 - t) * a + t * b
    return v.tolist() if v.ndim else float(v)


def animate_variants(table: dict, where: str = "[animate]") -> list[dict]:
    """``frames`` variants with every dotted key's value linear from its first to its last entry."""
    from warp_sg.distributed.rendering import dotted_variant

    table = dict(table)
    n = table.pop("frames", None)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise InputError(f"'frames' must be an integer >= 1, got {n!r}", where=where)
    for k, v in table.items():
        if not isinstance(v, list) or len(v) < 2:
            raise InputError("must be a list [first, ..., last] of at least 2 values", where=f"{where} {k}")
        try:
            np.asarray(v[0], np.float64) + np.asarray(v[-1], np.float64)
        except (TypeError, ValueError):
            raise InputError("first and last values must be numbers or vectors of the same length",
                             where=f"{where} {k}") from None
    return [dotted_variant({k: _lerp(v[0], v[-1], i / max(n - 1, 1)) for k, v in table.items()}) for i in range(n)]


#: the widest field an ``output`` pattern may ask for (``{index:0999999999d}`` would build a
#: gigabyte file name before any check of its length)
MAX_FIELD_WIDTH = 32


def check_output_pattern(out: str, where: str) -> None:
    """``output`` must hold ``{index}`` (e.g. ``frame_{index:04d}.png``), format with an integer
    index, ask for a field at most :data:`MAX_FIELD_WIDTH` wide and give a file name of at most 255
    characters; else one :class:`InputError` line quoting the pattern (shortened)."""
    import re
    import string

    shown = repr(out) if len(out) <= 80 else repr(out[:77] + "...")
    if "{index" not in out:
        raise InputError(f"'output' must contain {{index}} (e.g. frame_{{index:04d}}.png), got {shown}", where=where)
    try:
        fields = [(f, spec) for _, f, spec, _ in string.Formatter().parse(out) if f is not None]
    except ValueError as e:
        raise InputError(f"bad 'output' pattern {shown} ({e})", where=where) from None
    for name, spec in fields:
        if name != "index":
            raise InputError(f"bad 'output' pattern {shown}: only {{index}} may be used, not {{{name}}}", where=where)
        width = max((int(w) for w in re.findall(r"\d+", spec or "")), default=0)
        if width > MAX_FIELD_WIDTH:
            raise InputError(f"bad 'output' pattern {shown}: a field {width} characters wide (at most "
                             f"{MAX_FIELD_WIDTH})", where=where)
    try:
        name = Path(out.format(index=0)).name
    except (KeyError, ValueError, IndexError, TypeError) as e:
        raise InputError(f"bad 'output' pattern {shown} ({e})", where=where) from None
    if len(name.encode("utf-8", "replace")) > 255:
        raise InputError(f"bad 'output' pattern {shown}: its file names are longer than 255 bytes", where=where)


def load_job(path) -> Job:
    """Read and check a job file (see the module docstring)."""
    import tomllib

    from warp_sg.distributed.rendering import grid_variants

    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise InputError("job file not found", where=str(path)) from None
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"not valid TOML ({e})", where=str(path)) from None
    except RecursionError:
        raise InputError("not valid TOML here: arrays or tables nested too deeply to read (a job file nests a "
                         "few levels)", where=str(path)) from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read the job file ({getattr(e, 'strerror', None) or e})", where=str(path)) from None
    where = str(path)
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)} (allowed: {', '.join(_TOP_KEYS)})", where=where)
    for k in ("scene", "output"):
        if not isinstance(data.get(k), str):
            raise InputError(f"'{k}' must be a string", where=where)
    base = path.parent
    out = data["output"]
    check_output_pattern(out, where)
    variants = []
    frames = data.get("frames", [])
    if not isinstance(frames, list) or not all(isinstance(f, dict) for f in frames):
        raise InputError("'frames' must be an array of tables ([[frames]])", where=where)
    variants += frames
    if "grid" in data:
        variants += grid_variants(data["grid"])
    if "animate" in data:
        variants += animate_variants(data["animate"], f"{where} [animate]")
    if not variants:
        raise InputError("the job has no frames (add [[frames]], [grid] or [animate])", where=where)
    exposure = data.get("exposure", 0.0)
    if isinstance(exposure, bool) or not isinstance(exposure, (int, float)):
        raise InputError(f"'exposure' must be a number, got {exposure!r}", where=where)
    for k in ("cluster", "device"):
        if k in data and not isinstance(data[k], str):
            raise InputError(f"'{k}' must be a string", where=where)
    output = out if Path(out).is_absolute() else str(base / out)
    return Job(scene=base / data["scene"], output=output, variants=variants, cluster=data.get("cluster"),
               device=data.get("device"), exposure=float(exposure), path=path)


def run_job(job: Job, cluster=None, device=None, progress: bool = True, skip_existing: bool = False) -> list[Path]:
    """Render a :class:`Job`; returns the frame paths (all frames, written or skipped)."""
    from warp_sg.core.files import check_output_path, make_parents
    from warp_sg.core.image_io import save_image
    from warp_sg.distributed.rendering import check_variants, normalize_variants, render_many
    from warp_sg.scene.loader import load_scene

    paths = [job.frame_path(i) for i in range(len(job.variants))]
    if len(set(paths)) != len(paths):
        raise InputError("'output' gives several frames the same file name", where=str(job.path or "job"))
    for p in paths:
        check_output_path(p, create_parents=True)
    scene = load_scene(job.scene)
    try:
        normalize_variants(scene, job.variants)  # every variant checked before any work
    except InputError as e:
        raise InputError(str(e), where=str(job.path or "job")) from None
    check_variants(scene, job.variants, where=str(job.path or "job"))  # and its values
    todo = [i for i, p in enumerate(paths) if not (skip_existing and p.exists())]
    scale = 2.0 ** job.exposure

    def write(k, img):
        p = paths[todo[k]]
        make_parents(p)
        save_image(p, img * scale if job.exposure else img)

    render_many(scene, [job.variants[i] for i in todo], cluster if cluster is not None else job.cluster,
                device=device or job.device, progress=progress, on_frame=write)
    return paths


def add_cli_arguments(p) -> None:
    from warp_sg.core.device import add_device_argument
    from warp_sg.distributed.cluster import add_cluster_argument

    p.add_argument("job", help="job file (TOML): scene, output pattern, [[frames]] / [grid] / [animate]")
    add_device_argument(p)
    add_cluster_argument(p)
    p.add_argument("--skip-existing", action="store_true", help="do not re-render frames whose file exists")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def cli_main(args) -> int:
    job = load_job(args.job)
    paths = run_job(job, cluster=args.cluster, device=args.device, progress=not args.no_progress,
                    skip_existing=args.skip_existing)
    print(f"{len(paths)} frames in {Path(job.output).parent}")
    return 0


__all__ = ["Job", "load_job", "run_job", "animate_variants", "check_output_pattern", "MAX_FIELD_WIDTH",
           "add_cli_arguments", "cli_main"]

r"""``warp-sg fit`` and ``ws.fit``: recover materials, textures and lighting from photographs of a
scene whose geometry is known, through the renderer's gradients (:mod:`warp_sg.renderer.gradients`).

::

    warp-sg fit SCENE.toml VIEWS.toml --free materials.body.kd --free lights.0 -o FITTED.toml
                [--iterations 200] [--optimizer lbfgs|adam] [--lr 0.02] [--samples N] [--texture-size N]
                [--env-lobes 64] [--restart] [--seed 0] [--device cpu]

Each iteration shades, for every view (:mod:`warp_sg.inverse.views`), the pixels that see the
object away from its silhouette (or the view's mask; ``--samples N``: a random N of them), with
the renderer's gradient variant (``Renderer.shade_samples``), and takes one step on the free
parameters (:mod:`warp_sg.inverse.free`) along the gradient of the loss — of L-BFGS-B
(``scipy.optimize``, the default: the gradients are exact and noise-free, and quasi-Newton steps
follow the valleys where an unknown light trades against an unknown albedo) or, with random
pixels (``--samples``) or ``--optimizer adam``, of Adam (:mod:`warp_sg.inverse.adam`) —

    L = (1/V) Σ_views Σ_pixels |I − T|² / Σ_pixels |T|²     (relative squared error per view)

``I`` our shading of the pixel's centre, ``T`` the photograph. Visibility is precomputed once:
the geometry is known; an environment light is an SG basis with free amplitudes whose lobes'
visible fractions are computed once too (:mod:`warp_sg.inverse.env_basis`).

Outputs (:mod:`warp_sg.inverse.outputs`): ``FITTED.toml`` with the fitted values, its textures and
environment map as EXR beside it, ``FITTED_loss.png``; a checkpoint ``FITTED.fit.npz`` every
``checkpoint_every`` iterations (atomic): a fit started again with the same inputs goes on from it
(``--restart``: from the start; Adam's state is in it, L-BFGS starts its curvature memory again). Bad input — a views
file whose image size differs from its
camera, a free key the scene does not have, a pixel that is not finite — is one line and exit
status 2 (:class:`warp_sg.core.errors.InputError`), before any work.
"""
from __future__ import annotations

import hashlib
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: learning rates of the optimiser's spaces: values (kd, ks, Fresnel, texels) and logarithms
LR_VALUE = 0.02
LR_LOG = 0.05


@dataclass
class FitResult:
    """What :func:`fit` returns: the output files, the loss per iteration, the seconds it took
    (this run) and the iteration it started from (0, or a checkpoint's)."""

    scene: Path
    files: list
    losses: list
    seconds: float
    started_at: int
    values: dict


def _signature(scene_path: Path, views_path: Path, keys, opts: dict) -> str:
    h = hashlib.sha256()
    for p in (scene_path, views_path):
        h.update(p.read_bytes())
    h.update(repr((list(keys), sorted(opts.items()))).encode())
    return h.hexdigest()[:16]


def _erode(m: np.ndarray) -> np.ndarray:
    """Pixels whose 3 × 3 neighbourhood is all inside ``m`` (drops the silhouette band)."""
    p = np.pad(m, 1, constant_values=False)
    out = np.ones_like(m)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            out &= p[dy:dy + m.shape[0], dx:dx + m.shape[1]]
    return out


class _ViewSamples:
    """A view's pixels to match: their triangles, barycentrics and photograph values."""

    def __init__(self, r, view):
        cam = view.camera
        r.set_camera(**{k: getattr(cam, k) for k in ("origin", "target", "up", "fov", "width", "height", "near", "far")})
        vb = r.rasterize(1)
        tri = vb.tri_id.numpy().reshape(cam.height, cam.width)
        sel = _erode(tri >= 0)
        if view.mask is not None:
            sel &= view.mask
        ys, xs = np.nonzero(sel)
        if len(ys) == 0:
            raise InputError("the object covers no pixel of this view (check its camera)", where=view.name)
        self.eye = np.asarray(cam.origin, np.float32)
        self.tri = tri[ys, xs]
        self.bary = vb.bary.numpy().reshape(cam.height, cam.width, 2)[ys, xs]
        self.target = view.image[ys, xs].astype(np.float64)
        self.norm = max(float(np.sum(self.target ** 2)), 1e-30)


def fit(scene, views, free, out, *, iterations: int = 200, lr: float | None = None, samples: int | None = None,
        texture_size: int | None = None, env_lobes: int = 64, device: str | None = None, restart: bool = False,
        seed: int = 0, progress: bool = True, checkpoint_every: int = 10, optimizer: str | None = None) -> FitResult:
    """Fit the free parameters ``free`` (scene-file keys) of scene file ``scene`` to the views file
    ``views``; write the fitted scene to ``out`` (module docstring)."""
    from warp_sg.core.files import check_output_path
    from warp_sg.inverse.adam import Adam
    from warp_sg.inverse.free import apply, gradient_key, parse_free
    from warp_sg.inverse.outputs import plot_loss, write_scene
    from warp_sg.inverse.views import load_views
    from warp_sg.renderer.renderer import Renderer
    from warp_sg.scene.loader import load_scene

    t_start = time.perf_counter()
    scene_path, views_path, out = Path(scene), Path(views), Path(out)
    if out.suffix.lower() != ".toml":
        raise InputError("the fitted scene is a .toml file", where=str(out))
    check_output_path(out, suffixes=(".toml",), create_parents=True)
    if int(iterations) < 1:
        raise InputError(f"must be >= 1, got {iterations}", where="iterations")
    optimizer = optimizer or ("adam" if samples else "lbfgs")
    if optimizer not in ("adam", "lbfgs"):
        raise InputError(f"unknown optimizer '{optimizer}' (adam or lbfgs)", where="optimizer")
    try:
        doc = tomllib.loads(scene_path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read the scene file ({e})", where=str(scene_path)) from None
    sc = load_scene(scene_path)
    vs = load_views(views_path)
    frees = parse_free(free, doc, sc, env_lobes=env_lobes, texture_size=texture_size)
    out.parent.mkdir(parents=True, exist_ok=True)
    sc.render = replace(sc.render, antialias=1, supersampling=1)
    opts = {"iterations": int(iterations), "lr": lr, "samples": samples, "texture_size": texture_size,
            "env_lobes": int(env_lobes), "seed": int(seed), "optimizer": optimizer}
    sig = _signature(scene_path, views_path, free, {k: v for k, v in opts.items() if k != "iterations"})
    ckpt = out.with_suffix(".fit.npz")

    r = Renderer(sc, device, requires_grad=True, progress=progress)
    apply(frees, r)
    view_samples = [_ViewSamples(r, v) for v in vs]
    lrs = [(lr if lr is not None else (LR_LOG if f.log else LR_VALUE)) for f in frees]
    adam = Adam([f.x.shape for f in frees], lrs)
    losses, start = [], 0
    if ckpt.exists() and not restart:
        start, losses = _load_checkpoint(ckpt, sig, frees, adam)
    rng = np.random.default_rng(seed + start)
    bar = _bar(progress, start, int(iterations))

    def evaluate():
        """(loss, [∂L/∂x per free parameter]) at the parameters' current values."""
        apply(frees, r)
        total, grads = 0.0, [np.zeros_like(f.x) for f in frees]
        for s in view_samples:
            idx = np.arange(len(s.tri)) if not samples or samples >= len(s.tri) else \
                rng.choice(len(s.tri), int(samples), replace=False)
            scale = len(s.tri) / len(idx)  # (a random part stands for the whole view)
            col = r.shade_samples(s.tri[idx], s.bary[idx], s.eye).astype(np.float64)
            diff = col - s.target[idx]
            total += scale * float(np.sum(diff * diff)) / s.norm / len(view_samples)
            g = r.backward(2.0 * scale * diff / s.norm / len(view_samples))
            for k, f in enumerate(frees):
                grads[k] += f.grad_x(g[gradient_key(f, r.scene)])
        return total, grads

    def done(it: int, loss: float) -> None:
        losses.append(loss)
        if bar is not None:
            bar.update(1)
            bar.set_postfix(loss=f"{loss:.3e}")
        if it % checkpoint_every == 0 or it == int(iterations):
            _save_checkpoint(ckpt, sig, it, losses, frees, adam)

    try:
        if optimizer == "adam":
            for it in range(start, int(iterations)):
                loss, grads = evaluate()
                adam.step([f.x for f in frees], grads)
                for f in frees:
                    f.clip()
                done(it + 1, loss)
        else:
            _lbfgs(frees, evaluate, done, start, int(iterations))
    finally:
        if bar is not None:
            bar.close()
    stem = out.stem
    files = write_scene(out, doc, scene_path.parent, frees, stem)
    files.append(plot_loss(out.with_name(f"{stem}_loss.png"), losses))
    return FitResult(out, files, losses, time.perf_counter() - t_start, start, {f.key: f.value for f in frees})


def _lbfgs(frees, evaluate, done, start: int, iterations: int) -> None:
    """``scipy.optimize.minimize(method="L-BFGS-B")`` over the free parameters' optimiser spaces,
    bounded by their value bounds; one iteration is one step of L-BFGS (its line search may
    evaluate more than once). The gradients are exact and noise-free: quasi-Newton steps follow
    the valleys (an unknown light against an unknown albedo) that Adam crosses slowly."""
    from scipy.optimize import minimize

    sizes = [f.x.size for f in frees]
    bounds = []
    for f in frees:
        lo, hi = (np.log(max(f.lo, 1e-12)) if f.log else f.lo), (np.log(f.hi) if f.log and np.isfinite(f.hi) else f.hi)
        bounds += [(None if not np.isfinite(lo) else float(lo), None if not np.isfinite(hi) else float(hi))] * f.x.size

    def unpack(v):
        o = 0
        for f, n in zip(frees, sizes):
            f.x = np.array(v[o:o + n], np.float64).reshape(f.x.shape)
            o += n

    last = {}

    def fun(v):
        unpack(v)
        loss, grads = evaluate()
        last["loss"] = loss
        return loss, np.concatenate([g.ravel() for g in grads])

    it = [start]

    def callback(v):
        unpack(v)
        it[0] += 1
        done(it[0], last["loss"])

    x0 = np.concatenate([f.x.ravel() for f in frees])
    res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds, callback=callback,
                   options={"maxiter": max(iterations - start, 1), "maxfun": 3 * max(iterations - start, 1)})
    unpack(res.x)


def _bar(progress, start, total):
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=start, desc="fit", unit="it", dynamic_ncols=True)


def _save_checkpoint(path: Path, sig: str, it: int, losses, frees, adam) -> None:
    from warp_sg.core.files import atomic_output

    arrays = {f"x{k}": f.x for k, f in enumerate(frees)}
    with atomic_output(path, suffix=".npz") as tmp:
        np.savez(tmp, signature=np.array(sig), iteration=np.array(it), losses=np.asarray(losses, np.float64),
                 **arrays, **adam.state())


def _load_checkpoint(path: Path, sig: str, frees, adam) -> tuple[int, list]:
    """(iteration, losses) of a checkpoint of the same inputs (its values and Adam's state loaded);
    (0, []) for one of other inputs or an unreadable one (the fit starts again)."""
    try:
        with np.load(path) as z:
            if str(z["signature"]) != sig:
                return 0, []
            for k, f in enumerate(frees):
                f.x = np.array(z[f"x{k}"], np.float64).reshape(f.x.shape)
            adam.load(z)
            return int(z["iteration"]), [float(x) for x in z["losses"]]
    except (OSError, KeyError, ValueError):
        return 0, []


def add_cli_arguments(p) -> None:
    from warp_sg.core.device import add_device_argument

    p.add_argument("scene", help="scene file (.toml) with the known geometry")
    p.add_argument("views", help="views file: [[views]] tables of a camera and a linear image (EXR)")
    p.add_argument("--free", action="append", required=True, metavar="KEY",
                   help="what to recover, by the scene file's key: materials.NAME.PARAM (a constant or a texture), "
                        "lights.INDEX (an environment light's lobes, a light's intensity), lights.INDEX.FIELD")
    p.add_argument("-o", "--output", required=True, help="the fitted scene file (.toml); its EXR files beside it")
    p.add_argument("--iterations", type=int, default=200)
    p.add_argument("--lr", type=float, default=None, help=f"learning rate (default {LR_VALUE} for values, "
                                                          f"{LR_LOG} for logarithms)")
    p.add_argument("--samples", type=int, default=None, help="pixels per view and iteration (default: all)")
    p.add_argument("--texture-size", type=int, default=None, help="fit textures at N x N (written at their own size)")
    p.add_argument("--env-lobes", type=int, default=64, help="SG lobes of a fitted environment")
    p.add_argument("--optimizer", choices=("lbfgs", "adam"), default=None,
                   help="L-BFGS-B (default) or Adam (default with --samples)")
    p.add_argument("--restart", action="store_true", help="ignore a checkpoint of an earlier run")
    p.add_argument("--seed", type=int, default=0)
    add_device_argument(p)


def cli_main(args) -> int:
    for name in ("iterations", "samples", "texture_size", "env_lobes"):
        v = getattr(args, name)
        if v is not None and v < 1:
            raise InputError(f"must be >= 1, got {v}", where=f"--{name.replace('_', '-')}")
    if args.lr is not None and not (np.isfinite(args.lr) and args.lr > 0):
        raise InputError(f"must be a finite number > 0, got {args.lr}", where="--lr")
    res = fit(args.scene, args.views, args.free, args.output, iterations=args.iterations, lr=args.lr,
              samples=args.samples, texture_size=args.texture_size, env_lobes=args.env_lobes,
              device=getattr(args, "device", None), restart=args.restart, seed=args.seed, optimizer=args.optimizer)
    print(f"fitted {', '.join(args.free)} in {res.seconds:.1f} s: loss {res.losses[0]:.4g} -> {res.losses[-1]:.4g}; "
          f"wrote {res.scene}")
    return 0


__all__ = ["fit", "FitResult", "add_cli_arguments", "cli_main"]

r"""Gradients of a frame: the :class:`~warp_sg.renderer.renderer.Renderer`'s ``requires_grad`` frames
and their adjoint (a mixin of it).

With known geometry the per-lobe SSDF visibility does not depend on the lighting or the materials:
it is a constant of the backward pass, and the shaded image is a smooth function of the material
records, the texels, the lights and the environment's SG mixture — with its shadows, and without
edge sampling. ``Renderer(scene, requires_grad=True)`` records every frame on a ``wp.Tape``
(:attr:`GradientPaths.tape`):

1. the environment's per-lobe constants ``μ_j ∫G(λ_j)`` and table rows
   (``warp_sg.shading.visibility_terms.lobe_constants``), a kernel with its adjoint;
2. the shading launch — the variant of the scene compiled with its adjoint
   (``shading.kernel.Features.grad``; the forward frames of ``requires_grad=False`` run the variant
   without it, unchanged) — recorded as a function whose backward runs the kernel's adjoint;
3. the k×k box resolve (its adjoint spreads each pixel's adjoint over its sub-pixels, /k²).

:meth:`GradientPaths.backward` takes ``∂loss/∂image`` (H, W, 3) and returns the gradients keyed by
the scene file's own dotted keys (:mod:`warp_sg.renderer.gradient_keys`). Held fixed (constants of
the backward pass): visibility (SSDFs and the per-vertex caches), the geometry and the raster,
the environment map's exact-irradiance and ΓL tables (a map environment's gradient is given only
through its SG mixture, ``Renderer.set_environment_mixture``: :mod:`warp_sg.shading.env_mixture`),
and each material's environment-specular energy correction table ``c(o)`` (``brdf.kernel.albedo``)
— but its interpolation in the first parameter (roughness) is differentiated: a ``requires_grad``
renderer gives every isotropic specular material a table over a range of that parameter
(constant: ``[q/2, 2q]``; textured: the texture's range widened by 1.5) that stays put between
edits (:meth:`GradientPaths._fixed_albedo_ranges`), so the frame is one smooth function of it.

Frames take the supersampled path (``[render] supersampling`` k, one shading sample per
sub-pixel; the adaptive antialiasing's choice of pixels is not differentiable).

**Warp's adjoint rules** (its documentation, "Differentiability"), which the shading kernel keeps:
loops over lights and lobes only accumulate (``col += …``), with no in-place ``*=``/``/=`` on a
taped array; Warp's reverse pass does not replay a dynamic loop before the statements after it, so
every such loop is a function that returns its sums and nothing after a loop uses what it summed
(:mod:`warp_sg.shading.kernel_grad`; the per-pixel loop of the forward kernel is taken out of the
gradient variant). Arrays inside a ``@wp.struct`` get their gradients through their own ``.grad``
(the adjoint struct's arrays are not read). **Parallel adjoint on the CPU**: Warp's CPU
``atomic_add`` is a plain add, so two threads must not add into one gradient array: each worker
thread runs the adjoint of its own pixel range into private gradient arrays (views of the inputs
carrying them, :func:`with_grads`), summed afterwards.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import warp as wp

from warp_sg.brdf.kernel.material_struct import Material
from warp_sg.shading import kernel as S
from warp_sg.shading.visibility_terms import lobe_constants


@wp.kernel
def _add_material_grads(src: wp.array(dtype=Material), dst: wp.array(dtype=Material)):
    """``dst += src`` on the differentiable fields of the material records (a worker's private sums)."""
    i = wp.tid()
    a = dst[i]
    b = src[i]
    a.kd = a.kd + b.kd
    a.ks = a.ks + b.ks
    a.params = a.params + b.params
    a.fresnel_a = a.fresnel_a + b.fresnel_a
    a.fresnel_b = a.fresnel_b + b.fresnel_b
    dst[i] = a


def with_grads(v, grads: dict):
    """Kernel argument ``v`` with the arrays named in ``grads`` ({id(array): gradient array}) replaced
    by views of the same data whose ``.grad`` is that gradient array (structs copied field by field).
    Warp's adjoint adds into the ``.grad`` an array carries into the launch — for arrays inside a
    ``@wp.struct`` it is the only route (the adjoint struct's arrays are not read) — so a view per
    worker gives each its own sums."""
    if isinstance(v, wp.array):
        g = grads.get(id(v))
        if g is None:
            return v
        view = v[:]
        view.grad = g
        return view
    if hasattr(v, "_cls"):  # a @wp.struct instance
        c = v._cls()
        for name in v._cls.vars:
            setattr(c, name, with_grads(getattr(v, name), grads))
        return c
    return v


def blank_adjoint(v):
    """A launch's adjoint argument for ``v`` that carries nothing (the gradients go through the
    arrays' own ``.grad``, :func:`with_grads`): None for an array, an empty struct, zero."""
    if isinstance(v, wp.array):
        return None
    if hasattr(v, "_cls"):
        return v._cls()
    if isinstance(v, (bool, int)):
        return 0
    if isinstance(v, float):
        return 0.0
    return type(v)()


def _zeros_like(a: wp.array) -> wp.array:
    return wp.zeros(a.shape, dtype=a.dtype, device=a.device)


def _reduce_into(dst: wp.array, src: wp.array) -> None:
    """``dst += src`` (a worker's private gradient into the array's ``.grad``)."""
    if dst.dtype is Material:
        wp.launch(_add_material_grads, dim=dst.shape[0], inputs=[src, dst], device=dst.device)
    else:
        dst.assign(dst.numpy() + src.numpy())


def adjoint_launch(kern, n: int, args: list, grads: dict, device, workers: int = 1) -> None:
    """The adjoint of ``parallel.launch(kern, n, args, per_thread=PIXELS_PER_THREAD)``: the gradients of
    the arrays in ``grads`` ({id(array): its .grad}) accumulated, the image's adjoint read from its
    own ``.grad``. On the CPU ``workers`` contiguous pixel ranges, each into private gradient
    arrays, then summed (module docstring)."""
    cpu = str(device).startswith("cpu")
    per = 1  # (the gradient variant shades one pixel per thread: warp_sg.shading.kernel_grad)
    blank = [0, 0, *[blank_adjoint(a) for a in args]]

    def one(b: int, m: int, g: dict) -> None:
        wp.launch(kern, dim=-(-m // per), inputs=[b, per, *[with_grads(a, g) for a in args]], adj_inputs=blank,
                  adjoint=True, device=device)

    workers = max(1, int(workers)) if cpu else 1
    if workers == 1 or n < 4096:
        one(0, n, grads)
        return
    step = -(-n // workers)
    ranges = [(b, min(step, n - b)) for b in range(0, n, step)]
    privates = [grads] + [{k: _zeros_like(g) for k, g in grads.items()} for _ in ranges[1:]]
    with ThreadPoolExecutor(len(ranges)) as pool:
        list(pool.map(lambda r: one(*r[0], r[1]), zip(ranges, privates)))
    for p in privates[1:]:
        for k, g in grads.items():
            _reduce_into(g, p[k])


class GradientPaths:
    """The ``requires_grad`` frames of a ``Renderer`` and their adjoint (module docstring)."""

    tape = None  # the wp.Tape of the last frame

    def _differentiable(self, es) -> list:
        """The arrays of the shading inputs that get gradients, each given a ``.grad``: the material
        records, the texture atlas's texels, the lights and the environment mixture's lobes."""
        arrays = [self.material_table.materials, self.material_textures.atlas.texels, self.light_arrays.vec,
                  self.light_arrays.radius, self.light_arrays.intensity]
        if self.env_light is not None and es.count > 0:
            arrays += [es.axis, es.lam, es.mu, es.power, es.irr_row]
        for a in arrays:
            if not a.requires_grad:
                a.requires_grad = True
            a.grad.zero_()
        return arrays

    def _render_grad(self) -> np.ndarray:
        """One frame recorded on :attr:`tape`: (H, W, 3) float32 linear radiance."""
        from warp_sg.renderer.frame import _timer

        d = self.device
        cam = self.scene.camera
        k = int(self.scene.render.supersampling)
        t0 = _timer(d)
        vb = self.rasterize(k)
        t1 = _timer(d)
        sub = self._shade_taped(vb.tri_id, vb.bary, self._background(k), cam.origin)
        img = sub
        if k > 1:
            img = wp.zeros((cam.height, cam.width), dtype=wp.vec3, device=d, requires_grad=True)
            wp.launch(S.resolve_box, dim=(cam.height, cam.width), inputs=[sub, k], outputs=[img], device=d)

            def spread(img=img, sub=sub, k=k):  # the box filter's adjoint
                g = np.repeat(np.repeat(img.grad.numpy(), k, axis=0), k, axis=1) / float(k * k)
                sub.grad.assign(sub.grad.numpy() + g.astype(np.float32))

            self.tape.record_func(spread, [sub, img])
        t2 = _timer(d)
        self._grad["image"] = img
        hs, ws_ = sub.shape
        self.timings.update(raster=t1 - t0, shade=t2 - t1, resolve=0.0, frame=t2 - t0, shaded_samples=hs * ws_)
        return img.numpy().reshape(cam.height, cam.width, 3).copy()

    def shade_samples(self, tri_id, bary, eye) -> np.ndarray:
        """The shading of N surface samples — triangle ``tri_id`` (N,) of the installed geometry,
        barycentrics ``bary`` (N, 2) of its vertices 1 and 2 — seen from ``eye``, recorded on
        :attr:`tape` like a frame: (N, 3) float32 (:meth:`backward` takes (N, 3)). What a fit
        shades: the pixels of a view that see the object, or a random part of them."""
        if not self.requires_grad:
            from warp_sg.core.errors import InputError

            raise InputError("shade_samples needs Renderer(requires_grad=True)", where="shade_samples")
        self.poll()
        d = self.device
        tri = np.asarray(tri_id, np.int32).reshape(1, -1)
        n = tri.shape[1]
        t = wp.array(tri, dtype=int, device=d)
        b = wp.array(np.asarray(bary, np.float32).reshape(1, n, 2), dtype=wp.vec2, device=d)
        sub = self._shade_taped(t, b, wp.zeros((1, n), dtype=wp.vec3, device=d), eye)
        return sub.numpy().reshape(n, 3).copy()

    def _shade_taped(self, tri_id, bary, bg, eye):
        """Shade the samples of (tri_id, bary) into a new array on a new :attr:`tape` (module
        docstring): the lobe constants, the shading launch and its adjoint as a recorded function."""
        from raster import parallel
        from warp_sg.core.workers import cpu_workers

        d = self.device
        sub = wp.zeros(tri_id.shape, dtype=wp.vec3, device=d, requires_grad=True)
        kern, n, args, es = self._shade_args(tri_id, bary, bg, eye, sub)
        arrays = self._differentiable(es)
        tape = wp.Tape()
        if self.env_light is not None and es.count > 0:
            with tape:  # μ ∫G(λ) and the table rows, recomputed on the tape
                lobe_constants(es, self.irr_table, d, keep=True)
        parallel.launch(kern, n, args, d, min_chunk=2048, per_thread=1)  # (kernel_grad: one pixel per thread)
        grads = {id(a): a.grad for a in arrays}
        workers = cpu_workers()
        tape.record_func(lambda: adjoint_launch(kern, n, args, grads, d, workers), arrays)
        self.tape, self._grad = tape, {"image": sub, "sub": sub, "arrays": arrays, "es": es}
        return sub

    @property
    def image_array(self):
        """The last ``requires_grad`` frame as a (H, W) ``wp.vec3`` array on the tape (a loss kernel
        launched on it while :attr:`tape` records is differentiated with it)."""
        return None if self._grad is None else self._grad["image"]

    def backward(self, adj_image) -> dict:
        """Run the last frame's adjoint with ``∂loss/∂image`` ``adj_image`` (H, W, 3) and return
        :meth:`gradients`: those of ``Σ adj_image · image`` (each call starts from zero; a loss
        kernel recorded on :attr:`tape` by the caller goes through ``tape.backward`` instead)."""
        from warp_sg.core.errors import InputError

        if self._grad is None:
            raise InputError("no requires_grad frame to differentiate: render() one first", where="backward")
        img = self._grad["image"]
        g = np.asarray(adj_image, np.float32)
        if g.size != img.shape[0] * img.shape[1] * 3 or not np.all(np.isfinite(g)):
            raise InputError(f"expected a finite ({img.shape[0]}, {img.shape[1]}, 3) array, got shape {g.shape}",
                             where="backward")
        for a in self._grad["arrays"] + [self._grad["sub"]]:  # (each call: the gradients of its adjoint alone)
            a.grad.zero_()
        img.grad.assign(g.reshape(img.shape[0], img.shape[1], 3))
        self.tape.backward()
        return self.gradients()

    def gradients(self) -> dict:
        """The gradients of the last frame's backward pass by scene-file key
        (:func:`warp_sg.renderer.gradient_keys.scene_gradients`)."""
        from warp_sg.renderer.gradient_keys import scene_gradients

        return scene_gradients(self, self._grad["es"])

    def _fixed_albedo_ranges(self, names, ranges) -> list:
        """Per material the range of the first parameter its energy-correction table spans, kept
        from one edit to the next (module docstring): a textured parameter's range widened by 1.5,
        a constant's ``[q/2, 2q]``, widened again only when a value leaves it."""
        kept = self.__dict__.setdefault("_albedo_ranges", {})
        out = []
        for name, rng, rec in zip(names, ranges, self.material_table.records):
            if rng is None:
                q = max(float(rec["params"][0]), 1e-4)
                lo, hi = q / 2.0, 2.0 * q
            else:
                lo, hi = max(rng[0] / 1.5, 1e-4), rng[1] * 1.5
            old = kept.get(name)
            if old is not None and old[0] <= lo and hi <= old[1]:
                lo, hi = old
            elif old is not None:
                lo, hi = min(lo, old[0]), max(hi, old[1])
            kept[name] = (lo, hi)
            out.append((lo, hi))
        return out


__all__ = ["GradientPaths", "adjoint_launch", "with_grads", "blank_adjoint"]

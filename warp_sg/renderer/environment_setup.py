r"""The environment side of the :class:`~warp_sg.renderer.renderer.Renderer` (a mixin): sharp peaks
separated as lights (``precompute.environment.peaks``), the exact irradiance table of the residual
(``precompute.environment.irradiance``), its SG mixture (eq. 34, ``precompute.environment.sg_fit``; the lobes give
the visible fraction where the per-vertex quadrature does not), the ΓL pyramid for the specular
term (eq. 35, lazily, only when a material is specular), and the kernel-side ``EnvSG`` arrays,
rebuilt only when the environment's rotation or scale changes.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from precompute.environment.irradiance import placeholder_table
from warp_sg.renderer.kernel_preload import ENV_MODULES, GAMMA_MODULES
from warp_sg.renderer.progressive import ShadowJob
from warp_sg.scene.lights import DirectionalLight, PointLight
from warp_sg.shading import kernel as S
from warp_sg.shading.visibility_terms import lobe_constants

#: the sharpest ΓL level of a progressive renderer's first frames (σ = 1/√λ ≈ 3.6°); sharper lobes
#: read the prefilter's blend towards the map's own Gaussian-filtered texels until the scene's
#: ladder arrives (``EnvironmentSetup._ensure_gamma``)
PREVIEW_GAMMA_LAMBDA = 256.0
#: the first frames' ladder keeps every PREVIEW_GAMMA_STRIDE-th level of the scene's, counted down
#: from its top (ratio 2 instead of √2: half the prefilter's CPU; its lookups against quadrature
#: err 2–3× more at the median, 0.17–0.6 % on the procedural sky and a Poly Haven map, and up to
#: 5× at the worst point: docs/rendering.md, tests/test_progressive.py)
PREVIEW_GAMMA_STRIDE = 2


def preview_ladder(lams) -> np.ndarray:
    """The ΓL ladder of a progressive renderer's first frames from the scene's geometric ladder
    ``lams``: its levels up to :data:`PREVIEW_GAMMA_LAMBDA` (at least two), every
    :data:`PREVIEW_GAMMA_STRIDE`-th from the top one down (still a geometric ladder, with the same
    top)."""
    lams = np.asarray(lams, np.float64)
    top = lams[:max(int(np.searchsorted(lams, PREVIEW_GAMMA_LAMBDA, side="right")), 2)]
    kept = top[::-1][::PREVIEW_GAMMA_STRIDE][::-1]
    return kept if len(kept) >= 2 else top[-2:]


def lobes_with_energy(lam, mu) -> np.ndarray:
    """Which lobes of an SG mixture (sharpness ``lam`` (K,), RGB amplitudes ``mu`` (K, 3)) carry energy:
    ``max |μ| ∫G`` above 1e-6 of the mixture's sum (an amplitude the non-negative fit set to 0 does
    not); the first lobe when none does. What the frames' environment arrays keep."""
    lam = np.asarray(lam, np.float64)
    energy = np.abs(np.asarray(mu, np.float64)).max(axis=1) * 2.0 * np.pi * -np.expm1(-2.0 * lam) / np.maximum(lam, 1e-12)
    keep = energy > 1e-6 * max(float(energy.sum()), 1e-300)
    if not keep.any():
        keep[:1] = True
    return keep


class EnvironmentSetup:
    """Environment setup and arrays of a ``Renderer`` (which calls ``_setup_env_peaks`` before the
    geometry, whose refinement follows the peaks' shadows, and ``_setup_environment`` after the
    materials)."""

    def _smooth_tris(self):
        """(T,) uint8 triangles whose vertex normals agree within 5° (built once per installed mesh:
        a rigid motion of dynamic objects keeps the angles between their normals, so their flags
        are those of the pose the mesh was built in)."""
        g = self.geometry
        if getattr(self, "_smooth", None) is None or self._smooth[0] is not g.triangles:
            from warp_sg.shading.vertex_visibility import smooth_triangles

            normals = g.normals if self.dynamic is None else self.dynamic.rest_n
            self._smooth = (g.triangles, wp.array(smooth_triangles(normals, g.triangles), dtype=wp.uint8,
                                                  device=self.device))
        return self._smooth[1]

    def _setup_env_peaks(self):
        """Sharp peaks of the environment (a sun, lamps) become directional lights
        (``precompute.environment.peaks``, ``[render] env_peaks``): first, because the mesh is refined along
        their shadows (``_refine_lights``)."""
        env = self.scene.environment
        self.env_light = env
        self.env_peaks = []
        if env is None:
            return
        from precompute.environment.peaks import extract_peaks

        self.env_base = env.base_radiance()  # what the background shows
        t = self._tick()
        self.env_residual, self.env_peaks = extract_peaks(self.env_base, max_peaks=self.scene.render.env_peaks)
        self._tock("env_peaks", t)

    def _refine_lights(self) -> list:
        """The key lights the mesh refinement places shadow edges for: the scene's point and
        directional lights and the environment's peaks (world space)."""
        out = []
        for li in list(self.scene.local_lights) + self.peak_lights():
            if isinstance(li, DirectionalLight):
                out.append(("directional", np.asarray(li.direction, np.float64)))
            elif isinstance(li, PointLight):
                out.append(("point", np.asarray(li.position, np.float64)))
        return out

    def _setup_environment(self):
        """Environment: sharp peaks (a sun) become directional lights (``precompute.environment.peaks``,
        ``[render] env_peaks``); the broad remainder is fitted by an SG mixture for the diffuse
        term (eq. 34, fitted through the exact SG irradiance) and prefiltered (ΓL) for the
        specular term (lazily, only when a material is specular)."""
        env = self.scene.environment
        rs = self.scene.render
        self.env_light = env
        self.env_diffuse_mode = S.ENV_NONE
        self.env_specular_mode = S.ENV_NONE
        self._env_sg_base = None  # (axes in the map frame, λ, μ unscaled)
        self.env_irradiance = None
        self.gamma = None
        if env is None:
            return
        base = self.env_base
        # the ΓL prefilter needs only the residual: on its own threads beside the irradiance and the
        # SG fit (the fit is one thread of numpy and scipy), joined before this returns
        gamma = ShadowJob(self._ensure_gamma, name="warp-sg-gamma-setup") if (
            self.overlap_precompute and self.has_specular) else None
        try:
            self._fit_environment(env, base, rs)
        finally:
            if gamma is not None:
                gamma.wait()
        if gamma is not None:
            gamma.result()  # (its error, if any, is raised here)

    def _fit_environment(self, env, base, rs):
        """The exact irradiance table of the residual and its SG mixture (``_setup_environment``)."""
        t = self._tick()
        from precompute.environment.irradiance import cell_radiance, irradiance_cubemap

        self.load_modules(ENV_MODULES)  # (compiled on the pool: kernel_preload)
        self.env_irradiance = irradiance_cubemap(self.env_residual, device=self.device)
        self.env_texel_radiance = wp.array(cell_radiance(self.env_residual).astype(np.float32), dtype=wp.vec3,
                                           device=self.device)
        self._tock("env_irradiance", t)
        t = self._tick()
        if env.procedural == "constant":
            # a constant map is exactly one SG of vanishing sharpness: no fit needed
            rad = np.asarray(base.reshape(-1, 3)[0], np.float64)
            lam0 = 1.0e-4
            self._env_sg_base = (np.array([[0.0, 1.0, 0.0]]), np.array([lam0]), (rad * np.exp(lam0))[None, :])
        else:
            self._env_sg_base = self._fit_env(self.env_residual, rs.env_lobes)
        self.env_diffuse_mode = S.ENV_SG
        self._tock("env_fit", t)

    def _ensure_gamma(self):
        """Prefilter the environment (ΓL pyramid, eq. 35) when the scene needs it: a specular
        material. Done lazily so diffuse-only scenes skip it. The default λ ladder ends at the
        first level at or above the scene's sharpest NDF lobe (:mod:`warp_sg.scene.lobe_extent`); a
        material edit that needs a sharper level rebuilds it.

        A progressive renderer whose shadows are still to come builds only the levels up to
        :data:`PREVIEW_GAMMA_LAMBDA` for its first frames (the sharpest four or five levels are
        most of the prefilter's cost: the full map with sub-cells) and prefilters the scene's
        ladder on a background thread beside the shadows (:meth:`_start_gamma_job`, installed by
        :meth:`poll`): its later frames are those of a renderer built without ``progressive``."""
        env = self.env_light
        if env is None or not self.has_specular or self._gamma_job is not None or self.env_mixture:
            return  # (a full ladder on its way: the preview's serves until poll() installs it; a mixture needs none)
        if self.gamma is not None and (not self._gamma_capped or self._gamma_need <= self._gamma_reach):
            return
        t = self._tick()
        kw, capped, reach = self._gamma_request()
        if self.progressive and self._job is not None and reach > PREVIEW_GAMMA_LAMBDA:
            lams = kw.get("lambdas", self._gamma_ladder())
            preview = preview_ladder(lams)
            self._install_gamma(self._prefilter(lambdas=preview), True, float(preview[-1]))
            self._gamma_job = lambda: ShadowJob(lambda: (self._prefilter(**kw), capped, reach), name="warp-sg-gamma",
                                                background=True)
        else:
            self._install_gamma(self._prefilter(**kw), capped, reach)
        self._tock("env_prefilter", t)

    def _gamma_ladder(self) -> np.ndarray:
        from precompute.environment.prefilter import default_ladder

        return default_ladder(self.env_residual.shape[0], base_face=self.scene.render.gamma_resolution)[0]

    def _gamma_request(self) -> tuple:
        """``(keyword arguments of prefilter_environment, capped, reach)``: the ladder the scene
        needs (``[render] gamma_levels`` levels, or the default ladder up to the sharpest lobe),
        whether it stops short of the default ladder's top, and its last λ."""
        rs = self.scene.render
        lams = self._gamma_ladder()
        kw = {}
        if rs.gamma_levels > 0:
            kw["lambdas"] = np.geomspace(lams[0], lams[-1], rs.gamma_levels)
        elif 0.0 < self._gamma_need < lams[-2]:
            kw["lambdas"] = lams[:max(int(np.searchsorted(lams, self._gamma_need)) + 1, 2)]
        return kw, "lambdas" in kw and rs.gamma_levels == 0, float(kw.get("lambdas", lams)[-1])

    def _prefilter(self, **kw):
        import precompute

        self.load_modules(GAMMA_MODULES)
        return precompute.prefilter_environment(self.env_residual, device=self.device,
                                                base_face=self.scene.render.gamma_resolution,
                                                progress=self.progress, **kw)

    def _install_gamma(self, gamma, capped: bool, reach: float) -> None:
        self.gamma, self._gamma_capped, self._gamma_reach = gamma, bool(capped), float(reach)
        self.env_specular_mode = S.ENV_PREFILTERED

    def _start_gamma_job(self) -> None:
        """Start the background prefilter of the scene's ladder (``progressive``), once: after the
        first frame, which so has the cores to itself but for the shadows' thread (``render()``,
        ``wait()``)."""
        if callable(self._gamma_job):  # (not started yet: a ShadowJob's factory)
            self._gamma_job = self._gamma_job()

    def _poll_gamma(self) -> bool:
        """Install the background prefilter's ladder if it has finished (``progressive``): whether
        this call did."""
        job = self._gamma_job
        if not isinstance(job, ShadowJob) or not job.done():  # (None, or not started yet)
            return False
        self._gamma_job = None
        self._install_gamma(*job.result())
        self.timings["precompute_parts"]["env_prefilter_full"] = job.seconds
        return True

    @staticmethod
    def _fit_env(base, n_lobes):
        from precompute.environment.sg_fit import fit_environment_sgs

        axes, lam, mu = fit_environment_sgs(base, n_lobes, cosine="exact")
        return (np.asarray(axes, np.float64).reshape(-1, 3), np.asarray(lam, np.float64).reshape(-1),
                np.asarray(mu, np.float64).reshape(-1, 3))

    def _env_arrays(self):
        """EnvSG (world axes: rotation applied; amplitudes scaled) on the device, rebuilt only when
        the rotation, the scale or the installed mesh (a progressive renderer's refined mesh; not a
        motion of dynamic objects) changes. Lobes that carry no energy (``|μ| ∫G`` below 1e-6 of the
        mixture's, e.g. amplitudes the non-negative fit set to 0) are left out."""
        env = self.env_light
        base = self._env_sg_base  # (the key holds its axes and sharpnesses: set_environment_mixture changes μ in place)
        key = None if env is None or base is None else ((id(base[0]), id(base[1])), float(env.rotation), float(env.scale),
                                                        id(self.geometry.triangles))  # (smooth: per triangle)
        if self._env_arrays_key == key:
            return self._env_sg_arrays
        d = self.device
        es = S.EnvSG()
        if key is None:
            es.count = 0
            es.axis = wp.zeros(1, dtype=wp.vec3, device=d)
            es.lam = wp.ones(1, dtype=float, device=d)
            es.mu = wp.zeros(1, dtype=wp.vec3, device=d)
            es.exact = placeholder_table(d)
            es.radiance = wp.zeros((1, 1), dtype=wp.vec3, device=d)
            es.smooth = wp.zeros(1, dtype=wp.uint8, device=d)
        else:
            R = env.rotation_matrix()
            ax, lam, mu = self._env_sg_base
            # (every lobe of a given mixture: its gradients are indexed by lobe)
            keep = np.ones(len(lam), bool) if self.env_mixture else lobes_with_energy(lam, mu)
            ax, lam, mu = ax[keep], lam[keep], mu[keep]
            es.count = len(lam)
            es.axis = wp.array((ax @ R.T).astype(np.float32), dtype=wp.vec3, device=d)
            es.lam = wp.array(lam.astype(np.float32), dtype=float, device=d)
            es.mu = wp.array((mu * env.scale).astype(np.float32), dtype=wp.vec3, device=d)
            es.exact = self.env_irradiance.table(rotation=R, scale=float(env.scale), device=d)
            es.radiance = self.env_texel_radiance
            es.smooth = self._smooth_tris()
        self._env_arrays_key, self._env_sg_arrays = key, lobe_constants(es, self.irr_table, d)
        return es

    def set_environment_mixture(self, axes, lam, mu) -> None:
        """Make the environment light the SG mixture ``L(i) = Σ_j μ_j exp(λ_j (i·p_j − 1))``: ``axes``
        (K, 3) unit vectors in the map's frame (the light's rotation applies), ``lam`` (K,) > 0 and
        ``mu`` (K, 3) radiance (the light's scale applies). Its diffuse term is the lobes' exact
        irradiance with each lobe's visible fraction, its specular term the lobes' closed-form
        product with the slice lobes (:mod:`warp_sg.shading.env_mixture`); the map's peaks are no
        longer lights and the background still shows the map. A call with the same axes and
        sharpnesses changes only μ: no per-vertex visibility is recomputed (what inverse rendering
        does every step)."""
        from warp_sg.core.errors import SceneError

        if self.env_light is None:
            raise SceneError("the scene has no environment light", where="set_environment_mixture")
        ax = np.asarray(axes, np.float64).reshape(-1, 3)
        lam = np.asarray(lam, np.float64).reshape(-1)
        mu = np.asarray(mu, np.float64).reshape(-1, 3)
        if not (len(ax) == len(lam) == len(mu) and len(lam) > 0):
            raise SceneError(f"axes, lam and mu must have one row per lobe, got {len(ax)}, {len(lam)}, {len(mu)}",
                             where="set_environment_mixture")
        norm = np.linalg.norm(ax, axis=1)
        if not (np.all(np.isfinite(ax)) and np.all(norm > 0) and np.all(np.isfinite(lam)) and np.all(lam > 0)
                and np.all(np.isfinite(mu))):
            raise SceneError("axes must be finite non-zero vectors, lam finite and > 0, mu finite",
                             where="set_environment_mixture")
        ax = ax / norm[:, None]
        old = self._env_sg_base
        if (self.env_mixture and old is not None and old[0].shape == ax.shape and np.array_equal(old[0], ax)
                and np.array_equal(old[1], lam)):
            self._env_sg_base = (old[0], old[1], mu)  # the same key: the device μ updated here
            es = self._env_sg_arrays
            key = self._env_arrays_key
            if es is not None and key and key[0] == (id(old[0]), id(old[1])):  # (built for these lobes)
                es.mu.assign((mu * self.env_light.scale).astype(np.float32))
                lobe_constants(es, self.irr_table, self.device, keep=True)
            return
        self._env_sg_base = (ax, lam, mu)
        if not self.env_mixture:
            self.env_mixture = True
            self.env_peaks = []  # (the mixture is the whole environment)
            self.env_diffuse_mode = S.ENV_SG
            self._setup_lights()

    def peak_lights(self) -> list:
        """The environment's sharp peaks as world-space directional lights (rotation and scale
        of the environment applied)."""
        env = self.env_light
        if env is None or not self.env_peaks:
            return []
        R = env.rotation_matrix()
        return [DirectionalLight(direction=R @ p.direction, radius=p.radius, intensity=p.irradiance * env.scale)
                for p in self.env_peaks]


__all__ = ["EnvironmentSetup", "PREVIEW_GAMMA_LAMBDA", "lobes_with_energy"]

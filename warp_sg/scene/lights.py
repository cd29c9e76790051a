r"""Light records and their SG forms (paper §6, eq. 32–35; docs/math.md "Lights").

Records (what a scene holds; the Monte-Carlo reference reads the same records):

* :class:`PointLight` — a sphere at ``position`` with ``radius`` r and ``intensity`` s (RGB, W/sr):
  uniform radiance ``s/(π r²)``, so the irradiance at distance d facing it is ``s/d²``.
* :class:`DirectionalLight` — ``direction`` (unit, pointing **towards** the light, i.e. the
  direction light comes *from*), angular radius ``radius`` (radians), ``intensity`` = irradiance E
  on a surface facing it.
* :class:`EnvironmentLight` — equirectangular radiance (Mitsuba's convention) from ``file`` (EXR or Radiance .hdr)
  or ``procedural`` ("sky" → :func:`warp_sg.scene.sky.procedural_sky` with ``options``;
  "constant" → uniform radiance ``options.radiance``), times ``scale``, rotated by ``rotation``
  degrees about +Y: ``L_world(d) = L_map(R_y(rotation)ᵀ d)``.

SG lights (eq. 32–33), amplitude chosen so that the SG's integral is the light's irradiance
(eq. 32 kept physical instead of literal, docs/math.md)::

    point:        p = (l − x)/d,  λ = fa⁻¹(2π r²/d²),  μ: ∫G = 2πμ(1 − e^{−2λ})/λ = s/d²
    directional:  p = l,          λ = fa⁻¹(2π r²),     μ: ∫G = E

with ``fa⁻¹(A) = −2π ln ε / A`` (ε = 0.1). A radius of 0 (a delta light) is clamped to a tiny solid
angle (``MIN_LIGHT_AREA``), which gives a very sharp SG with the same integral.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp

from warp_sg.core.errors import InputError, SceneError
from warp_sg.scene.envmap import check_envmap_shape, load_envmap, rotate_envmap, rotation_y, validate_envmap
from warp_sg.scene.light_tables import DirectionalLightTable, EnvironmentData, LightTable, PointLightTable, default_of
from warp_sg.scene.sky import procedural_sky
from warp_sg.scene.values import check_record
from warp_sg.sg import EPSILON
from warp_sg.sg.algebra_wp import expm1_neg

#: Smallest light solid angle (sr) used to turn a light into an SG (radius 0 = delta light).
MIN_LIGHT_AREA = 1.0e-6
#: Largest light sharpness (fa⁻¹(MIN_LIGHT_AREA)).
FA_NUMERATOR = -2.0 * math.pi * math.log(EPSILON)


def _check(model, label: str, **values):
    """The validated table ``model`` of a light record's fields (the scene file's rule and words)."""
    return check_record(model, values, f"[[lights]] ({label})")


@dataclass
class PointLight:
    """Spherical light: centre ``position``, ``radius`` r, ``intensity`` s (RGB, W/sr).
    Should sit outside the objects' convex hulls (visibility is precomputed for distant light).
    Checked by :class:`~warp_sg.scene.light_tables.PointLightTable`."""

    position: np.ndarray
    radius: float = default_of(PointLightTable, "radius")
    intensity: np.ndarray = field(default_factory=lambda: np.asarray(default_of(PointLightTable, "intensity")))
    type: str = field(default="point", init=False)

    def __post_init__(self):
        t = _check(PointLightTable, "point light", type="point", position=self.position, radius=self.radius,
                   intensity=self.intensity)
        self.position, self.radius = np.asarray(t.position, np.float64), t.radius
        self.intensity = np.asarray(t.intensity, np.float64)


@dataclass
class DirectionalLight:
    """Distant light from unit ``direction`` (towards the light), angular ``radius`` (radians),
    irradiance ``intensity`` E (RGB). Checked by :class:`~warp_sg.scene.light_tables.DirectionalLightTable`."""

    direction: np.ndarray
    radius: float = default_of(DirectionalLightTable, "radius")
    intensity: np.ndarray = field(default_factory=lambda: np.asarray(default_of(DirectionalLightTable, "intensity")))
    type: str = field(default="directional", init=False)

    def __post_init__(self):
        t = _check(DirectionalLightTable, "directional light", type="directional", direction=self.direction,
                   radius=self.radius, intensity=self.intensity)
        d = np.asarray(t.direction, np.float64)
        self.direction, self.radius = d / np.linalg.norm(d), t.radius
        self.intensity = np.asarray(t.intensity, np.float64)


@dataclass
class EnvironmentLight:
    """Distant environment: ``file`` (equirectangular EXR or Radiance .hdr) or ``procedural`` ("sky" | "constant")
    with ``options`` (passed to ``procedural_sky``; "constant": ``radiance`` RGB, ``width``,
    ``height``), times ``scale``, rotated ``rotation`` degrees about +Y. Checked by the
    environment tables of :mod:`warp_sg.scene.light_tables` (``data``, an array given in Python, by
    :class:`~warp_sg.scene.light_tables.EnvironmentData`)."""

    file: str | Path | None = None
    procedural: str | None = None
    options: dict = field(default_factory=dict)
    scale: float = default_of(EnvironmentData, "scale")
    rotation: float = default_of(EnvironmentData, "rotation")
    data: np.ndarray | None = None  # (H, W, 3) radiance given directly (Python API)
    type: str = field(default="environment", init=False)
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        given = {"type": "environment", "scale": self.scale, "rotation": self.rotation}
        if self.data is not None:
            if self.file is not None or self.procedural is not None:
                raise SceneError("[[lights]] (environment light) give exactly one of 'file', 'procedural' or data")
            t = _check(EnvironmentData, "environment light", **given)
        else:
            given.update({k: v for k, v in (("file", self.file), ("procedural", self.procedural)) if v is not None})
            if self.options:
                given["options"] = self.options
            t = _check(LightTable, "environment light", **given)
        self.scale, self.rotation = t.scale, t.rotation

    def base_radiance(self) -> np.ndarray:
        """Unscaled, unrotated (H, W, 3) float32 map (cached): what precompute prefilters."""
        if "base" not in self._cache:
            if self.data is not None:
                a = np.asarray(self.data, np.float32)
                if a.ndim != 3 or a.shape[2] != 3:
                    raise InputError(f"environment data must be (H, W, 3), got {a.shape}", where="environment light")
                a = validate_envmap(a, where="environment light.data")
            elif self.procedural == "constant":
                o = self.options  # checked by ConstantOptions when the record was made
                rad = np.broadcast_to(np.asarray(o.get("radiance", 1.0), np.float32), (3,))
                w, h = int(o.get("width", 64)), int(o.get("height", 32))
                check_envmap_shape(h, w, "environment light.options")  # before the texels exist
                a = np.broadcast_to(rad, (h, w, 3)).copy()
            elif self.procedural == "sky":
                o = self.options
                check_envmap_shape(o.get("height", 128), o.get("width", 256), "environment light.options")
                a = np.asarray(procedural_sky(**self.options), np.float32)
            else:
                a = np.asarray(load_envmap(self.file), np.float32)
            self._cache["base"] = a
        return self._cache["base"]

    def rotation_matrix(self) -> np.ndarray:
        """R_y(rotation): world = R · map frame."""
        return rotation_y(self.rotation)

    def radiance(self) -> np.ndarray:
        """The world-space map: ``scale`` applied and rotated about +Y (exact resampling along u)."""
        return rotate_equirect(self.base_radiance() * np.float32(self.scale), self.rotation)


# The environment's rotation is implemented once, in warp_sg.scene.envmap (``rotation_y`` is imported from there).
def rotate_equirect(env: np.ndarray, degrees: float) -> np.ndarray:
    """``L_out(d) = L_in(R_y(degrees)ᵀ d)`` as float32: :func:`warp_sg.scene.envmap.rotate_envmap` of
    :func:`rotation_y` (a rotation about +Y is an exact resampling along u)."""
    return rotate_envmap(env, rotation_y(degrees))


# --------------------------------------------------------------------------------------------
# SG forms (numpy, float64) — eq. 32-33
# --------------------------------------------------------------------------------------------
def light_sharpness(solid_angle):
    """``λ = fa⁻¹(A)`` with the area clamped to ``MIN_LIGHT_AREA``."""
    return FA_NUMERATOR / np.maximum(np.asarray(solid_angle, np.float64), MIN_LIGHT_AREA)


def amplitude_for_integral(lam, integral):
    """μ such that ``2πμ(1 − e^{−2λ})/λ = integral``."""
    lam = np.asarray(lam, np.float64)
    return np.asarray(integral, np.float64) * lam[..., None] / (2 * np.pi * -np.expm1(-2 * lam))[..., None]


def point_light_sg(light: PointLight, x):
    """SG of a point light seen from points x (..., 3): (axis (..., 3), λ (...), μ (..., 3))."""
    v = light.position - np.asarray(x, np.float64)
    d2 = np.sum(v * v, -1)
    p = v / np.sqrt(d2)[..., None]
    lam = light_sharpness(2 * np.pi * light.radius ** 2 / d2)
    mu = amplitude_for_integral(lam, light.intensity / d2[..., None])
    return p, lam, mu


def directional_light_sg(light: DirectionalLight):
    lam = light_sharpness(2 * np.pi * light.radius ** 2)
    return light.direction, float(lam), amplitude_for_integral(np.asarray(lam), light.intensity)


# --------------------------------------------------------------------------------------------
# kernel side
# --------------------------------------------------------------------------------------------
#: the kernel-side light kinds (``LightArrays.kind``; the reference's kernels read them too)
LIGHT_POINT = 0
LIGHT_DIRECTIONAL = 1

_FA_NUM = wp.constant(FA_NUMERATOR)
_MIN_AREA = wp.constant(MIN_LIGHT_AREA)
_TWO_PI = wp.constant(2.0 * math.pi)


@wp.struct
class LightArrays:
    """Point and directional lights for the shading kernel (``count`` may be 0)."""

    count: int
    kind: wp.array(dtype=int)  # LIGHT_POINT | LIGHT_DIRECTIONAL
    vec: wp.array(dtype=wp.vec3)  # point: position; directional: unit direction towards the light
    radius: wp.array(dtype=float)  # point: sphere radius; directional: angular radius
    intensity: wp.array(dtype=wp.vec3)  # s (point) or E (directional)


@wp.func
def light_irradiance(lights: LightArrays, j: int, x: wp.vec3):
    """(unit direction towards light ``j`` from ``x``, its SG sharpness λ = fa⁻¹(solid angle),
    irradiance E (RGB) on a surface facing it): ``s/d²`` for a point light, ``E`` for a directional one."""
    r = lights.radius[j]
    axis = lights.vec[j]
    area = _TWO_PI * r * r
    irr = lights.intensity[j]
    if lights.kind[j] == LIGHT_POINT:
        v = lights.vec[j] - x
        d2 = wp.max(wp.dot(v, v), 1.0e-20)
        axis = v / wp.sqrt(d2)
        area = area / d2
        irr = irr / d2
    return axis, _FA_NUM / wp.max(area, _MIN_AREA), irr


@wp.func
def light_sg(lights: LightArrays, j: int, x: wp.vec3):
    """SG (axis, λ, μ RGB) of light ``j`` at world point ``x`` (eq. 32–33, integral-preserving μ:
    ``∫G = 2πμ(1 − e^{−2λ})/λ`` equals the irradiance)."""
    axis, lam, irr = light_irradiance(lights, j, x)
    return axis, lam, irr * (lam / (_TWO_PI * expm1_neg(2.0 * lam)))


def light_arrays(lights: list, device) -> LightArrays:
    """Pack Point/DirectionalLights into :class:`LightArrays` (dummy entry when empty)."""
    n = len(lights)
    m = max(n, 1)
    kind = np.zeros(m, np.int32)
    vec = np.zeros((m, 3), np.float32)
    rad = np.zeros(m, np.float32)
    inten = np.zeros((m, 3), np.float32)
    for j, li in enumerate(lights):
        if isinstance(li, PointLight):
            kind[j], vec[j] = LIGHT_POINT, li.position
        elif isinstance(li, DirectionalLight):
            kind[j], vec[j] = LIGHT_DIRECTIONAL, li.direction
        else:
            raise InputError(f"not a point or directional light: {li!r}", where=f"lights[{j}]")
        rad[j] = li.radius
        inten[j] = li.intensity
    a = LightArrays()
    a.count = n
    a.kind = wp.array(kind, dtype=int, device=device)
    a.vec = wp.array(vec, dtype=wp.vec3, device=device)
    a.radius = wp.array(rad, dtype=float, device=device)
    a.intensity = wp.array(inten, dtype=wp.vec3, device=device)
    return a


__all__ = ["PointLight", "DirectionalLight", "EnvironmentLight", "point_light_sg", "directional_light_sg",
           "light_sharpness", "amplitude_for_integral", "rotation_y", "rotate_equirect", "LightArrays",
           "light_sg", "light_irradiance", "light_arrays", "LIGHT_POINT", "LIGHT_DIRECTIONAL"]

r"""What a fit recovers: free parameters named by the scene file's own dotted keys.

* ``materials.NAME.PARAM`` — a material parameter: a constant (a number or RGB; a table's number
  such as ``materials.NAME.fresnel.schlick``) or, when the file gives a texture, the texture's
  values per texel (at its own resolution, or ``texture_size``; written back at its own);
* ``lights.INDEX`` — an environment light: an SG basis with free amplitudes
  (:mod:`warp_sg.inverse.env_basis`), started from the light's own map; a point or directional
  light: its intensity; ``lights.INDEX.FIELD`` (``intensity``, ``position``, ``direction``) a
  local light's field.

Each parameter keeps its value in the optimiser's space: the logarithm for values that must stay
positive and scale freely (roughness, an exponent, a light's intensity, the environment's
amplitudes: gradient ``x ∂L/∂x``), the value itself otherwise, clipped to the model's bounds after
each step (``kd`` and the roughness in [0, 1], ``ks`` and Fresnel values ≥ 0). :func:`parse_free`
refuses a key the scene file does not have (one line, with the closest key).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from warp_sg.core.errors import InputError
from warp_sg.core.suggest import did_you_mean
from warp_sg.renderer.gradient_keys import get_leaf, set_leaf
from warp_sg.scene.model import COLOUR_PARAMS

#: parameters kept in log space (positive, scale-like)
LOG_PARAMS = ("alpha", "alpha_x", "alpha_y", "m", "n", "nu", "nv", "sigma")
#: upper bounds of parameters (lower bounds come from the model's declaration, else 0)
UPPER = {"kd": 0.999, "alpha": 1.0, "alpha_x": 1.0, "alpha_y": 1.0, "m": 1.0, "schlick": 1.0}
LOCAL_FIELDS = ("intensity", "position", "direction")


@dataclass
class Free:
    """One free parameter: its key, kind (``constant``, ``texture``, ``environment``, ``light``),
    material or light, value in the optimiser's space ``x`` (value = exp(x) when ``log``) and the
    bounds of the value."""

    key: str
    kind: str
    owner: str | int
    leaf: str
    x: np.ndarray
    log: bool
    lo: float
    hi: float
    colour: bool = False
    extra: dict = field(default_factory=dict)

    @property
    def value(self) -> np.ndarray:
        return np.exp(self.x) if self.log else self.x

    def set_value(self, v) -> None:
        v = np.clip(np.asarray(v, np.float64), self.lo, self.hi)
        self.x = np.array(np.log(np.maximum(v, 1e-12)) if self.log else v, np.float64)  # (an array: Adam steps in place)

    def clip(self) -> None:
        self.set_value(self.value)

    def grad_x(self, g: np.ndarray) -> np.ndarray:
        """∂L/∂x from ∂L/∂value (the chain rule of the log)."""
        g = np.asarray(g, np.float64).reshape(self.x.shape)
        return g * self.value if self.log else g


def _bounds(model: str, leaf: str) -> tuple[float, float]:
    from warp_sg.brdf import MODELS

    name = leaf.split(".")[-1]
    p = MODELS[model].PARAMS.get(leaf.split(".")[0])
    lo = 0.0
    if p is not None and p.lo is not None and p.kind != "fresnel":
        lo = float(p.lo) + (1e-3 if p.lo_open else 0.0)
    return lo, UPPER.get(name, np.inf)


def _material_free(key, parts, doc, scene, texture_size) -> Free:
    from warp_sg.brdf import MODELS

    mats = doc.get("materials", {})
    if len(parts) < 3 or parts[1] not in mats:
        name = parts[1] if len(parts) > 1 else ""
        raise InputError(f"no material '{name}' in the scene{did_you_mean(name, mats)}", where=f"--free {key}")
    name, leaf = parts[1], ".".join(parts[2:])
    md, m = mats[name], scene.materials[name]
    declared = MODELS[md["model"]].PARAMS
    head = parts[2]
    if head not in declared:
        raise InputError(f"[materials.{name}] (model {md['model']}) has no parameter '{head}'"
                         f"{did_you_mean(head, declared)}; its parameters: {', '.join(declared)}", where=f"--free {key}")
    if head in m.textures:
        tex = m.textures[head]
        colour = head in COLOUR_PARAMS
        data = tex.rgba(colour=colour)[..., :3 if colour else 1].astype(np.float64)
        if texture_size:
            from warp_sg.inverse.outputs import resize

            data = resize(data, texture_size, texture_size)
        lo, hi = _bounds(md["model"], head)
        f = Free(key, "texture", name, head, data, False, lo, hi, colour, {"size": tex.rgba().shape[:2]})
        f.clip()
        return f
    from warp_sg.renderer.gradient_keys import model_params

    params = model_params(m)
    try:
        v = np.asarray(get_leaf(params, leaf), np.float64)
    except (KeyError, TypeError):
        raise InputError(f"[materials.{name}] has no number '{leaf}' to fit", where=f"--free {key}") from None
    if not np.issubdtype(v.dtype, np.number):
        raise InputError(f"[materials.{name}] '{leaf}' is not a number", where=f"--free {key}")
    lo, hi = _bounds(md["model"], leaf)
    f = Free(key, "constant", name, leaf, v, False, lo, hi, v.size == 3)
    f.log = leaf in LOG_PARAMS
    f.set_value(v)
    return f


def _light_free(key, parts, doc, scene, env_lobes) -> Free:
    from warp_sg.inverse.env_basis import basis_axes, basis_sharpness, project_map

    lights = doc.get("lights", [])
    try:
        i = int(parts[1])
        li = lights[i]
        if i < 0:
            raise IndexError
    except (ValueError, IndexError):
        raise InputError(f"the scene has {len(lights)} [[lights]] tables (lights.0 to lights.{len(lights) - 1})",
                         where=f"--free {key}") from None
    light = scene.lights[i]
    if li.get("type") == "environment":
        if len(parts) > 2:
            raise InputError("an environment light is fitted whole: give lights.INDEX", where=f"--free {key}")
        axes, lam = basis_axes(env_lobes), np.full(env_lobes, basis_sharpness(env_lobes))
        mu = project_map(light.base_radiance(), axes, lam)
        floor = 1e-4 * max(float(mu.mean()), 1e-6)
        f = Free(key, "environment", i, "mu", np.zeros_like(mu), True, floor, np.inf, True,
                 {"axes": axes, "lam": lam})
        f.set_value(np.maximum(mu, floor))
        return f
    fld = parts[2] if len(parts) > 2 else "intensity"
    if fld not in LOCAL_FIELDS or (fld == "position" and li.get("type") != "point") or (
            fld == "direction" and li.get("type") != "directional"):
        raise InputError(f"a {li.get('type')} light has no field '{fld}' to fit{did_you_mean(fld, LOCAL_FIELDS)}",
                         where=f"--free {key}")
    v = np.asarray(getattr(light, fld), np.float64)
    f = Free(key, "light", i, fld, v.copy(), fld == "intensity", 0.0 if fld == "intensity" else -np.inf, np.inf, True)
    f.set_value(v)
    return f


def parse_free(keys, doc: dict, scene, env_lobes: int = 64, texture_size: int | None = None) -> list[Free]:
    """The free parameters named by ``keys`` in the scene document ``doc`` (the TOML as read) of
    ``scene`` (module docstring)."""
    out, seen = [], set()
    for key in keys:
        parts = str(key).split(".")
        if parts[0] == "materials":
            f = _material_free(key, parts, doc, scene, texture_size)
        elif parts[0] == "lights" and len(parts) >= 2:
            f = _light_free(key, parts, doc, scene, env_lobes)
        else:
            raise InputError("expected materials.NAME.PARAM, lights.INDEX or lights.INDEX.FIELD"
                             f"{did_you_mean(parts[0], ('materials', 'lights'))}", where=f"--free {key}")
        if (f.kind, f.owner, f.leaf) in seen:
            raise InputError("named twice", where=f"--free {key}")
        seen.add((f.kind, f.owner, f.leaf))
        out.append(f)
    if not out:
        raise InputError("nothing to fit: name at least one key", where="--free")
    return out


def gradient_key(f: Free, scene) -> str:
    """The key of :meth:`Renderer.backward`'s gradients that belongs to ``f``."""
    if f.kind in ("constant", "texture"):
        return f"materials.{f.owner}.{f.leaf}"
    if f.kind == "environment":
        return f"lights.{f.owner}.mu"
    return f"lights.{f.owner}.{f.leaf}"


def apply(frees: list[Free], r) -> None:
    """Put the free parameters' values into renderer ``r`` (materials once each; the environment's
    amplitudes in place)."""
    from dataclasses import replace

    from warp_sg.scene.textures import Texture

    per_material: dict = {}
    for f in frees:
        if f.kind == "constant":
            m = r.scene.materials[f.owner]
            cur = per_material.setdefault(f.owner, dict(m.params))
            v = f.value
            per_material[f.owner] = set_leaf(cur, f.leaf, v.tolist() if v.ndim else float(v))
        elif f.kind == "texture":
            per_material.setdefault(f.owner, dict(r.scene.materials[f.owner].params))
            per_material[f.owner + "\0tex"] = {**per_material.get(f.owner + "\0tex", {}),
                                               f.leaf: Texture(data=f.value.astype(np.float32), srgb=False)}
        elif f.kind == "environment":
            r.set_environment_mixture(f.extra["axes"], f.extra["lam"], f.value)
        else:
            from warp_sg.scene.lights import EnvironmentLight

            local = sum(1 for li in r.scene.lights[:f.owner] if not isinstance(li, EnvironmentLight))
            lights = r.scene.local_lights
            lights[local] = replace(lights[local], **{f.leaf: f.value.copy()})
            r.set_lights(lights)
    for name, params in per_material.items():
        if "\0" in name:
            continue
        texs = per_material.get(name + "\0tex", {})
        heads = {k.split(".")[0] for f in frees if f.kind == "constant" and f.owner == name for k in [f.leaf]}
        r.set_material(name, **{h: params[h] for h in heads}, **texs)


__all__ = ["Free", "parse_free", "apply", "gradient_key", "LOG_PARAMS"]

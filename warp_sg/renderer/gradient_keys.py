r"""A frame's gradients by the scene file's own dotted keys (:mod:`warp_sg.renderer.gradients`).

The adjoint gives gradients of the kernel's inputs: the packed material records (``kd``, ``ks``,
``params``, ``fresnel_a``, ``fresnel_b``), the texture atlas's texels, the light arrays and the
environment mixture's lobes. :func:`scene_gradients` names them as a scene file does:

* ``materials.NAME.PARAM`` for a constant parameter (a number: a float; RGB: (3,); a table such as
  ``fresnel = {schlick = …}``: ``materials.NAME.fresnel.schlick``): the chain rule through the
  model's packing ``record(params)`` (``BRDF.material_record``), whose Jacobian is taken by central
  differences in float64 (the packing is plain Python arithmetic: exact to ~1e-9);
* ``materials.NAME.PARAM`` for a textured parameter: (H, W, C) per texel of the texture's values
  (``offset + scale · texel``, linear; C = 3 for colours, 1 otherwise); ``materials.NAME.normal_map``
  (H, W, 3) per raw texel;
* ``lights.INDEX.intensity`` (3,), ``lights.INDEX.position`` (3,) of a point light, ``lights.INDEX.direction``
  (3,) of a directional light (projected on the plane orthogonal to the unit direction, the only
  directions it can move in), ``lights.INDEX.radius``;
* an environment light given as an SG mixture (``Renderer.set_environment_mixture``):
  ``lights.INDEX.mu`` (K, 3), ``lights.INDEX.axis`` (K, 3, in the map's frame, projected as directions are)
  and ``lights.INDEX.lambda`` (K,), with ``lights.INDEX.scale``.
"""
from __future__ import annotations

import numpy as np

from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.model import COLOUR_PARAMS
from warp_sg.shading.surface import SLOT_NORMAL, param_slots

#: the record's differentiable fields, in the order of :func:`record_vector`
RECORD_FIELDS = (("kd", 3), ("ks", 3), ("params", 4), ("fresnel_a", 3), ("fresnel_b", 3))


def record_vector(model: str, params: dict) -> np.ndarray:
    """The differentiable fields of the packed record of ``model`` with scene parameters ``params``
    (16 floats: kd, ks, params, fresnel_a, fresnel_b)."""
    from warp_sg.brdf import make_model

    rec = make_model(model, **params).material_record()
    return np.concatenate([np.asarray(rec[k], np.float64).reshape(-1)[:n] for k, n in RECORD_FIELDS])


def numeric_leaves(params: dict, prefix: str = ""):
    """``(dotted key, value)`` of every number or numeric list in a parameter table (strings and
    flags skipped): ``{"alpha": 0.3, "fresnel": {"schlick": 0.04}}`` → alpha, fresnel.schlick."""
    for k, v in params.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            yield from numeric_leaves(v, key + ".")
        elif isinstance(v, bool) or isinstance(v, str):
            continue
        elif isinstance(v, (int, float)) or (isinstance(v, (list, tuple, np.ndarray))
                                             and all(isinstance(x, (int, float, np.floating)) for x in np.ravel(v))):
            yield key, v


def set_leaf(params: dict, key: str, value) -> dict:
    """A copy of ``params`` with the dotted ``key`` set to ``value``."""
    out = dict(params)
    head, _, rest = key.partition(".")
    out[head] = set_leaf(dict(out[head]), rest, value) if rest else value
    return out


def get_leaf(params: dict, key: str):
    head, _, rest = key.partition(".")
    return get_leaf(params[head], rest) if rest else params[head]


def model_params(m) -> dict:
    """The scene material's parameters as its model is built (textured ones at their means) plus
    ``kd``/``ks`` at the model's values where the model has them and the file leaves them out."""
    p = dict(m.params)
    for k, tex in m.textures.items():
        mean = tex.mean(colour=k in COLOUR_PARAMS)
        p[k] = mean.tolist() if k in COLOUR_PARAMS else float(mean[0])
    b = m.brdf
    for k in ("kd", "ks"):
        if k not in p and k in type(b).PARAMS and getattr(b, k, None) is not None:
            p[k] = [float(x) for x in np.broadcast_to(np.asarray(getattr(b, k), np.float64), (3,))]
    return p


def record_jacobian(model: str, params: dict, key: str, rel: float = 1e-6) -> np.ndarray:
    """``∂record/∂params[key]`` (16, n) by central differences in float64 (one-sided where the
    parameter's bound refuses a side)."""
    from warp_sg.core.errors import InputError

    v = np.asarray(get_leaf(params, key), np.float64)
    flat = v.reshape(-1)
    cols = []
    for c in range(flat.size):
        h = rel * max(1.0, abs(flat[c]))
        vals = []
        for s in (1.0, -1.0):
            x = flat.copy()
            x[c] += s * h
            val = x.reshape(v.shape).tolist() if v.ndim else float(x[0])
            try:
                vals.append(record_vector(model, set_leaf(params, key, val)))
            except InputError:
                vals.append(None)
        if vals[0] is not None and vals[1] is not None:
            cols.append((vals[0] - vals[1]) / (2.0 * h))
        else:
            base = record_vector(model, params)
            cols.append((vals[0] - base) / h if vals[0] is not None else (base - vals[1]) / h)
    return np.stack(cols, axis=1)


def _material_gradients(r, out: dict) -> None:
    grads = r.material_table.materials.grad.numpy().copy()  # (copies: the next frame zeroes them)
    slots = r.material_textures.slots.numpy()
    atlas = r.material_textures.atlas
    texel_grad = atlas.texels.grad.numpy().copy()
    offs, widths, heights = atlas.offset.numpy(), atlas.width.numpy(), atlas.height.numpy()

    def texture(t):
        o, w, h = int(offs[t]), int(widths[t]), int(heights[t])
        return texel_grad[o:o + w * h].reshape(h, w, 4)

    for mi, name in enumerate(r.geometry.material_names):
        m = r.scene.materials[name]
        g = np.concatenate([np.asarray(grads[f][mi], np.float64).reshape(-1)[:n] for f, n in RECORD_FIELDS])
        params = model_params(m)
        for key, _ in numeric_leaves(params):
            if key in m.textures:
                continue
            jac = record_jacobian(m.model, params, key)
            val = g @ jac
            out[f"materials.{name}.{key}"] = val if np.ndim(get_leaf(params, key)) else float(val[0])
        for pname in m.textures:
            slot = param_slots(m.model, pname)[0]
            t = int(slots[mi, slot])
            if t >= 0:
                tg = texture(t)
                out[f"materials.{name}.{pname}"] = tg[..., :3].copy() if pname in COLOUR_PARAMS else tg[..., :1].copy()
        if m.normal_map is not None and int(slots[mi, SLOT_NORMAL]) >= 0:
            out[f"materials.{name}.normal_map"] = texture(int(slots[mi, SLOT_NORMAL]))[..., :3].copy()


def _tangent(g: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``g`` without its component along the unit vectors ``d`` (rows)."""
    return g - np.sum(g * d, axis=-1, keepdims=True) * d


def _light_gradients(r, es, out: dict) -> None:
    la = r.light_arrays
    vec_g, rad_g, int_g = (a.grad.numpy().copy() for a in (la.vec, la.radius, la.intensity))
    j = 0
    for i, li in enumerate(r.scene.lights):
        if isinstance(li, EnvironmentLight):
            if r.env_mixture and es.count > 0:
                ax, _, mu = r._env_sg_base
                R = li.rotation_matrix()
                g_mu = es.mu.grad.numpy().astype(np.float64)
                out[f"lights.{i}.mu"] = g_mu * li.scale
                out[f"lights.{i}.axis"] = _tangent(es.axis.grad.numpy().astype(np.float64) @ R, ax)
                out[f"lights.{i}.lambda"] = es.lam.grad.numpy().astype(np.float64)
                out[f"lights.{i}.scale"] = float(np.sum(g_mu * mu))
            continue
        out[f"lights.{i}.intensity"] = int_g[j].astype(np.float64)
        out[f"lights.{i}.radius"] = float(rad_g[j])
        if isinstance(li, PointLight):
            out[f"lights.{i}.position"] = vec_g[j].astype(np.float64)
        elif isinstance(li, DirectionalLight):
            d = np.asarray(li.direction, np.float64)
            out[f"lights.{i}.direction"] = _tangent(vec_g[j].astype(np.float64), d)
        j += 1


def scene_gradients(r, es) -> dict:
    """``{scene-file key: gradient}`` of renderer ``r``'s last backward pass (module docstring)."""
    out: dict = {}
    _material_gradients(r, out)
    _light_gradients(r, es, out)
    return out


__all__ = ["scene_gradients", "record_vector", "record_jacobian", "numeric_leaves", "model_params", "RECORD_FIELDS"]

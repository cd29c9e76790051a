r"""One Mitsuba 3 BSDF plugin for every model of :mod:`warp_sg.tools.mitsuba.formulas`.

``mi.load_dict({"type": "warpsg_brdf", "material": KEY})`` gives the BSDF of the material table
registered under ``KEY`` by :func:`register_material` (a scene file's ``[materials.NAME]`` values,
with ``fresnel`` resolved to a dict and a measured material's table loaded). It is a one-sided
reflection BSDF, evaluated in the shading frame Mitsuba builds from the interpolated normal; an
anisotropic model turns that frame about the normal so that x follows the mesh's ``vertex_tangent``
attribute (the per-vertex tangents of the scene's geometry, interpolated and projected onto the
tangent plane).

Sampling (any positive density is unbiased; this one puts samples where the lobe is): with
probability ``pd`` a cosine-weighted direction, else the mirror of a half vector drawn from a GGX
distribution of the model's sampling roughness (:func:`~warp_sg.tools.mitsuba.formulas.sampling_alphas`),
density ``D(h)(n·h)/(4 (o·h))``; ``pd`` = the diffuse share of ``kd`` and ``ks``'s luminance, clamped
to [0.1, 0.9] (1 for diffuse models). ``eval`` returns ``f(o, i) cos θi``, as Mitsuba expects.
"""
from __future__ import annotations

import math

from .formulas import MODELS, sampling_alphas

#: material key → the material table (plain Python values)
_MATERIALS: dict[str, dict] = {}
PLUGIN = "warpsg_brdf"
_REGISTERED: set[str] = set()


def register_material(key: str, table: dict) -> None:
    """Make ``table`` (a material's values) available to the plugin as ``key``."""
    _MATERIALS[str(key)] = dict(table)


def _luminance(v) -> float:
    if v is None:
        return 0.0
    if isinstance(v, (int, float)):
        return float(v)
    v = [float(x) for x in v]
    return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2] if len(v) == 3 else v[0]


def diffuse_probability(p: dict) -> float:
    """Probability of the cosine strategy (module docstring)."""
    if p["model"] in ("lambert", "oren_nayar"):
        return 1.0
    if p["model"] == "measured":
        return 0.5
    ld, ls = _luminance(p.get("kd", 0.0)), _luminance(p.get("ks", 1.0))
    if ld <= 0.0:
        return 0.1
    return min(0.9, max(0.1, ld / (ld + ls)))


def _make_class():
    import drjit as dr
    import mitsuba as mi

    class WarpSgBRDF(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.p = _MATERIALS[str(props["material"])]
            model = self.p["model"]
            if model == "measured":
                from .merl_lookup import merl_brdf

                self.f = merl_brdf(self.p)
            else:
                self.f = MODELS[model]
            self.pd = diffuse_probability(self.p)
            self.alphas = sampling_alphas(self.p)
            self.aniso = any(k in self.p for k in ("alpha_x", "alpha_y")) or model in ("ashikhmin_shirley",
                                                                                    "lafortune", "measured")
            flags = mi.BSDFFlags.FrontSide | mi.BSDFFlags.DiffuseReflection
            if self.alphas is not None:
                flags = flags | mi.BSDFFlags.GlossyReflection
            if self.aniso:
                flags = flags | mi.BSDFFlags.Anisotropic
            self.m_components = [flags]
            self.m_flags = flags

        # -- frames -------------------------------------------------------------------------
        def _rotation(self, si, active):
            """(cos, sin) of the angle from Mitsuba's frame x to the mesh tangent, in the tangent plane."""
            if not self.aniso or si.shape is None:  # (every mesh of scene_dict carries the attribute;
                return None  # a bare interaction of the scalar variant has no shape: Mitsuba's frame)
            t = si.shape.eval_attribute_3("vertex_tangent", si, active)
            tl = si.sh_frame.to_local(mi.Vector3f(t[0], t[1], t[2]))
            ln = dr.sqrt(dr.square(tl.x) + dr.square(tl.y))
            ok = ln > 1e-12
            return dr.select(ok, tl.x / dr.maximum(ln, 1e-12), 1.0), dr.select(ok, tl.y / dr.maximum(ln, 1e-12), 0.0)

        @staticmethod
        def _to(rot, v):
            if rot is None:
                return v
            c, s = rot
            return mi.Vector3f(c * v.x + s * v.y, -s * v.x + c * v.y, v.z)

        @staticmethod
        def _back(rot, v):
            if rot is None:
                return v
            c, s = rot
            return mi.Vector3f(c * v.x - s * v.y, s * v.x + c * v.y, v.z)

        # -- densities ----------------------------------------------------------------------
        def _pdf_local(self, o, i):
            p = self.pd * dr.maximum(i.z, 0.0) / math.pi
            if self.alphas is not None:
                dist = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alphas[0], self.alphas[1], False)
                h = dr.normalize(o + i)
                oh = dr.dot(o, h)
                ph = dist.pdf(o, h) / dr.maximum(4.0 * oh, 1e-20)
                p = p + (1.0 - self.pd) * dr.select((oh > 0.0) & (h.z > 0.0), ph, 0.0)
            return dr.select(i.z > 0.0, p, 0.0)

        def _value_local(self, o, i):
            up = (o.z > 0.0) & (i.z > 0.0)
            return dr.select(up, self.f(self.p, o, i) * dr.maximum(i.z, 0.0), 0.0)

        # -- the BSDF interface -------------------------------------------------------------
        def sample(self, ctx, si, sample1, sample2, active):
            rot = self._rotation(si, active)
            o = self._to(rot, si.wi)
            cos_dir = mi.warp.square_to_cosine_hemisphere(sample2)
            if self.alphas is not None:
                dist = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alphas[0], self.alphas[1], False)
                h, _ = dist.sample(o, sample2)
                spec_dir = 2.0 * dr.dot(o, h) * h - o
                i = dr.select(sample1 < self.pd, cos_dir, spec_dir)
            else:
                i = cos_dir
            pdf = self._pdf_local(o, i)
            value = self._value_local(o, i)
            bs = mi.BSDFSample3f()
            bs.wo = self._back(rot, i)
            bs.pdf = pdf
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection if self.alphas is not None
                                        else +mi.BSDFFlags.DiffuseReflection)
            bs.sampled_component = mi.UInt32(0)
            ok = active & (pdf > 0.0) & (o.z > 0.0)
            return bs, dr.select(ok, value / dr.maximum(pdf, 1e-30), 0.0)

        def eval(self, ctx, si, wo, active):
            rot = self._rotation(si, active)
            return dr.select(active, self._value_local(self._to(rot, si.wi), self._to(rot, wo)), 0.0)

        def pdf(self, ctx, si, wo, active):
            rot = self._rotation(si, active)
            return dr.select(active, self._pdf_local(self._to(rot, si.wi), self._to(rot, wo)), 0.0)

        def eval_pdf(self, ctx, si, wo, active):
            rot = self._rotation(si, active)
            o, i = self._to(rot, si.wi), self._to(rot, wo)
            return dr.select(active, self._value_local(o, i), 0.0), dr.select(active, self._pdf_local(o, i), 0.0)

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"WarpSgBRDF[{self.p['model']}]"

    return WarpSgBRDF


def ensure_registered() -> None:
    """Register the plugin with Mitsuba for the current variant (once per variant)."""
    import mitsuba as mi

    v = mi.variant()
    if v in _REGISTERED:
        return
    cls = _make_class()
    mi.register_bsdf(PLUGIN, lambda props: cls(props))
    _REGISTERED.add(v)


__all__ = ["register_material", "ensure_registered", "diffuse_probability", "PLUGIN"]

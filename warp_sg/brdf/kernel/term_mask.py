"""A BRDF model with its diffuse and/or specular term hidden (``Renderer.set_terms``)."""
from __future__ import annotations


class TermMask:
    """A BRDF model seen with its kd and/or ks zeroed (:meth:`Renderer.set_terms`); everything
    else (lobes, tables, parameters) is the model's own."""

    def __init__(self, model, diffuse: bool, specular: bool):
        self._model, self._diffuse, self._specular = model, diffuse, specular

    def __getattr__(self, name):
        return getattr(self._model, name)

    def material_record(self):
        rec = dict(self._model.material_record())
        if not self._diffuse:
            rec["kd"] = (0.0, 0.0, 0.0)
        if not self._specular:
            rec["ks"] = (0.0, 0.0, 0.0)
        return rec


__all__ = ["TermMask"]

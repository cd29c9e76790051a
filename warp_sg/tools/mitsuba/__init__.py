"""Mitsuba 3 as an independent peer: the scene format's BRDF models written again from their
published formulas as one Mitsuba BSDF plugin (:mod:`.formulas`, :mod:`.plugin`, :mod:`.merl_lookup`),
and scenes translated from the scene file's own words (:mod:`.scene_dict`). Needs the ``mitsuba``
package (a ``[dev]`` dependency); nothing here imports the renderer's BRDF code."""

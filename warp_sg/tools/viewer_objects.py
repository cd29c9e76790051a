"""The viewer's handles on dynamic objects (``[[objects]] dynamic = true``,
:mod:`warp_sg.renderer.dynamic_objects`): drag an object in the view plane, turn it with a key.

Every dynamic object gets an orange sphere handle at its centre (a pyvista sphere widget, which
moves in the view plane under the mouse). Dragging it moves the object by the handle's
displacement (``Renderer.set_object_transform``: translation, its turn kept); grabbing a handle
selects its object. Key ``o`` turns the selected object by +15° about the vertical axis through
its centre, ``O`` by −15°. No precompute runs: each edit renders the next frame through the
viewport (coarse while dragging, like the camera).
"""
from __future__ import annotations

import numpy as np

from warp_sg.numeric.rigid_motion import motion_about, rotation_about

#: the turn of one key press (degrees)
TURN_STEP = 15.0


class ObjectHandles:
    """Handles of ``editor.renderer``'s dynamic objects (module docstring)."""

    def __init__(self, editor):
        self.editor = editor
        self.renderer = editor.renderer
        r = self.renderer
        self.objects = [k for k, ob in enumerate(r.scene.objects) if ob.dynamic] if r.dynamic is not None else []
        g = r.geometry
        self.rest_centre = {}
        for k in self.objects:
            v = np.asarray(g.vertices)[np.unique(np.asarray(g.triangles)[np.asarray(g.tri_object) == k])]
            self.rest_centre[k] = 0.5 * (v.min(0) + v.max(0))
        self.offset = {k: np.zeros(3) for k in self.objects}
        self.turn = {k: 0.0 for k in self.objects}
        self.selected = self.objects[0] if self.objects else None
        self.widgets = []
        if not self.objects:
            return
        pl, vp = editor.plotter, editor.viewport
        for k in self.objects:
            size = 0.03 * editor.extent
            w = pl.add_sphere_widget(
                lambda c, k=k: editor._edit(f"object.{k}", lambda v, k=k: self.move_object(k, v), tuple(map(float, c))),
                center=tuple(self.rest_centre[k]), radius=size, color="orange", interaction_event="always",
                test_callback=False)
            w.AddObserver("StartInteractionEvent", lambda *_, k=k: (self._select(k), vp.begin_interaction()))
            w.AddObserver("EndInteractionEvent", lambda *_: vp.end_interaction())
            self.widgets.append(w)
        pl.add_key_event("o", lambda: self._turn_key(+TURN_STEP))
        pl.add_key_event("O", lambda: self._turn_key(-TURN_STEP))

    def _select(self, k: int) -> None:
        self.selected = k

    def matrix(self, k: int) -> np.ndarray:
        """Object k's motion: its turn about the vertical through its centre, then its offset."""
        return motion_about(rotation_about([0.0, 1.0, 0.0], self.turn[k]), self.rest_centre[k], self.offset[k])

    def move_object(self, k: int, centre) -> None:
        """Object k's handle moved to ``centre``: the object follows (its turn kept)."""
        self.offset[k] = np.asarray(centre, np.float64) - self.rest_centre[k]
        self.renderer.set_object_transform(k, self.matrix(k))

    def turn_object(self, k: int, degrees: float) -> None:
        """Turn object k by ``degrees`` about the vertical axis through its centre."""
        self.turn[k] = (self.turn[k] + float(degrees)) % 360.0
        self.renderer.set_object_transform(k, self.matrix(k))

    def _turn_key(self, degrees: float) -> None:
        k = self.selected
        if k is not None:
            self.editor._edit(f"turn.{k}", lambda v: self.turn_object(k, degrees), (self.turn[k] + degrees) % 360.0)


__all__ = ["ObjectHandles", "TURN_STEP"]

"""The viewer's editing widgets: sliders, light handles, toggles, keys and click-to-select.

:class:`Editor` puts pyvista widgets on a :class:`warp_sg.tools.viewer.Viewport`'s plotter. Every edit
goes through a ``Renderer`` setter (``set_material``, ``update_light``,
``set_environment_rotation`` / ``_scale``, ``set_terms``) — no precompute — then the viewport
renders: coarse while a widget is dragged (its ``Start``/``EndInteractionEvent`` bracket the
drag), full when it is released.

* Left column: the selected material's parameters with a slider range in the model's ``PARAMS``
  (:mod:`warp_sg.brdf.params`; :func:`slider_params`) — ``kd`` and ``ks`` as the largest channel
  (the hue is kept), and the model's scalar roughness (Phong / Blinn-Phong ``n``, Cook-Torrance /
  Torrance-Sparrow ``m``, Ward and GGX ``alpha`` or ``alpha_x``/``alpha_y``, Ashikhmin-Shirley
  ``nu``/``nv``, Oren-Nayar ``sigma``). Textured parameters have no slider.
  A left click on an object selects its material (``Viewport.pick``).
* Right column: the selected local light's intensity (largest channel, hue kept) and radius;
  the environment's rotation (degrees about +Y) and scale; the display exposure (stops).
* A sphere handle per local light: a point light's position, or, for a directional light, a
  point on the ray from the scene centre whose direction is the light's.
* Check boxes (lower left): shadows (when the scene has SSDF visibility), diffuse, specular, and
  bounces (light that bounces, ``[render] bounces`` > 0: off shows the paper's direct light).
* Keys: ``s`` screenshot (EXR linear + PNG tone-mapped, atomic), ``r`` reset the view to the
  scene camera, ``t`` print timings, ``l`` next light, ``h`` hide/show the widgets.

``Editor.latency`` records, per edit, the seconds from the widget's callback to the new frame on
the texture (what ``docs/benchmarks.md`` reports as slider → frame).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from warp_sg.scene.lights import DirectionalLight, PointLight


def slider_params(params: dict, given) -> list:
    """The parameters of a model's ``PARAMS`` ({name: Param}) that get a slider: those with a
    ``slider`` range, and of a parameter and those given ``instead_of`` it, the ones ``given``
    (Ward's ``alpha_x``/``alpha_y`` when the material sets either, else its ``alpha``)."""
    out = []
    for name, p in params.items():
        if p.slider is None:
            continue
        rivals = [q for q, r in params.items() if r.instead_of == (p.instead_of or name)]
        chosen = any(q in given for q in rivals)
        if not rivals or chosen == (p.instead_of is not None):
            out.append(name)
    return out

_ROW0, _ROW_STEP = 0.86, 0.105
_COLS = ((0.02, 0.30), (0.70, 0.98))


def _peak(c) -> float:
    return float(np.max(np.asarray(c, np.float64)))


def _with_peak(c, value: float) -> list:
    """Colour ``c`` scaled so its largest channel is ``value`` (grey when ``c`` is black)."""
    c = np.asarray(c, np.float64).reshape(-1)
    hue = c / c.max() if c.max() > 0 else np.ones_like(c)
    return (hue * float(value)).tolist()


class Editor:
    """Widgets editing ``viewport.renderer``'s scene (see the module docstring)."""

    def __init__(self, viewport, screenshot_dir=".", screenshot_stem: str = "warp_sg_view"):
        self.viewport = viewport
        self.renderer = viewport.renderer
        self.plotter = viewport.plotter
        self.screenshot_dir = Path(screenshot_dir)
        self.screenshot_stem = screenshot_stem
        self.screenshots = 0
        self.latency: list[dict] = []
        g = self.renderer.input_geometry
        self.material = g.material_names[0] if len(g.material_names) else None
        self.light = 0 if self.renderer.scene.local_lights else None
        self.sliders: dict = {}
        self.spheres: list = []
        self.checkboxes: dict = {}
        self._values: dict = {}
        self._visible = True
        lo, hi = g.vertices.min(0), g.vertices.max(0)
        self.centre = 0.5 * (lo + hi)
        self.extent = float(np.linalg.norm(hi - lo)) or 1.0
        self._info = self.plotter.add_text("", position="upper_left", font_size=8, name="warp_sg_material")
        self._material_sliders()
        self._light_sliders()
        self._scene_sliders()
        self._light_handles()
        self._toggles()
        self._keys()
        from warp_sg.tools.viewer_objects import ObjectHandles

        self.objects = ObjectHandles(self)  # dynamic objects: drag handles, 'o'/'O' turn
        self.plotter.track_click_position(self._on_click, side="left", viewport=True)

    # ------------------------------------------------------------------ edits
    def _edit(self, key: str, apply, value) -> None:
        """A widget's callback: apply the edit (a Renderer setter) and render a frame."""
        if self._values.get(key) == value:
            return  # pyvista calls back once at creation with the current value
        self._values[key] = value
        t0 = time.perf_counter()
        apply(value)
        self.viewport.invalidate()
        self.viewport.draw()
        self.latency.append({"edit": key, "seconds": time.perf_counter() - t0, "coarse": self.viewport.last["coarse"]})

    def _slider(self, key, title, rng, value, col, row, apply) -> None:
        x0, x1 = _COLS[col]
        y = _ROW0 - _ROW_STEP * row
        self._values[key] = float(value)
        vp = self.viewport
        w = self.plotter.add_slider_widget(lambda v: self._edit(key, apply, float(v)), [float(rng[0]), float(rng[1])],
                                           value=float(value), title=title, pointa=(x0, y), pointb=(x1, y),
                                           interaction_event="always", style="modern", title_height=0.018,
                                           fmt="%.3g")
        w.AddObserver("StartInteractionEvent", lambda *_: vp.begin_interaction())
        w.AddObserver("EndInteractionEvent", lambda *_: vp.end_interaction())
        self.sliders[key] = w

    def _remove_sliders(self, prefix: str) -> None:
        for key in [k for k in self.sliders if k.startswith(prefix)]:
            w = self.sliders.pop(key)
            w.Off()
            group = getattr(self.plotter, "widgets", self.plotter)  # pyvista >= 0.47 groups them
            if w in group.slider_widgets:
                group.slider_widgets.remove(w)
            self._values.pop(key, None)

    # ------------------------------------------------------------------ material
    def material_params(self, name: str) -> list:
        """(parameter, low, high, value) of material ``name``'s sliders."""
        m = self.renderer.scene.materials[name]
        model = m.brdf
        params = type(model).PARAMS
        out = []
        for p in slider_params(params, m.params):
            if p in m.textures:
                continue
            (lo, hi), rgb = params[p].slider, params[p].kind == "rgb"
            v = _peak(getattr(model, p)) if rgb else float(getattr(model, p))
            out.append((p, lo, hi, v) if rgb else (p, min(lo, v), max(hi, v), v))
        return out

    def _material_sliders(self) -> None:
        self._remove_sliders("material.")
        name = self.material
        if name is None:
            return
        m = self.renderer.scene.materials[name]
        self._info.SetText(2, f"material: {name} ({m.model}) - click an object to edit its material")
        for row, (p, lo, hi, v) in enumerate(self.material_params(name)):
            self._slider(f"material.{p}", p, (lo, hi), v, 0, row, lambda val, p=p: self.set_material_param(p, val))

    def set_material_param(self, param: str, value: float) -> None:
        m = self.renderer.scene.materials[self.material]
        if param in ("kd", "ks"):
            value = _with_peak(getattr(m.brdf, param), value)
        self.renderer.set_material(self.material, **{param: value})

    def select_material(self, name: str) -> None:
        """Make the sliders edit material ``name``."""
        if name == self.material or name not in self.renderer.scene.materials:
            return
        self.material = name
        self._material_sliders()
        self.plotter.render()

    def _on_click(self, pos) -> None:
        name = self.viewport.pick(*pos)
        if name is not None:
            self.select_material(name)

    # ------------------------------------------------------------------ lights
    def _light_sliders(self) -> None:
        self._remove_sliders("light.")
        j = self.light
        if j is None:
            return
        li = self.renderer.scene.local_lights[j]
        e = _peak(li.intensity)
        self._slider("light.intensity", f"light {j} intensity", (0.0, max(4.0 * e, 1.0)), e, 1, 0,
                     lambda v: self.renderer.update_light(self.light, intensity=_with_peak(
                         self.renderer.scene.local_lights[self.light].intensity, v)))
        hi = 0.5 if isinstance(li, DirectionalLight) else 0.25 * self.extent
        self._slider("light.radius", f"light {j} radius", (0.0, max(hi, li.radius)), li.radius, 1, 1,
                     lambda v: self.renderer.update_light(self.light, radius=v))

    def select_light(self, j: int) -> None:
        n = len(self.renderer.scene.local_lights)
        if n and j % n != self.light:
            self.light = j % n
            self._light_sliders()
            self.plotter.render()

    def handle_centre(self, li) -> np.ndarray:
        """Where light ``li``'s sphere handle sits."""
        if isinstance(li, PointLight):
            return np.asarray(li.position, np.float64)
        return self.centre + np.asarray(li.direction, np.float64) * 0.6 * self.extent

    def move_light(self, j: int, centre) -> None:
        """Light ``j``'s handle moved to ``centre``."""
        li = self.renderer.scene.local_lights[j]
        c = np.asarray(centre, np.float64)
        if isinstance(li, PointLight):
            self.renderer.update_light(j, position=c)
        else:
            d = c - self.centre
            if np.linalg.norm(d) > 1e-9:
                self.renderer.update_light(j, direction=d / np.linalg.norm(d))

    def _light_handles(self) -> None:
        vp = self.viewport
        for j, li in enumerate(self.renderer.scene.local_lights):
            size = max(li.radius if isinstance(li, PointLight) else 0.0, 0.02 * self.extent)
            w = self.plotter.add_sphere_widget(
                lambda c, j=j: self._edit(f"handle.{j}", lambda v, j=j: self.move_light(j, v), tuple(map(float, c))),
                center=tuple(self.handle_centre(li)), radius=size, color="yellow",
                interaction_event="always", test_callback=False)
            w.AddObserver("StartInteractionEvent", lambda *_, j=j: (self.select_light(j), vp.begin_interaction()))
            w.AddObserver("EndInteractionEvent", lambda *_: vp.end_interaction())
            self.spheres.append(w)

    # ------------------------------------------------------------------ environment, exposure, toggles
    def _scene_sliders(self) -> None:
        r = self.renderer
        row = 2
        env = r.env_light
        if env is not None:
            self._slider("env.rotation", "environment rotation", (0.0, 360.0), float(env.rotation) % 360.0, 1, row,
                         r.set_environment_rotation)
            self._slider("env.scale", "environment scale", (0.0, max(4.0, 4.0 * env.scale)), float(env.scale), 1,
                         row + 1, r.set_environment_scale)
            row += 2
        self._slider("view.exposure", "exposure (stops)", (-6.0, 6.0), self.viewport.exposure, 1, row,
                     self.viewport.set_exposure)

    def _toggles(self) -> None:
        r = self.renderer
        names = (["shadows"] if r.shadows else []) + ["diffuse", "specular"] + \
            (["bounces"] if r.shadows and r.scene.render.bounces > 0 else [])  # light that bounces
        for i, name in enumerate(names):
            y = 10 + 28 * i
            self._values[f"toggle.{name}"] = True
            w = self.plotter.add_checkbox_button_widget(
                lambda state, name=name: self._edit(f"toggle.{name}", lambda s: self.renderer.set_terms(**{name: s}),
                                                    bool(state)),
                value=True, position=(10, y), size=22, border_size=2, color_on="white", color_off="grey")
            self.plotter.add_text(name, position=(38, y + 4), font_size=6, name=f"warp_sg_toggle_{name}")
            self.checkboxes[name] = w

    # ------------------------------------------------------------------ keys
    def _keys(self) -> None:
        pl = self.plotter
        pl.add_key_event("s", lambda: self.screenshot())
        pl.add_key_event("t", lambda: print(self.timings_text(), flush=True))
        pl.add_key_event("l", lambda: self.select_light((self.light or 0) + 1))
        pl.add_key_event("h", lambda: self.toggle_widgets())
        if pl.iren is not None:
            # after the interactor style's own 'r' (reset to the bounds): priority below its 0
            pl.iren.interactor.AddObserver("CharEvent", self._on_char, -1.0)

    def _on_char(self, iren, _event) -> None:
        if iren.GetKeySym() == "r":
            self.viewport.reset_view()

    def toggle_widgets(self) -> None:
        self._visible = not self._visible
        for w in list(self.sliders.values()) + self.spheres + list(self.checkboxes.values()):
            (w.On if self._visible else w.Off)()
        self.plotter.render()

    def screenshot(self, stem=None) -> tuple:
        """Write the full-resolution frame: ``<stem>.exr`` (linear) and ``<stem>.png`` (the
        viewer's exposure), each atomically. ``stem`` defaults to ``<dir>/<stem>_NNN``."""
        from warp_sg.core.image_io import save_image

        vp = self.viewport
        if vp.image is None or vp.last.get("coarse", 1) > 1 or vp._dirty:
            vp.render_frame(coarse=False)
        if stem is None:
            self.screenshots += 1
            stem = self.screenshot_dir / f"{self.screenshot_stem}_{self.screenshots:03d}"
        stem = Path(stem)
        exr = save_image(stem.with_suffix(".exr"), vp.image)
        png = save_image(stem.with_suffix(".png"), vp.image, exposure=vp.exposure)
        print(f"wrote {exr} and {png}", flush=True)
        return exr, png

    def timings_text(self) -> str:
        r = self.renderer
        t = r.timings
        lines = [f"precompute {t.get('precompute', 0.0):.2f} s "
                 + " ".join(f"{k}={v:.2f}s" for k, v in t.get("precompute_parts", {}).items()),
                 "last frame: " + " ".join(f"{k}={t[k] * 1e3:.1f}ms" for k in ("raster", "shade", "resolve", "frame")
                                           if k in t)
                 + f"  viewer {self.viewport.last.get('seconds', 0.0) * 1e3:.1f} ms"
                 + f" at {self.viewport.last.get('width')}x{self.viewport.last.get('height')}"]
        if self.latency:
            e = self.latency[-1]
            lines.append(f"last edit '{e['edit']}' -> frame: {e['seconds'] * 1e3:.1f} ms (1/{e['coarse']} resolution)")
        return "\n".join(lines)


__all__ = ["Editor", "slider_params"]

"""Per-interaction latency of the viewer (``warp-sg preview``), measured off-screen.

For each window size, one viewer of ``examples/ward.toml`` (precompute once), then each
interaction driven through its VTK widget / interactor events exactly as a mouse would:

* slider drag (Ward ``alpha``): a value change during the drag → the coarse frame on the texture;
* slider release → the full frame;
* orbit: a mouse move during a left-button drag → the coarse frame; button release → full frame;
* light handle drag end, environment rotation release, shadows toggle → the full frame;
* the VTK draw of the window (texture upload + widgets), added to each figure above.

Median of ``--repeat`` runs, milliseconds. Usage::

    python scripts/viewer_latency.py [--sizes 256 512] [--repeat 5] [-o table.md]
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _ms(f, n):
    out = []
    for i in range(n):
        t = time.perf_counter()
        f(i)
        out.append(time.perf_counter() - t)
    return statistics.median(out) * 1e3


def measure(size: int, repeat: int) -> dict:
    import warp_sg as ws
    from warp_sg.preview import open_viewer

    v = open_viewer(ws.load_scene(ROOT / "examples" / "ward.toml"), off_screen=True, window_size=(size, size),
                    progress=False)
    it = v.plotter.iren.interactor
    it.Initialize()
    vp, ed = v.viewport, v.editor
    ed.select_material("iron")
    win = v.plotter.render_window
    win.Render()
    draw = _ms(lambda i: (vp._vimg.Modified(), win.Render()), repeat)
    res = {"size": f"{size}²", "full frame (render only)": None}
    w = ed.sliders["material.alpha"]
    rep = w.GetRepresentation()

    def drag(i):
        rep.SetValue(0.10 + 0.01 * (i % 5))
        w.InvokeEvent("InteractionEvent")

    w.InvokeEvent("StartInteractionEvent")
    drag(7)  # the first coarse frame sizes the divisor
    res["slider drag → coarse frame"] = _ms(drag, repeat) + draw
    res["coarse divisor"] = f"1/{vp.last['coarse']}"
    w.InvokeEvent("EndInteractionEvent")

    def release(widget, move):
        """Drag (untimed), then the time from the button release to the full frame."""
        out = []
        for i in range(repeat):
            widget.InvokeEvent("StartInteractionEvent")
            move(i)
            widget.InvokeEvent("InteractionEvent")
            t = time.perf_counter()
            widget.InvokeEvent("EndInteractionEvent")
            out.append(time.perf_counter() - t)
        return statistics.median(out) * 1e3

    res["slider release → full frame"] = release(w, lambda i: rep.SetValue(0.15 + 0.01 * (i % 5))) + draw
    res["full frame (render only)"] = vp._full_seconds * 1e3

    def orbit(i):
        it.SetEventPosition(size // 2, size // 2)
        it.LeftButtonPressEvent()
        it.SetEventPosition(size // 2 + 4 + i, size // 2)
        t = time.perf_counter()
        it.MouseMoveEvent()
        vp.update()
        dt_move = time.perf_counter() - t
        t = time.perf_counter()
        it.LeftButtonReleaseEvent()
        vp.update()
        return dt_move, time.perf_counter() - t

    times = [orbit(i) for i in range(repeat)]
    res["orbit move → coarse frame"] = statistics.median(t[0] for t in times) * 1e3 + draw
    res["orbit release → full frame"] = statistics.median(t[1] for t in times) * 1e3 + draw
    h = ed.spheres[0]
    c0 = h.GetCenter()

    res["light handle release → full frame"] = release(
        h, lambda i: h.SetCenter(c0[0] + 0.05 * (i % 3 + 1), c0[1], c0[2])) + draw
    cb = ed.checkboxes["shadows"]

    def toggle(i):
        cb.GetRepresentation().SetState(i % 2)
        cb.InvokeEvent("StateChangedEvent")

    toggle(0), toggle(1)  # compile the shadow-free variant once
    res["shadows toggle → full frame"] = _ms(toggle, repeat) + draw
    res["VTK draw of the window"] = draw
    v.close()
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("-o", "--output", default=None)
    a = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    rows = [measure(s, a.repeat) for s in a.sizes]
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        lines.append("| " + " | ".join(f"{r[k]:.0f}" if isinstance(r[k], float) else str(r[k]) for k in keys) + " |")
    text = "\n".join(lines)
    print(text)
    if a.output:
        Path(a.output).write_text(text + "\n")


if __name__ == "__main__":
    main()

"""Per-interaction latency of the viewer (``warp-sg preview``), measured off-screen.

For each window size, one viewer of ``examples/ward.toml`` (precompute once), then each
interaction driven through its VTK widget / interactor events exactly as a mouse would:

* slider drag (Ward ``alpha``): a value change during the drag → the coarse frame on the texture;
* slider release → the full frame;
* orbit: a mouse move during a left-button drag → the coarse frame; button release → full frame;
* light handle drag end, environment rotation release, shadows toggle → the full frame;
* the VTK draw of the window (texture upload + widgets), added to each figure above.

Median of ``--repeat`` runs, milliseconds: wall-clock, and the process's CPU time (all threads;
on a machine shared with other jobs the wall time grows with the load, the CPU time much less —
on an idle 2-core machine the wall time of the threaded shading is about CPU time / 2). Usage::

    python scripts/viewer_latency.py [--sizes 256 512] [--repeat 5] [-o table.md]
"""
from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


class _Clock:
    """Wall and process CPU time of a block."""

    def __enter__(self):
        self.t, self.c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall, self.cpu = time.perf_counter() - self.t, time.process_time() - self.c


def _median(pairs):
    return tuple(statistics.median(p[i] for p in pairs) * 1e3 for i in (0, 1))


def _ms(f, n):
    out = []
    for i in range(n):
        with _Clock() as c:
            f(i)
        out.append((c.wall, c.cpu))
    return _median(out)


def _plus(a, b):
    return (a[0] + b[0], a[1] + b[1])


def measure(size: int, repeat: int) -> dict:
    import warp_sg as ws
    from warp_sg.tools.preview import open_viewer

    v = open_viewer(ws.load_scene(ROOT / "examples" / "ward.toml"), off_screen=True, window_size=(size, size),
                    progress=False)
    it = v.plotter.iren.interactor
    it.Initialize()
    vp, ed = v.viewport, v.editor
    ed.select_material("iron")
    win = v.plotter.render_window
    win.Render()
    draw = _ms(lambda i: (vp._vimg.Modified(), win.Render()), repeat)
    res = {}
    w = ed.sliders["material.alpha"]
    rep = w.GetRepresentation()

    def drag(i):
        rep.SetValue(0.10 + 0.01 * (i % 5))
        w.InvokeEvent("InteractionEvent")

    w.InvokeEvent("StartInteractionEvent")
    drag(7)  # the first coarse frame sizes the divisor
    res["slider drag → coarse frame"] = _plus(_ms(drag, repeat), draw)
    res["coarse divisor"] = f"1/{vp.last['coarse']}"
    w.InvokeEvent("EndInteractionEvent")

    def release(widget, move):
        """Drag (untimed), then the time from the button release to the full frame."""
        out = []
        for i in range(repeat):
            widget.InvokeEvent("StartInteractionEvent")
            move(i)
            widget.InvokeEvent("InteractionEvent")
            with _Clock() as c:
                widget.InvokeEvent("EndInteractionEvent")
            out.append((c.wall, c.cpu))
        return _plus(_median(out), draw)

    res["slider release → full frame"] = release(w, lambda i: rep.SetValue(0.15 + 0.01 * (i % 5)))

    def orbit(i):
        it.SetEventPosition(size // 2, size // 2)
        it.LeftButtonPressEvent()
        it.SetEventPosition(size // 2 + 4 + i, size // 2)
        with _Clock() as move:
            it.MouseMoveEvent()
            vp.update()
        with _Clock() as up:
            it.LeftButtonReleaseEvent()
            vp.update()
        return (move.wall, move.cpu), (up.wall, up.cpu)

    times = [orbit(i) for i in range(repeat)]
    res["orbit move → coarse frame"] = _plus(_median([t[0] for t in times]), draw)
    res["orbit release → full frame"] = _plus(_median([t[1] for t in times]), draw)
    h = ed.spheres[0]
    c0 = h.GetCenter()

    res["light handle release → full frame"] = release(
        h, lambda i: h.SetCenter(c0[0] + 0.05 * (i % 3 + 1), c0[1], c0[2]))
    cb = ed.checkboxes["shadows"]

    def toggle(state):
        cb.GetRepresentation().SetState(state)
        cb.InvokeEvent("StateChangedEvent")

    toggle(0), toggle(1)  # compile the shadow-free variant once
    offs = []
    for _ in range(repeat):
        with _Clock() as c:
            toggle(0)
        offs.append((c.wall, c.cpu))
        toggle(1)
    res["shadows off → full frame"] = _plus(_median(offs), draw)
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
    import os

    rows = {s: measure(s, a.repeat) for s in a.sizes}
    head = ["interaction"] + [f"{s}² {kind}" for s in a.sizes for kind in ("wall ms", "CPU ms")]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for key in next(iter(rows.values())):
        cells = []
        for s in a.sizes:
            v = rows[s][key]
            cells += [f"{v[0]:.0f}", f"{v[1]:.0f}"] if isinstance(v, tuple) else [str(v), ""]
        lines.append(f"| {key} | " + " | ".join(cells) + " |")
    lines.append(f"\n(load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)")
    text = "\n".join(lines)
    print(text)
    if a.output:
        Path(a.output).write_text(text + "\n")


if __name__ == "__main__":
    main()

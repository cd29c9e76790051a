"""The README's viewer figure: ``warp-sg preview examples/ward.toml`` off-screen with its widgets.

    python scripts/viewer_screenshot.py [-o docs/figures/viewer.png] [--size 384]
"""
from __future__ import annotations

import argparse
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default=str(ROOT / "docs" / "figures" / "viewer.png"))
    ap.add_argument("--size", type=int, default=384)
    a = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    import warp_sg as ws
    from warp_sg.tools.preview import open_viewer

    v = open_viewer(ws.load_scene(ROOT / "examples" / "ward.toml"), off_screen=True, window_size=(a.size, a.size),
                    progress=False)
    v.editor.select_material("iron")
    v.viewport.set_pose((1.2, 1.3, 3.3), (0.0, 0.55, 0.0))
    print(v.screenshot(a.output))
    v.close()


if __name__ == "__main__":
    main()

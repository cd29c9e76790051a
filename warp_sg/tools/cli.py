"""The ``warp-sg`` command line (argparse).

::

    warp-sg render SCENE -o OUT.(exr|png) [--device cpu|cuda|auto] [--supersampling K] [--exposure EV]
    warp-sg render ASSET.(glb|gltf|obj|ply|...) [--env SKY.(hdr|exr)] [--view AZ EL] [--print-scene] -o OUT
    warp-sg preview SCENE|ASSET [--env SKY] [--view AZ EL] [--screenshot PNG] [--window-size W H] [--exposure EV]
    warp-sg reference SCENE -o OUT --spp N         (arguments from warp_sg.groundtruth.reference)
    warp-sg report SCENE -o DIR [--animation JOB.toml]   (arguments from warp_sg.tools.report)
    warp-sg bench                                  (arguments from warp_sg.tools.bench)
    warp-sg precompute SCENE [--cluster local:N|tcp://HOST:PORT]   (warp_sg.distributed.precompute)
    warp-sg batch JOB.toml [--cluster ...]         (warp_sg.distributed.batch)
    warp-sg schema [-o FILE] [--markdown]          (JSON Schema of scene files, warp_sg.scene.schema; or the key reference)
    warp-sg fit SCENE VIEWS --free KEY ... -o FITTED.toml   (warp_sg.inverse.fit)

``render``, ``precompute``, ``report``, ``bench`` and ``batch`` take ``--cluster``: the SSDF precompute
(and batch / reference work) then runs on Dask (docs/distributed.md); without it Dask is not imported.

``--device`` defaults to the scene's ``[render] device`` (``cpu`` unless the scene sets it) in
every subcommand; ``bench``, which has no scene, defaults to ``cpu``.

``reference``, ``report`` and ``bench`` take their arguments and their work from the modules of
the same name (``add_cli_arguments(parser)``, ``cli_main(args) -> int``), imported lazily; a missing
module makes its subcommand say so and exit 2.

Bad input (any :class:`warp_sg.core.errors.InputError`, an unusable output path, an ``OSError`` while
writing) prints one line ``warp-sg: error: ...`` on stderr and exits with status 2 — never a
traceback, never a partial output file (``save_image`` writes atomically; output paths are
checked before any work). ``--exposure`` and ``--view`` take finite numbers only, and ``render``
writes no image with a non-finite pixel (radiance or exposure that overflows float32 is an error).
Every warning is one line ``warp-sg: warning: ...`` (:func:`_show_warning`).
"""
from __future__ import annotations

import argparse
import importlib
import math
import sys
import warnings

from warp_sg.core.device import add_device_argument
from warp_sg.core.errors import InputError
from warp_sg.core.files import check_output_path, make_parents

EXTERNAL = {
    "reference": ("warp_sg.groundtruth.reference", "Monte-Carlo reference image (exact BRDF, ray-traced visibility)"),
    "report": ("warp_sg.tools.report", "error-vs-run-time report against the Monte-Carlo reference"),
    "bench": ("warp_sg.tools.bench", "performance benchmarks (rasterizer, shading, precompute)"),
    "precompute": ("warp_sg.distributed.precompute", "fill the precompute cache of a scene (optionally on Dask)"),
    "batch": ("warp_sg.distributed.batch", "render a batch of frames (animation / parameter grid) on Dask"),
    "fit": ("warp_sg.inverse.fit", "recover materials, textures and lighting from photographs (known geometry)"),
}


class _Fail(Exception):
    """A one-line failure with exit status 2."""


def _positive_int(name):
    def conv(s):
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {s!r}") from None
        if v < 1:
            raise argparse.ArgumentTypeError(f"{name} must be >= 1, got {v}")
        return v

    return conv


def _render_key(key):
    """An option that sets ``[render]`` key ``key``: an integer the scene-file model accepts for it
    (:func:`warp_sg.scene.render_settings.render_table`, the one rule of the key)."""
    def conv(s):
        from warp_sg.scene.render_settings import RenderSettings

        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {s!r}") from None
        try:
            RenderSettings(**{key: v}).validate()
        except InputError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
        return v

    return conv


def _float(s):
    """A finite number (``inf`` and ``nan`` are refused: they make every pixel inf or NaN)."""
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {s!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {s!r}")
    return v


def _finite_image(img, what: str):
    """``img`` if every pixel is finite, else a one-line failure naming ``what`` made it so."""
    import numpy as np

    bad = ~np.isfinite(img)
    if bad.any():
        r, c = (int(x) for x in np.argwhere(bad)[0][:2])
        n = int(bad.reshape(bad.shape[0], bad.shape[1], -1).any(-1).sum())
        raise _Fail(f"{what}: {n} pixel(s) are not finite (first at row {r}, column {c}); float32 holds at "
                    f"most 3.4e38, nothing was written")
    return img


# --------------------------------------------------------------------------------------------
# render
# --------------------------------------------------------------------------------------------
def add_render_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="scene file (TOML), or an asset (.glb, .gltf, .obj, .ply, ...) to render on a "
                                 "ground plane under a sky with a framing camera")
    p.add_argument("-o", "--output", default=None,
                   help="output image: .exr (linear HDR) or .png (sRGB); missing folders are created")
    p.add_argument("--env", default=None, metavar="MAP",
                   help="asset renders: environment map (.hdr or .exr; default: the procedural sky)")
    p.add_argument("--view", type=_float, nargs=2, default=None, metavar=("AZ", "EL"),
                   help="asset renders: camera azimuth and elevation in degrees (default 30 20)")
    p.add_argument("--print-scene", action="store_true",
                   help="print the scene as TOML (with an asset: the scene made for it; -o optional)")
    add_device_argument(p)
    p.add_argument("--spp", "--supersampling", dest="supersampling", type=_render_key("supersampling"),
                   default=None, help="[render] supersampling: the factor k (k×k samples per pixel, box filter)")
    p.add_argument("--exposure", type=_float, default=0.0, help="exposure in stops applied before writing (default 0)")
    p.add_argument("--width", type=_positive_int("--width"), default=None, help="override the camera width")
    p.add_argument("--height", type=_positive_int("--height"), default=None, help="override the camera height")
    p.add_argument("--no-shadows", action="store_true", help="render without SSDF visibility")
    p.add_argument("--first-frame", default=None, metavar="OUT",
                   help="also write the first frame, without SSDF shadows, here (.exr or .png) as soon as it "
                        "is ready; the shadows are computed meanwhile and the final frame goes to -o")
    p.add_argument("--no-progress", action="store_true", help="hide progress bars")
    p.add_argument("--timings", action="store_true", help="print precompute / raster / shade timings")
    p.add_argument("--cluster", default=None, metavar="local:N|tcp://HOST:PORT",
                   help="compute the SSDFs on Dask (docs/distributed.md); default: locally, without Dask")


def _render_scene(args, width=None, height=None):
    """(scene, TOML text) of ``render``'s and ``preview``'s SCENE: a TOML file, or an asset
    (:mod:`warp_sg.scene.importers.asset`, framed at ``width`` × ``height``). Features of an asset that are
    not rendered are reported as one ``warp-sg: warning:`` line each."""
    import warnings
    from pathlib import Path

    from warp_sg.scene.importers.asset import DEFAULT_SIZE, DEFAULT_VIEW, asset_scene
    from warp_sg.scene.importers.gltf import AssetWarning
    from warp_sg.scene.loader import load_scene

    path = Path(args.scene)
    asset = path.suffix.lower() != ".toml"
    if not asset and (args.env is not None or args.view is not None):
        raise _Fail("--env and --view apply to asset renders (a mesh or glTF file), not to a TOML scene")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", AssetWarning)
        if asset:
            scene, text = asset_scene(path, env=args.env, view=args.view or DEFAULT_VIEW,
                                      width=width or DEFAULT_SIZE[0], height=height or DEFAULT_SIZE[1])
        else:
            scene = load_scene(path)
            text = path.read_text(encoding="utf-8") if getattr(args, "print_scene", False) else ""
    for w in caught:
        if issubclass(w.category, AssetWarning):
            print(f"warp-sg: warning: {w.message}", file=sys.stderr)
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return scene, text


def _compile_ahead(args) -> None:
    """An asset rendered on the CPU: the frames' Warp modules start compiling while it is read
    (:func:`warp_sg.renderer.kernel_preload.prefetch_early`)."""
    if not str(args.scene).lower().endswith(".toml") and args.device in (None, "cpu") and not getattr(args, "cluster", None):
        from warp_sg.renderer.kernel_preload import prefetch_early

        prefetch_early("cpu")


def render_main(args) -> int:
    from warp_sg.core.image_io import save_image
    from warp_sg.renderer.renderer import Renderer

    if args.output is None and not args.print_scene:
        raise _Fail("the following argument is required: -o/--output")
    out = None if args.output is None else check_output_path(args.output, create_parents=True)
    first = None
    if getattr(args, "first_frame", None) is not None:
        if args.output is None:
            raise _Fail("--first-frame needs -o/--output (the final frame)")
        if args.cluster:
            raise _Fail("--first-frame computes the shadows on this machine; it cannot be combined with --cluster")
        first = check_output_path(args.first_frame, create_parents=True)
    if out is not None:
        _compile_ahead(args)
    scene, text = _render_scene(args, args.width, args.height)
    if args.print_scene:
        print(text, end="" if text.endswith("\n") else "\n")
    if out is None:
        return 0
    if args.supersampling is not None:
        scene.render.supersampling = args.supersampling
    if args.no_shadows:
        scene.render.shadows = False
    cam = scene.camera
    if args.width or args.height:
        from dataclasses import replace

        scene.camera = replace(cam, width=args.width or cam.width, height=args.height or cam.height)
    if args.cluster:
        from warp_sg.distributed.precompute import renderer

        r = renderer(scene, device=args.device, progress=not args.no_progress, cluster=args.cluster)
    else:
        r = Renderer(scene, device=args.device, progress=not args.no_progress and first is None,
                     progressive=first is not None)
    import numpy as np

    with np.errstate(over="ignore"):  # a gain beyond float32 is reported below
        gain = np.float32(2.0 ** args.exposure) if args.exposure else None

    def frame():
        img = _finite_image(r.render(), "the rendered radiance overflows (an environment or light too bright?)")
        if gain is None:
            return img
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported below
            return _finite_image(img * gain, f"--exposure {args.exposure:g} overflows")

    img = frame()
    if first is not None:
        make_parents(first)
        save_image(first, img)
        print(f"first frame written to {first}", file=sys.stderr)
        r.wait()
        img = frame()
    make_parents(out)  # only now: a failed render leaves nothing behind
    save_image(out, img)
    if args.timings:
        t = r.timings
        parts = ", ".join(f"{k} {v:.3f} s" for k, v in t.get("precompute_parts", {}).items())
        print(f"precompute {t['precompute']:.3f} s ({parts}), raster {t['raster']:.4f} s, shade {t['shade']:.4f} s, "
              f"frame {t['frame']:.4f} s")
    return 0


# --------------------------------------------------------------------------------------------
# preview
# --------------------------------------------------------------------------------------------
def add_preview_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="scene file (TOML), or an asset (.glb, .gltf, .obj, .ply, ...) shown as "
                                 "`warp-sg render` shows it: on a ground plane under a sky, framed")
    p.add_argument("--env", default=None, metavar="MAP",
                   help="assets: environment map (.hdr or .exr; default: the procedural sky)")
    p.add_argument("--view", type=_float, nargs=2, default=None, metavar=("AZ", "EL"),
                   help="assets: camera azimuth and elevation in degrees (default 30 20)")
    p.add_argument("--screenshot", default=None, help="render off-screen into this PNG instead of opening a window")
    add_device_argument(p)
    p.add_argument("--window-size", type=_positive_int("--window-size"), nargs=2, default=None,
                   metavar=("W", "H"), help="window / screenshot size = rendered resolution (default: the scene "
                                            "camera's)")
    p.add_argument("--exposure", type=_float, default=0.0, help="display exposure in stops (default 0)")


def preview_main(args) -> int:
    from warp_sg.tools.preview import preview

    if args.screenshot:
        make_parents(check_output_path(args.screenshot, (".png",), create_parents=True))
    if not math.isfinite(args.exposure):
        raise InputError(f"must be a finite number, got {args.exposure}", where="--exposure")
    size = tuple(args.window_size) if args.window_size else (None, None)
    _compile_ahead(args)
    scene, _ = _render_scene(args, *size)  # an asset: the scene `warp-sg render` makes for it
    preview(scene, screenshot=args.screenshot, device=args.device,
            window_size=tuple(args.window_size) if args.window_size else None, exposure=args.exposure)
    return 0


# --------------------------------------------------------------------------------------------
# schema
# --------------------------------------------------------------------------------------------
def add_schema_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output", default=None,
                   help="write the schema to this file (atomically; missing folders are created) instead of stdout")
    p.add_argument("--markdown", action="store_true",
                   help="the reference of every key as Markdown (docs/scene-keys.md) instead of the JSON Schema")


def schema_main(args) -> int:
    from warp_sg.scene.json_schema import schema_text, write_schema

    text = None
    if args.markdown:
        from warp_sg.scene.key_reference import keys_markdown

        text = keys_markdown()
    if args.output:
        write_schema(args.output, text)
    else:
        sys.stdout.write(text or schema_text())
    return 0


# --------------------------------------------------------------------------------------------
# parser
# --------------------------------------------------------------------------------------------
def _missing_module(name, mod, err):
    def main(args):
        raise _Fail(f"the '{name}' command is not available in this installation ({mod}: {err})")

    return main


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error: ``warp-sg: error: <command>: argument --width: ...`` and exit
    status 2 (argparse prints its usage first: seven lines before the one that matters)."""

    def error(self, message):
        cmd = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        self.exit(2, f"warp-sg: error: {cmd}{message} (see {self.prog} --help)\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser; only the external module of ``command`` (if it is one) is imported."""
    parser = _Parser(
        prog="warp-sg",
        description="All-frequency rendering of dynamic, spatially-varying reflectance with spherical Gaussians "
                    "(Wang et al. 2009) on NVIDIA Warp.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    p = sub.add_parser("render", help="render a scene to an image", description="Render SCENE to OUT (EXR or PNG).")
    add_render_arguments(p)
    p.set_defaults(func=render_main)
    p = sub.add_parser("preview", help="interactive per-pixel viewer and editor (or a headless screenshot)",
                       description="Show SCENE rendered per pixel for the pyvista camera (orbit, pan, zoom), with "
                                   "sliders for materials, lights, environment and exposure, handles for the "
                                   "lights and toggles for shadows / diffuse / specular; click an object to edit "
                                   "its material; keys: s screenshot (EXR + PNG), r reset view, t timings, "
                                   "l next light, h hide widgets. --screenshot PNG renders off-screen.")
    add_preview_arguments(p)
    p.set_defaults(func=preview_main)
    p = sub.add_parser("schema", help="print the JSON Schema of scene files (for editors), or their key reference",
                       description="Print the JSON Schema (Draft 4) of the TOML scene format, for editors' TOML "
                                   "language servers (Taplo / Even Better TOML): see docs/rendering.md, "
                                   "\"Editor completion and validation\"; "
                                   "with --markdown the reference of every key (docs/scene-keys.md).")
    add_schema_arguments(p)
    p.set_defaults(func=schema_main)
    for name, (mod, help_) in EXTERNAL.items():
        p = sub.add_parser(name, help=help_, description=help_)
        if name != command:
            p.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
            continue
        try:
            m = importlib.import_module(mod)
            m.add_cli_arguments(p)
            p.set_defaults(func=m.cli_main)
        except (ImportError, AttributeError) as e:
            p.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
            p.set_defaults(func=_missing_module(name, mod, e))
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Every warning as one line ``warp-sg: warning: ...``: ours (:class:`~warp_sg.core.errors.InputWarning`,
    asset notes) as they are, a library's (numpy, trimesh, Pillow) prefixed with its name and kind."""
    from pathlib import Path

    text = str(message).strip().splitlines()[0] if str(message).strip() else category.__name__
    parts = Path(str(filename)).parts
    ours = "warp_sg" in parts or "precompute" in parts or "raster" in parts
    if not (ours and issubclass(category, UserWarning)):
        lib = next((p for p in parts[::-1] if p in ("numpy", "trimesh", "PIL", "scipy", "warp", "OpenEXR")), None)
        text = f"{lib or Path(str(filename)).stem}: {text} ({category.__name__})"
    print(f"warp-sg: warning: {text}", file=sys.stderr if file is None else file)


def _message(e: BaseException) -> str:
    msg = str(e).strip().replace("\n", " ")
    return msg or type(e).__name__


def main(argv=None) -> int:
    """Entry point of the ``warp-sg`` console script. Returns the exit status."""
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    from warp_sg.core.device import quiet_warp

    quiet_warp()  # keep the terminal for our own output (Warp's banner and module-load lines)
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(command)
    args = parser.parse_args(argv)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")  # each warning once per place it is raised
            # numpy's floating-point notes (overflow, 0/0 in a masked-out branch): the results are
            # checked where they matter (finite images, one-line refusals); not the user's business
            warnings.filterwarnings("ignore", category=RuntimeWarning,
                                    message=r".*(encountered in|Mean of empty slice|Degrees of freedom <= 0)")
            warnings.showwarning = _show_warning
            rc = args.func(args)
        return int(rc or 0)
    except (InputError, _Fail) as e:
        print(f"warp-sg: error: {_message(e)}", file=sys.stderr)
        return 2
    except OSError as e:
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        print(f"warp-sg: error: {where}{e.strerror or _message(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("warp-sg: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

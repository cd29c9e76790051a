"""The README's commands work as written (issue 12): the shell commands of its first code block and
of its "Using it" block are parsed by the real CLI, the cheap ones are run (at small sizes, via
documented flags) with every output redirected into a temporary folder, and every file the README
names exists in the repository. Every project name that the README, ``docs/*.md`` and the docstrings
of the three packages, ``scripts/``, ``examples/`` and ``tests/`` cite (``warp_sg.<module>.<name>``,
``precompute.<name>``, ``raster.<name>``, ``<module>.<function>``, ``<Class>.<member>``) resolves by
import and ``getattr`` (issue 29).

Run in a fresh clone by CI (``.ci/run``), so this is the "newcomer" check of the README.
"""
from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

#: the two newcomer commands (CI and the README's first paragraph rely on them, word for word)
FIRST_COMMANDS = [
    "pip install -e '.[dev]' && warp-sg render examples/cook_torrance.toml -o out/cook_torrance.png",
    "python3 -m pytest -q",
]
SMALL = ["--width", "64", "--height", "64"]


def _blocks(text: str):
    """``(heading, language, body)`` of every fenced code block, in order."""
    out, heading = [], ""
    fence = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
    pos = 0
    for m in fence.finditer(text):
        for line in text[pos:m.start()].splitlines():
            if line.startswith("#"):
                heading = line.lstrip("#").strip()
        out.append((heading, m.group(1), m.group(2)))
        pos = m.end()
    return out


def _lines(body: str) -> list[str]:
    return [ln.strip() for ln in body.splitlines() if ln.strip() and not ln.strip().startswith("#")]


def _commands(line: str) -> list[list[str]]:
    """A shell line split into its ``&&``-joined commands (tokens, comments removed)."""
    cmds, cur = [], []
    for tok in shlex.split(line, comments=True):
        if tok == "&&":
            cmds.append(cur)
            cur = []
        else:
            cur.append(tok)
    return cmds + ([cur] if cur else [])


def _readme_lines() -> tuple[list[str], list[str]]:
    blocks = _blocks(README.read_text(encoding="utf-8"))
    first = blocks[0]
    assert first[1] == "bash", "the README's first code block is the shell quick start"
    using = [b for b in blocks if b[0] == "Using it" and b[1] == "bash"]
    assert len(using) == 1, "the README has one shell block under '## Using it'"
    return _lines(first[2]), _lines(using[0][2])


def _warp_sg_commands() -> list[list[str]]:
    first, using = _readme_lines()
    cmds = [c for line in first + using for c in _commands(line)]
    return [c[1:] for c in cmds if c and c[0] == "warp-sg"]


def _find(sub: str, scene: str | None = None) -> list[str]:
    """The README command for ``warp-sg SUB [SCENE]`` (the first one if several)."""
    for c in _warp_sg_commands():
        if c[0] == sub and (scene is None or scene in c):
            return list(c)
    raise AssertionError(f"the README has no 'warp-sg {sub} {scene or ''}' command")


def _redirect(argv: list[str], tmp: Path) -> list[str]:
    """Outputs under ``out/`` go to ``tmp/out/`` (which does not exist yet)."""
    return [str(tmp / a) if a.startswith("out/") else a for a in argv]


def _cli() -> list[str]:
    exe = Path(sys.executable).parent / ("warp-sg.exe" if os.name == "nt" else "warp-sg")
    if exe.exists():
        return [str(exe)]  # the installed entry point, as the README uses it
    found = shutil.which("warp-sg")
    return [found] if found else [sys.executable, "-m", "warp_sg.tools.cli"]


def _run(argv: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.setdefault("PYVISTA_OFF_SCREEN", "true")
    return subprocess.run(_cli() + argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)


def _ok(res: subprocess.CompletedProcess, *files: Path) -> None:
    assert res.returncode == 0, f"exit {res.returncode}\n{res.stderr[-3000:]}"
    for f in files:
        assert f.is_file() and f.stat().st_size > 0, f"{f} was not written"


# --------------------------------------------------------------------------------------------
# the text
# --------------------------------------------------------------------------------------------
def test_first_block_is_the_newcomer_commands():
    first, _ = _readme_lines()
    assert first == FIRST_COMMANDS


def test_using_it_covers_every_command():
    _, using = _readme_lines()
    subs = {c[1] for line in using for c in _commands(line) if c[0] == "warp-sg"}
    assert {"render", "reference", "report", "preview", "bench"} <= subs


def test_every_readme_command_parses():
    """Each ``warp-sg`` command of the README is accepted by the CLI's own parser and names files
    that exist (also the ones too slow to run here: report, the full bench, the preview window)."""
    from warp_sg.tools.cli import build_parser

    cmds = _warp_sg_commands()
    assert len(cmds) >= 6
    for argv in cmds:
        try:
            args = build_parser(argv[0]).parse_args(argv)
        except SystemExit as e:  # argparse rejects unknown flags with exit 2
            pytest.fail(f"'warp-sg {' '.join(argv)}' is rejected by the CLI (exit {e.code})")
        scene = getattr(args, "scene", None)
        if scene is not None:
            assert (ROOT / scene).is_file(), f"'warp-sg {' '.join(argv)}': no file {scene}"


def _paths(text: str) -> set[str]:
    """Repository paths in backticks: words with a '/' or a file suffix."""
    out = set()
    for tok in re.findall(r"`([^`\n]+)`", text):
        for word in re.split(r"[\s(),]+", tok):
            word = word.strip("'\"")
            if word and ("/" in word or re.search(r"\.(py|md|toml|ipynb)$", word)):
                if not word.startswith(("out/", "~/", "$", "http", ".venv", "-")):
                    out.add(word)
    return out


def test_named_files_exist():
    """Every repository path the README names exists: links, paths in backticks, and in the
    "What is where" table the file names of each row, relative to the row's folder(s)."""
    text = README.read_text(encoding="utf-8")
    prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    missing = [n for n in re.findall(r"\]\(([^)#\s]+)\)", text) if not (ROOT / n).exists()]
    for line in prose.splitlines():
        cells = line.split("|")
        if line.startswith("|") and len(cells) > 2 and "`" in cells[1]:  # table row: `dir/` | names
            bases = [ROOT / d for d in _paths(cells[1])]
            names = _paths("|".join(cells[2:]))
        else:
            bases, names = [ROOT], _paths(line)
        missing += [n for n in sorted(names) if not any((b / n).exists() or (ROOT / n).exists() for b in bases)]
    assert not missing, f"README names files that do not exist: {missing}"


def test_python_snippet_names_exist():
    import warp_sg as ws

    for name in ("load_scene", "Renderer", "render", "reference", "save_image"):
        assert callable(getattr(ws, name)), name
    assert callable(ws.Renderer.render)


# --------------------------------------------------------------------------------------------
# project names cited by the docs and the docstrings resolve
# --------------------------------------------------------------------------------------------
PACKAGES = ("warp_sg", "raster", "precompute")
ALIASES = {"ws": "warp_sg"}  # ``import warp_sg as ws``, as the README and docs write it
#: placeholders of the batch-job keys (``lights.INDEX.FIELD``), not names
PLACEHOLDERS = {"NAME", "INDEX", "FIELD", "PARAM", "N", "KEY"}
_FILE_SUFFIX = re.compile(r"\.(py|md|toml|ipynb|png|jpe?g|exr|hdr|glb|gltf|bin|obj|ply|stl|off|json|npz|npy"
                          r"|binary|txt|sh|csv|ya?ml|log|html|pdf|xyz|so|whl|cfg|ini|zip|gz)$", re.I)
#: a dotted identifier that is not part of a path, a longer dotted word or a quoted string
_DOTTED = re.compile(r"(?<![\w./\-'\"])([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)+)")


def _project_modules() -> list[str]:
    """Every module of the three packages, found by walking their folders (so the check follows a
    restructuring: a short name ``shading.<name>`` is looked up in whichever module ends in ``shading``)."""
    out = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def _project_classes(mods: list[str]) -> dict[str, list[str]]:
    """Class name -> the modules that define it at top level (read with ``ast``, no import)."""
    out: dict[str, list[str]] = {}
    for m in mods:
        path = ROOT / (m.replace(".", "/") + ".py")
        if not path.exists():
            path = ROOT / m.replace(".", "/") / "__init__.py"
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ClassDef):
                out.setdefault(node.name, []).append(m)
    return out


def _members(cls) -> set[str]:
    """Names an instance has beyond ``getattr(cls, ...)``: annotations, Warp struct fields and
    ``self.x = ...`` assignments in the class's source."""
    names = set(getattr(cls, "vars", {}) or {})  # a @wp.struct
    for c in (inspect.getmro(cls) if inspect.isclass(cls) else [getattr(cls, "cls", cls)]):
        names |= set(getattr(c, "__annotations__", {}))
        try:
            src = inspect.getsource(c)
        except (OSError, TypeError):
            continue
        names |= set(re.findall(r"self\.(\w+)\s*(?::[^=\n]+)?=", src))
    return names


def _walk(obj, rest: list[str]) -> bool:
    """``getattr`` along ``rest``, importing submodules that a package does not import itself."""
    for i, part in enumerate(rest):
        if hasattr(obj, part):
            obj = getattr(obj, part)
            continue
        if inspect.ismodule(obj) and hasattr(obj, "__path__"):  # a package
            sub = f"{obj.__name__}.{part}"
            if importlib.util.find_spec(sub) is not None:
                obj = importlib.import_module(sub)
                continue
        return i == len(rest) - 1 and not inspect.ismodule(obj) and part in _members(obj)
    return True


class _Names:
    def __init__(self):
        self.mods = _project_modules()
        self.classes = _project_classes(self.mods)

    def resolves(self, name: str) -> bool | None:
        """None: not a project name; else whether it resolves."""
        parts = name.split(".")
        if any(p in PLACEHOLDERS for p in parts):
            return None
        parts[0] = ALIASES.get(parts[0], parts[0])
        rooted = parts[0] in PACKAGES
        for k in range(len(parts), 0, -1):  # the longest prefix that names a project module
            prefix = ".".join(parts[:k])
            cands = [m for m in self.mods if m == prefix or (not rooted and m.endswith("." + prefix))]
            if cands:
                break
        else:
            if parts[0] in self.classes:  # Class.member
                return any(_walk(importlib.import_module(m), parts) for m in self.classes[parts[0]])
            return None
        if any(_walk(importlib.import_module(m), parts[k:]) for m in cands):
            return True
        if not rooted and importlib.util.find_spec(parts[0]) is not None:
            try:  # a library of the same short name (``distributed.Client``)
                return _walk(importlib.import_module(parts[0]), parts[1:]) or False
            except ImportError:
                return False
        return False


def _cited(text: str, ticks: str) -> set[str]:
    """Dotted names in backticks, and names rooted in a package anywhere in ``text``."""
    out = set()
    for tok in re.findall(ticks, text):
        out |= set(_DOTTED.findall(tok))
    out |= {n for n in _DOTTED.findall(text) if n.split(".")[0] in PACKAGES + tuple(ALIASES)}
    return {n for n in out if not _FILE_SUFFIX.search(n)}


def _docstrings(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    kinds = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)
    return [d for n in ast.walk(tree) if isinstance(n, kinds) and (d := ast.get_docstring(n, clean=False))]


@pytest.fixture(scope="module")
def names():
    return _Names()


def test_names_resolver_rejects_what_does_not_exist(names):
    """The check can fail: a stale name, a stale member and a package-rooted typo are caught, and
    what is not a project name (a library, a file, a placeholder) is left alone."""
    assert names.resolves("warp_sg.sg.inner_product") is True
    assert names.resolves("ws.sg.integral") is True
    assert names.resolves("sg.inner_product") is True  # module.function by the module's short name
    assert names.resolves("raster.rasterize") is True
    assert names.resolves("sg.no_such_function") is False
    assert names.resolves("warp_sg.no_such_module") is False
    assert names.resolves("Renderer.no_such_member") is False
    assert names.resolves("Renderer.render") is True
    assert names.resolves("np.linspace") is None
    assert names.resolves("lights.INDEX.FIELD") is None


def test_docs_name_project_names_that_exist(names):
    """Every project name the README and ``docs/*.md`` cite in backticks (and every name rooted in
    a package anywhere) resolves."""
    bad = []
    for path in [README, *sorted((ROOT / "docs").glob("*.md"))]:
        for n in sorted(_cited(path.read_text(encoding="utf-8"), r"`([^`\n]+)`")):
            if names.resolves(n) is False:
                bad.append(f"{path.relative_to(ROOT)}: {n}")
    assert not bad, "docs name what does not exist:\n" + "\n".join(bad)


def test_docstrings_name_project_names_that_exist(names):
    """Every project name in the docstrings of ``warp_sg/``, ``raster/``, ``precompute/``,
    ``scripts/``, ``examples/`` and ``tests/`` (in ``backticks`` or a ``:func:`` role, or rooted in a
    package) resolves."""
    bad = []
    files = [p for pkg in (*PACKAGES, "scripts", "examples", "tests") for p in sorted((ROOT / pkg).rglob("*.py"))]
    for path in files:
        cited = set()
        for doc in _docstrings(path):
            cited |= _cited(doc, r"`+~?([^`\n]+)`+")
        bad += [f"{path.relative_to(ROOT)}: {n}" for n in sorted(cited) if names.resolves(n) is False]
    assert not bad, "docstrings name what does not exist:\n" + "\n".join(bad)


def test_repository_cites_only_its_own_docs():
    """No file of the repository sends the reader to a design card that is not in it."""
    files = [p for p in ROOT.rglob("*") if p.suffix in {".py", ".md", ".toml", ".ipynb"}
             and not any(part.startswith(".") for part in p.relative_to(ROOT).parts)
             and p.name != "test_readme.py"]
    bad = [str(p.relative_to(ROOT)) for p in files if "DESIGN" + ".md" in p.read_text(encoding="utf-8")]
    assert not bad, f"cite DESIGN.md, which is not in the repository: {bad}"


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return "".join(ch for ch in heading.strip().lower() if ch.isalnum() or ch in "-_ ").replace(" ", "-")


def _prose(text: str) -> str:
    return re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)


def test_doc_links_reach_their_files_and_headings():
    """Every relative link of the README and ``docs/*.md`` reaches a file of the repository, and a
    ``#anchor`` one of that page's headings."""
    bad = []
    for page in [README, *sorted((ROOT / "docs").glob("*.md"))]:
        for target in re.findall(r"\]\(([^)\s]+)\)", _prose(page.read_text(encoding="utf-8"))):
            if target.startswith(("http://", "https://", "mailto:")):
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path) if path else page
            if not dest.exists():
                bad.append(f"{page.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and dest.suffix == ".md":
                heads = {_slug(ln.lstrip("#")) for ln in _prose(dest.read_text(encoding="utf-8")).splitlines()
                         if ln.startswith("#")}
                if anchor not in heads:
                    bad.append(f"{page.relative_to(ROOT)}: {target} (no such heading)")
    assert not bad, "links that lead nowhere:\n" + "\n".join(bad)


# --------------------------------------------------------------------------------------------
# the commands, run
# --------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_quick_start_render(tmp_path):
    """``warp-sg render examples/cook_torrance.toml -o out/cook_torrance.png`` at 64², into a
    folder that does not exist yet."""
    argv = _redirect(_find("render", "examples/cook_torrance.toml"), tmp_path)
    out = tmp_path / "out" / "cook_torrance.png"
    assert str(out) in argv
    _ok(_run(argv + SMALL + ["--no-progress"]), out)


def test_render_exr_device_auto(tmp_path):
    """``warp-sg render examples/shadows.toml -o out/shadows.exr --device auto`` at 64²; the SSDF
    precompute of this scene takes a minute on a fresh cache, so shadows are off here (the shadow
    path is covered by the quick-start render and tests/test_render.py)."""
    argv = _redirect(_find("render", "examples/shadows.toml"), tmp_path)
    assert "--device" in argv
    out = tmp_path / "out" / "shadows.exr"
    _ok(_run(argv + SMALL + ["--no-shadows", "--no-progress"]), out)


def _reference_argv(tmp_path: Path) -> list[str]:
    argv = _redirect(_find("reference"), tmp_path)
    i = argv.index("--spp")
    argv[i + 1] = "1"  # 256 spp is minutes; one sample per sub-pixel checks the command
    return argv + ["--no-progress"]


def test_reference_into_an_existing_folder(tmp_path):
    (tmp_path / "out").mkdir()
    argv = _reference_argv(tmp_path)
    _ok(_run(argv), Path(argv[argv.index("-o") + 1]))


def test_reference_creates_missing_folders(tmp_path):
    """As written in the README, ``-o out/...`` into a fresh checkout where ``out/`` (here
    ``tmp/out/sub/dir``) does not exist yet."""
    argv = _reference_argv(tmp_path)
    i = argv.index("-o")
    out = tmp_path / "out" / "sub" / "dir" / "ref.exr"
    argv[i + 1] = str(out)
    _ok(_run(argv), out)


@pytest.mark.slow
def test_preview_screenshot(tmp_path):
    """``warp-sg preview examples/ward.toml --screenshot out/ward_preview.png`` in a 64² window."""
    argv = _redirect(next(c for c in _warp_sg_commands() if c[0] == "preview" and "--screenshot" in c), tmp_path)
    out = tmp_path / "out" / "ward_preview.png"
    assert str(out) in argv
    _ok(_run(argv + ["--window-size", "64", "64"]), out)


def test_bench_help():
    """``warp-sg bench`` itself runs for minutes (tests/test_bench.py runs its quick mode)."""
    assert _find("bench")
    res = _run(["bench", "--help"], timeout=120)
    _ok(res)
    assert "--quick" in res.stdout


# --------------------------------------------------------------------------------------------
# "Render your own asset"
# --------------------------------------------------------------------------------------------
def _asset_commands() -> list[list[str]]:
    """The ``warp-sg`` commands of the block under '## Render your own asset' (a ``>`` redirection
    and what follows it dropped)."""
    blocks = [b for b in _blocks(README.read_text(encoding="utf-8"))
              if b[0] == "Render your own asset" and b[1] == "bash"]
    assert len(blocks) == 1, "the README has one shell block under '## Render your own asset'"
    cmds = [c for line in _lines(blocks[0][2]) for c in _commands(line)]
    return [c[1:c.index(">")] if ">" in c else c[1:] for c in cmds if c and c[0] == "warp-sg"]


@pytest.mark.slow
def test_render_your_own_asset_renders_and_prints_a_scene_that_loads(tmp_path):
    """The one-command glTF render under the ``.hdr`` sky, at 64×48 without shadows (the SSDF of the
    asset's ground takes minutes on a fresh cache; tests/test_asset_scene.py covers the scene), and
    ``--print-scene``, whose TOML loads back as a scene."""
    from warp_sg.scene.loader import load_scene
    from warp_sg.tools.cli import build_parser

    render, printed, first, preview = _asset_commands()
    assert preview[0] == "preview" and preview[1:] == render[1:render.index("-o")]  # the same asset, the same sky
    for argv in (render, printed, first, preview):
        args = build_parser(argv[0]).parse_args(argv)
        assert (ROOT / args.scene).is_file() and (args.env is None or (ROOT / args.env).is_file())
    args = build_parser(first[0]).parse_args(first)  # the progressive render (tests/test_progressive.py)
    assert args.first_frame and args.output and args.first_frame != args.output
    assert "--env" in render and render[render.index("--env") + 1].endswith(".hdr")
    out = tmp_path / "out" / "still_life.png"
    argv = _redirect(render, tmp_path)
    assert str(out) in argv
    _ok(_run(argv + ["--width", "64", "--height", "48", "--no-shadows", "--no-progress"], timeout=600), out)
    res = _run(printed)
    _ok(res)
    (tmp_path / "scene.toml").write_text(res.stdout)
    scene = load_scene(tmp_path / "scene.toml")
    assert {"asset/tiles", "asset/gold", "asset/copper", "asset/red_plastic"} <= set(scene.material_names)

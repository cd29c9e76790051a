"""Every third-party import in the project is a declared dependency.

A new user installs ``pip install -e '.[dev]'`` into a bare virtualenv and runs the tests; an
import that only works because the machine happened to have a package (mpmath, once) stops the
suite at collection. This test reads every ``import`` in the packages, tests, scripts, examples
and notebooks (with :mod:`ast`, so imports inside functions count too) and maps each top-level
module to the distribution that installed it (from the installed distributions' file lists).
That distribution must be declared in ``pyproject.toml`` -- the core dependencies or the ``dev``
extra -- or be one that a declared distribution depends on by contract (``CONTRACT``; the test
also checks the parent really requires it). Imports guarded by ``try: ... except ImportError``
may come from any optional extra.
"""
from __future__ import annotations

import ast
import importlib.metadata as md
import json
import re
import sys
from functools import lru_cache
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
SOURCE_DIRS = ("warp_sg", "raster", "precompute", "tests", "scripts", "examples")
# distribution -> the declared distribution that brings it, by that distribution's own contract
CONTRACT = {"ipython": "ipykernel", "vtk": "pyvista", "pydantic-core": "pydantic"}


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _req_name(req: str) -> str:
    return _norm(re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", req).group(1))


def _declared() -> tuple[set[str], set[str]]:
    """(core + dev, every optional extra) as normalised distribution names."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project.get("optional-dependencies", {})
    required = {_req_name(r) for r in project["dependencies"]} | {_req_name(r) for r in extras.get("dev", [])}
    optional = {_req_name(r) for reqs in extras.values() for r in reqs}
    return required, optional


@lru_cache(maxsize=1)
def _module_to_dists() -> dict[str, set[str]]:
    """Top-level importable name -> distributions whose installed files provide it."""
    out: dict[str, set[str]] = {}
    for name, dists in md.packages_distributions().items():
        out.setdefault(name, set()).update(_norm(d) for d in dists)
    for dist in md.distributions():
        for f in dist.files or ():
            parts = f.parts
            if not parts or parts[0].endswith((".dist-info", ".egg-info", ".data")) or parts[0] == "..":
                continue
            top = parts[0].split(".")[0] if len(parts) == 1 else parts[0]
            if len(parts) == 1 and not re.search(r"\.(py|so|pyd)$", parts[0]):
                continue
            out.setdefault(top, set()).add(_norm(dist.metadata["Name"]))
    return out


def _guarded(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> bool:
    """True when ``node`` sits in the body of a ``try`` that catches ImportError."""
    while node in parents:
        parent = parents[node]
        if isinstance(parent, ast.Try) and node in parent.body:
            for h in parent.handlers:
                names = [h.type] if not isinstance(h.type, ast.Tuple) else list(h.type.elts)
                if any(isinstance(n, ast.Name) and n.id in ("ImportError", "ModuleNotFoundError") for n in names):
                    return True
        node = parent
    return False


def _imports(source: str) -> list[tuple[str, bool]]:
    tree = ast.parse(source)
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name.split(".")[0], _guarded(node, parents)) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module.split(".")[0], _guarded(node, parents)))
    return found


def _sources() -> list[tuple[str, str]]:
    out = [(str(p.relative_to(ROOT)), p.read_text()) for d in SOURCE_DIRS for p in sorted((ROOT / d).rglob("*.py"))]
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        for i, cell in enumerate(json.loads(nb.read_text())["cells"]):
            if cell["cell_type"] == "code":
                src = "".join(cell["source"])
                src = "\n".join(line for line in src.splitlines() if not line.lstrip().startswith(("%", "!")))
                out.append((f"{nb.relative_to(ROOT)}[cell {i}]", src))
    return out


def _local_modules() -> set[str]:
    local = {d for d in SOURCE_DIRS if (ROOT / d / "__init__.py").exists()}
    for d in SOURCE_DIRS:
        local |= {p.stem for p in (ROOT / d).rglob("*.py")}
    return local


def test_contract_dependencies_are_really_required_by_their_parents():
    for child, parent in CONTRACT.items():
        reqs = {_req_name(r) for r in (md.requires(parent) or []) if "extra ==" not in r}
        assert child in reqs, f"{parent} no longer requires {child}: declare {child} in pyproject.toml"


def test_every_import_is_a_declared_dependency():
    required, optional = _declared()
    allowed = required | {c for c, p in CONTRACT.items() if p in required}
    local = _local_modules()
    mod2dist = _module_to_dists()
    problems = []
    for where, src in _sources():
        for mod, guarded in _imports(src):
            if mod in sys.stdlib_module_names or mod in local or mod == "__future__":
                continue
            dists = mod2dist.get(mod)
            if not dists:  # not installed here: fine only if guarded or declared (an environment marker)
                if not guarded and _norm(mod) not in required:
                    problems.append(f"{where}: imports {mod!r}, which no installed distribution provides")
                continue
            ok = allowed | optional if guarded else allowed
            if not dists & ok:
                problems.append(f"{where}: imports {mod!r} from {sorted(dists)}, not declared in pyproject.toml")
    assert not problems, "\n".join(sorted(set(problems)))


def test_checker_flags_an_undeclared_import():
    """The check itself can fail: an import of a module nobody declares is reported."""
    mods = dict(_imports("import numpy\ntry:\n    import mitsuba\nexcept ImportError:\n    pass\nimport mpmath as mp\n"))
    assert mods == {"numpy": False, "mitsuba": True, "mpmath": False}
    required, _ = _declared()
    assert "numpy" in required and "warp-lang" in required
    assert _module_to_dists()["warp"] == {"warp-lang"}
    assert "OpenEXR" in _module_to_dists(), "extension-module distributions are mapped from their file lists"


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))

"""The Markdown reference of scene-file keys, ``docs/scene-keys.md`` (``warp-sg schema --markdown``):
every table of the scene-file model with its keys' values, defaults and meanings, read from the
JSON Schema of :mod:`warp_sg.scene.json_schema` — the same models the loader validates with, so
the reference cannot drift from the checks.
"""
from __future__ import annotations

import json
import re

from warp_sg.brdf import MODELS
from warp_sg.scene.json_schema import json_schema

#: (heading, definitions shown under it) in the order of a scene file
SECTIONS = (
    ("[camera]", ("CameraTable",)),
    ("[[objects]]", ("MeshObject", "Primitive_sphere", "Primitive_plane", "Primitive_torus")),
    ("[materials.NAME]", None),  # one table per model of the BRDF registry, in its order
    ("Material values", ("TextureTable", "FresnelTable", "LafortuneLobe")),
    ("[[lights]]", ("PointLightTable", "DirectionalLightTable", "EnvironmentFile", "EnvironmentSky",
                    "EnvironmentConstant", "SkyOptions", "ConstantOptions")),
    ("[render]", ("RenderTable",)),
)


def _num(x) -> str:
    return str(x) if isinstance(x, int) else f"{x:.6g}"


def _bound(node) -> str:
    lo, hi = node.get("minimum"), node.get("maximum")
    if lo is not None and hi is not None:
        return f" in {'(' if node.get('exclusiveMinimum') else '['}{_num(lo)}, {_num(hi)}]"
    if lo is not None:
        return f" {'>' if node.get('exclusiveMinimum') else '≥'} {_num(lo)}"
    return f" ≤ {_num(hi)}" if hi is not None else ""


def _markdown(text: str) -> str:
    """A docstring phrase as Markdown: ``x`` and :role:`x` -> `x`; table cells keep their bars."""
    return " ".join(re.sub(r"(?::\w+:)?``?([^`]+)``?", r"`\1`", text).replace("|", "\\|").split())


def value_text(node: dict) -> str:
    """A short phrase for the values a JSON Schema node accepts (``integer in [1, 16]``)."""
    if "$ref" in node:
        return f"a {node['$ref'].rsplit('/', 1)[-1]}"
    for k in ("oneOf", "anyOf", "allOf"):
        if k in node:
            return " or ".join(dict.fromkeys(value_text(x) for x in node[k]))
    if "enum" in node:
        if len(node["enum"]) > 4:
            return f"one of {len(node['enum'])} names (see its meaning)"
        return " \\| ".join(f'`"{e}"`' for e in node["enum"])
    t = node.get("type")
    if t == "integer":
        return ("odd " if "not" in node else "") + "integer" + _bound(node)
    if t == "number":
        return "number" + _bound(node)
    if t == "boolean":
        return "true or false"
    if t == "string":
        return "a file path" if node.get("minLength") else "string"
    if t == "array":
        item = value_text(node.get("items", {}))
        n = node.get("minItems")
        if n is not None and n == node.get("maxItems"):
            return f"{n} × {item}" + (", not all 0" if "not" in node else "")
        return f"a list of {item.removeprefix('a ')}"
    if t == "object":
        return "a table"
    return "any"


def _default(prop: dict) -> str:
    return f"`{json.dumps(prop['default'], ensure_ascii=False)}`" if "default" in prop else ""


def _table(title: str, props: dict, required=()) -> list[str]:
    out = [title, "", "| key | value | default | meaning |", "|---|---|---|---|"]
    for k, p in props.items():
        out.append(f"| `{k}`{' (required)' if k in required else ''} | {value_text(p)} | {_default(p)} | "
                   f"{_markdown(p.get('description', ''))} |")
    return out + [""]


def _section(tables: dict) -> list[str]:
    """The tables of one heading; the optional keys every one of them has alike are listed once, first."""
    common = {}
    if len(tables) > 1:
        first, *rest = tables.values()
        common = {k: p for k, p in first.get("properties", {}).items()
                  if k not in first.get("required", ()) and all(t.get("properties", {}).get(k) == p for t in rest)}
    out = _table("**Every table below** also takes:", common) if common else []
    for name, d in tables.items():
        props = {k: p for k, p in d.get("properties", {}).items() if k not in common}
        out += _table(f"**{name}** — {_markdown(d.get('description', ''))}", props, set(d.get("required", ())))
    return out


def keys_markdown() -> str:
    """The text of ``docs/scene-keys.md``."""
    defs = json_schema()["definitions"]
    lines = ["# Scene file keys", "",
             "Every key of a scene file (TOML): its values, default and meaning, generated from the scene-file",
             "model that `load_scene` validates with (`warp-sg schema --markdown -o docs/scene-keys.md`; do not",
             "edit). The same model is `docs/scene.schema.json` for editors; how the keys are used:",
             "[rendering.md](rendering.md) \"Scene files\".", ""]
    for heading, names in SECTIONS:
        if names is None:
            names = tuple(f"Material_{m}" for m in MODELS)
        lines += [f"## {heading}", "", *_section({n: defs[n] for n in names})]
    return "\n".join(lines).rstrip() + "\n"


__all__ = ["keys_markdown", "value_text", "SECTIONS"]

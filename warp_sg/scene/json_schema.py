r"""The JSON Schema of scene files, from :class:`warp_sg.scene.schema.SceneFile` (what ``warp-sg schema``
prints: ``docs/scene.schema.json``).

The JSON Schema is Draft 4 (the newest draft Taplo documents): ``const`` is written as a one-value
``enum``, exclusive bounds as ``"exclusiveMinimum": true``, ``$defs`` as ``definitions``, and a
``$ref`` with a description is wrapped in ``allOf`` (Draft 4 ignores a ``$ref``'s siblings).
"""
from __future__ import annotations

import json
from pathlib import Path

from warp_sg.core.errors import InputError
from warp_sg.core.files import atomic_output, make_parents
from warp_sg.scene.schema import DRAFT, SceneFile


def _draft4(node):
    """Pydantic's schema (2020-12 flavoured) rewritten in Draft 4 terms (see the module docstring)."""
    if isinstance(node, list):
        return [_draft4(x) for x in node]
    if not isinstance(node, dict):
        return node
    out = {}
    for k, v in node.items():
        if k == "$defs":
            out["definitions"] = {n: _draft4(s) for n, s in v.items()}
        elif k == "$ref":
            out[k] = v.replace("#/$defs/", "#/definitions/")
        elif k == "const":
            out["enum"] = [v]
        elif k == "properties":  # property names are data, not keywords
            out[k] = {n: _draft4(s) for n, s in v.items()}
        else:
            out[k] = _draft4(v)
    if "$ref" in out and len(out) > 1:
        ref = out.pop("$ref")
        out = {"allOf": [{"$ref": ref}], **out}
    if out.get("default", 0) is None:  # "unset" in the models: no default to show
        out.pop("default")
    if out.get("type") == "string" and "enum" in out and len(out["enum"]) == 1:
        out.pop("type")
    return out


def _merged(branches: list, defs: dict) -> dict | None:
    """For a ``oneOf`` of table definitions: every key any branch allows (its schema where the
    branches agree, else only its description; a tag key's enums joined) and
    ``additionalProperties: false``. Validators then name a misspelt key itself ("'rougness' was
    unexpected") instead of only "not valid under any of the schemas listed in 'oneOf'", and
    editors complete keys and tag values before the branch is known."""
    tables = [defs[b["$ref"].split("/")[-1]] for b in branches if set(b) == {"$ref"}]
    if len(tables) != len(branches) or not all(t.get("additionalProperties") is False for t in tables):
        return None
    props: dict = {}
    for t in tables:
        for k, v in t["properties"].items():
            props.setdefault(k, []).append(v)
    out = {}
    for k, vs in props.items():
        desc = " | ".join(dict.fromkeys(v.get("description", k) for v in vs))
        bare = [{a: b for a, b in v.items() if a not in ("description", "title")} for v in vs]
        if all(set(v) <= {"enum"} for v in bare):
            out[k] = {"enum": list(dict.fromkeys(e for v in bare for e in v["enum"])), "description": desc}
        elif all(v == bare[0] for v in bare):
            out[k] = {**bare[0], "description": desc}
        else:
            out[k] = {"description": desc}
    required = set.intersection(*(set(t.get("required", ())) for t in tables))
    return {"type": "object", "properties": out, "additionalProperties": False,
            **({"required": sorted(required)} if required else {})}


def _merge_unions(node, defs):
    if isinstance(node, list):
        return [_merge_unions(x, defs) for x in node]
    if not isinstance(node, dict):
        return node
    node = {k: _merge_unions(v, defs) for k, v in node.items()}
    if "oneOf" in node and (m := _merged(node["oneOf"], defs)) is not None:
        node = {**m, **node}
    return node


def json_schema() -> dict:
    """The JSON Schema (Draft 4) of scene files, from :class:`SceneFile`."""
    s = _draft4(SceneFile.model_json_schema())
    s = _merge_unions(s, s["definitions"])
    s.pop("title", None)
    return {"$schema": DRAFT, "title": "warp-sg scene file", **s}


def schema_text() -> str:
    """:func:`json_schema` as the text of ``docs/scene.schema.json`` (2-space indent, UTF-8)."""
    return json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"


def write_schema(path, text: str | None = None) -> Path:
    """Write ``text`` (default :func:`schema_text`) to ``path`` atomically (missing folders are created)."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder, not a file", where=str(p))
    make_parents(p)
    with atomic_output(p) as tmp:
        Path(tmp).write_text(schema_text() if text is None else text, encoding="utf-8")
    return p


__all__ = ["json_schema", "schema_text", "write_schema"]

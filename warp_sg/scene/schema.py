r"""Typed models of the TOML scene format (pydantic v2); their JSON Schema is :mod:`warp_sg.scene.json_schema`'s.

:class:`SceneFile` is the whole file: ``[camera]``, ``[[objects]]``, ``[materials.NAME]``,
``[[lights]]`` and ``[render]`` (field meanings in :mod:`warp_sg.scene`). ``warp_sg.scene.loader``
validates the parsed TOML with it and turns the validated tables into :class:`~warp_sg.scene.Scene`
records; :func:`warp_sg.scene.json_schema.json_schema` is what ``warp-sg schema`` prints
(``docs/scene.schema.json``), so
editors with a TOML language server (Taplo / "Even Better TOML") complete keys and flag mistakes
while a scene is typed.

The schema follows the code, not a copy of it: material tables have one branch per entry of
``warp_sg.brdf.MODELS`` with that model's ``PARAMS`` (a discriminated union on ``model``; each
parameter's kind, bound, meaning and texture rule as the model declares it,
:mod:`warp_sg.brdf.params`), objects
one branch per primitive of ``warp_sg.scene.primitives.PRIMITIVE_PARAMS`` (plus ``mesh``). The tables
whose records a user also builds in Python are defined beside those records and check them too:
``[camera]`` (:class:`warp_sg.scene.camera.CameraTable`), ``[[lights]]``
(:mod:`warp_sg.scene.light_tables`, one branch per ``type``) and ``[render]``
(:func:`warp_sg.scene.render_settings.render_table`).

Leaf values are the types of :mod:`warp_sg.scene.values` (each a check in the project's wording
and the same rule as JSON Schema); :func:`error_message` turns pydantic's first error into the
one-line ``[materials.gold] key 'rougness' unknown — did you mean ...`` form (never a pydantic
dump).
"""
from __future__ import annotations

import inspect
from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, create_model, model_validator

from warp_sg.brdf import MODELS
from warp_sg.brdf.fresnel import PRESETS
from warp_sg.core.suggest import did_you_mean
from warp_sg.scene.camera import CameraTable
from warp_sg.scene.importers import brings_materials, material_suffixes
from warp_sg.scene.light_tables import LIGHT_MODELS, LightTable
from warp_sg.scene.primitives import PRIMITIVE_PARAMS, PRIMITIVES
from warp_sg.scene.render_settings import render_table
from warp_sg.scene.values import (
    Table,
    boolean,
    choice,
    fail,
    failure_text,
    int_or_ints,
    integer,
    number,
    number_or_vector,
    path,
    plain,
    require_tag,
    rgb,
    string,
    tagged,
    vector,
)

DRAFT = "http://json-schema.org/draft-04/schema#"


def _texture_or(value_type, description):
    """A material parameter that may be a texture: the value (unless ``value_type`` is None), a
    texture path or a texture table."""
    def tag(v):
        return "<texture path>" if isinstance(v, str) else "<texture table>" if isinstance(v, dict) else "<value>"

    branches = {"<texture path>": path("texture file (PNG: sRGB for colours; EXR: linear)"),
                "<texture table>": TextureTable}
    if value_type is not None:
        branches = {"<value>": value_type, **branches}
    return Annotated[tagged(branches, tag), Field(description=description)]


class TextureTable(Table):
    """A texture with a value mapping: value = offset + scale · texel."""

    texture: path("texture file (PNG or EXR), relative to the scene file")
    scale: number(description="value = offset + scale · texel") = 1.0
    offset: number(description="value = offset + scale · texel") = 0.0
    srgb: boolean("decode as sRGB (default: PNG colour parameters yes, everything else no)") = None


class FresnelTable(Table):
    """``{schlick = F0}``, ``{eta = η}`` (dielectric) or ``{eta = η, k = k}`` (conductor)."""

    model_config = ConfigDict(json_schema_extra={"anyOf": [{"required": ["schlick"], "maxProperties": 1},
                                                           {"required": ["eta"], "not": {"required": ["schlick"]}}]})
    schlick: rgb(raw=True, hi=1.0, description="Schlick F0 (number or RGB)") = None
    eta: rgb(raw=True, lo_open=True, description="index of refraction η (number or RGB)") = None
    k: rgb(raw=True, description="extinction coefficient k of a conductor (number or RGB)") = None

    @model_validator(mode="after")
    def _combination(self):
        given = {k for k in ("schlick", "eta", "k") if getattr(self, k) is not None}
        if given not in ({"schlick"}, {"eta"}, {"eta", "k"}):
            fail("use {schlick = f0}, {eta = η} or {eta = η, k = k}", sep=": ")
        return self


FRESNEL = tagged({"<preset>": choice(PRESETS, fold_case=True), "<fresnel table>": FresnelTable},
                  lambda v: "<fresnel table>" if isinstance(v, dict) else "<preset>")


class LafortuneLobe(Table):
    """One generalised cosine lobe ``(cx ux vx + cy uy vy + cz uz vz)^n``."""

    cx: number(description="weight of ux vx (−1 with cy = −1, cz = 1: a mirror-like lobe)")
    cy: number(description="weight of uy vy")
    cz: number(description="weight of uz vz")
    n: number(lo=0, description="exponent (sharpness)")


_POS = dict(lo=0, lo_open=True)


def param_value(param):
    """The value type of a model parameter (a :class:`warp_sg.brdf.params.Param` of ``PARAMS``)."""
    if param.kind == "rgb":
        return rgb(raw=True)
    if param.kind == "number":
        return number(lo=param.lo, lo_open=param.lo_open)
    if param.kind == "integer":
        return integer(lo=param.lo, odd=param.odd)
    if param.kind == "fresnel":
        return FRESNEL
    if param.kind == "file":
        return path()
    return Annotated[list[LafortuneLobe], Field(min_length=1)]  # "lafortune_lobes"


#: parameters that may be a texture, over every model (the kernel's texture slots, ``warp_sg.shading.surface``)
TEXTURE_PARAMS = tuple(dict.fromkeys(k for cls in MODELS.values() for k, p in cls.PARAMS.items() if p.texture))


def _material_model(name: str, cls):
    """The table of ``[materials.X] model = name``: the model's ``PARAMS`` (defaults shown from its
    constructor) plus ``normal_map`` and ``tangent_map``."""
    sig = inspect.signature(cls.__init__).parameters
    fields_ = {"model": (Literal[name], Field(description=f"BRDF model {cls.__name__}"))}
    for p, param in cls.PARAMS.items():
        typ, desc = param_value(param), param.description
        d = sig[p].default if p in sig else None
        extra = {"default": plain(d)} if d not in (None, inspect.Parameter.empty) else None
        typ = _texture_or(typ, desc) if param.texture else Annotated[typ, Field(description=desc)]
        fields_[p] = (typ, Field(None, json_schema_extra=extra))
    for p, desc in (("normal_map", "tangent-space normal map (RGB)"),
                    ("tangent_map", "tangent direction map (RG)")):
        fields_[p] = (_texture_or(None, desc), None)
    return create_model(f"Material_{name}", __base__=Table,
                        __doc__=f"`model = \"{name}\"` ({cls.__name__}): {', '.join(cls.PARAMS)}", **fields_)


def _material_tag(v):
    require_tag(v, "model", tuple(MODELS), "model")
    return v


MATERIAL_MODELS = {name: _material_model(name, cls) for name, cls in MODELS.items()}
MaterialTable = tagged({f"<model {k}>": m for k, m in MATERIAL_MODELS.items()},
                   lambda v: f"<model {v.get('model')}>" if isinstance(v, dict) else None, _material_tag)


_OBJECT_FIELDS = {
    "material": (string("name of a [materials.NAME] table"), ...),
    "name": (string("label used in messages"), None),
    "translate": (vector(description="translation (applied last)"), None),
    "scale": (number_or_vector(3, description="scale: a number or 3 numbers, > 0"), None),
    "rotate": (vector(description="Euler angles (degrees) about X, then Y, then Z: P' = translate + Rz·Ry·Rx·"
                                  "(scale ⊙ P)"), None),
    "dynamic": (boolean("the object may move after the precompute (Renderer.set_object_transform): its "
                        "self-shadows are kept in its own frame, its shadows on others come from proxies"), None),
}
_PRIMITIVE_PARAM_TYPES = {
    "center": vector(description="centre"),
    "radius": number(**_POS, description="sphere radius"),
    "major_radius": number(**_POS, description="radius of the ring (axis +Y)"),
    "minor_radius": number(**_POS, description="radius of the tube"),
    "size": number_or_vector(2, description="[sx, sz] (normal +Y) or one number"),
    "resolution": int_or_ints(2, description="tessellation: [n_theta, n_phi] (sphere), [nx, nz] (plane; SSDF "
                                             "shadows need vertices), [n_major, n_minor] (torus), or one integer "
                                             "for both"),
}


def _suffix_pattern(suffixes) -> str:
    """A case-insensitive ECMA-262 pattern for file names ending in one of ``suffixes``."""
    alt = "|".join("".join(f"[{c.lower()}{c.upper()}]" if c.isalpha() else c for c in s.lstrip(".")) for s in suffixes)
    return rf"\.({alt})$"


class _MeshObjectBase(Table):
    """A mesh file; a glTF (.glb/.gltf) or USD (.usd/.usda/.usdc/.usdz) brings its own materials
    (:mod:`warp_sg.scene.importers.gltf`, :mod:`warp_sg.scene.importers.usd`), any other mesh needs ``material``."""

    model_config = ConfigDict(json_schema_extra={"anyOf": [
        {"required": ["material"]}, {"properties": {"mesh": {"pattern": _suffix_pattern(material_suffixes())}}}]})

    @model_validator(mode="after")
    def _material_unless_gltf(self):
        if self.material is None and not brings_materials(self.mesh):
            fail("is missing (only a .glb/.gltf or USD file brings its own materials)", key="material")
        return self


def _object_model(prim: str | None):
    f = dict(_OBJECT_FIELDS)
    if prim is None:
        f["mesh"] = (path("mesh file (any format trimesh reads; .glb/.gltf and USD with their materials), "
                          "relative to the scene file"), ...)
        f["material"] = (string("name of a [materials.NAME] table (optional for .glb/.gltf and USD: the file's)"),
                         None)
        return create_model("MeshObject", __base__=_MeshObjectBase, __doc__=_MeshObjectBase.__doc__, **f)
    f["primitive"] = (Literal[prim], Field(description="built-in primitive"))
    for k, default in PRIMITIVE_PARAMS[prim].items():
        f[k] = (_PRIMITIVE_PARAM_TYPES[k], Field(default=list(default) if isinstance(default, tuple) else default))
    return create_model(f"Primitive_{prim}", __base__=Table, __doc__=f"A {prim} primitive.", **f)


def _object_tag(v):
    if not isinstance(v, dict):
        fail(f"must be a table, got {type(v).__name__}")
    if "mesh" not in v and "primitive" not in v:
        typo = next((k for k in v if did_you_mean(k, ("mesh", "primitive"))), None)
        if typo is not None:
            fail(f"unknown{did_you_mean(typo, ('mesh', 'primitive'))}", key=typo)
    if ("mesh" in v) == ("primitive" in v):
        fail("give exactly one of 'mesh' or 'primitive'")
    if "primitive" in v:
        require_tag(v, "primitive", PRIMITIVES, "primitive")
    return v


OBJECT_MODELS = {"<mesh>": _object_model(None), **{f"<primitive {p}>": _object_model(p) for p in PRIMITIVES}}
SceneObjectTable = tagged(OBJECT_MODELS, lambda v: "<mesh>" if "mesh" in v else f"<primitive {v['primitive']}>",
                           _object_tag)

RenderTable = render_table()


class SceneFile(Table):
    """A warp-sg scene file (TOML): camera, objects, materials, lights and render settings."""

    camera: Annotated[CameraTable, Field(description="the camera")]
    objects: Annotated[list[SceneObjectTable], Field(description="[[objects]]: meshes and primitives")] = []
    materials: Annotated[dict[str, MaterialTable],
                         Field(description="[materials.NAME]: a BRDF model and its parameters")] = {}
    lights: Annotated[list[LightTable], Field(description="[[lights]]: point, directional, environment")] = []
    render: Annotated[RenderTable, Field(description="renderer settings")] = RenderTable()


# --------------------------------------------------------------------------------------------
# errors -> one line
# --------------------------------------------------------------------------------------------
_TAGS = {*OBJECT_MODELS, *LIGHT_MODELS, *(f"<model {k}>" for k in MODELS), "<value>", "<texture path>",
         "<texture table>", "<preset>", "<fresnel table>"}


def _table_label(data, loc) -> tuple[str, Any, tuple]:
    """(``[table]`` label, the raw table, the rest of ``loc``) of an error location."""
    if not loc:
        return "", data, ()
    head = loc[0]
    if head in ("objects", "lights") and len(loc) > 1 and isinstance(loc[1], int):
        return f"[[{head}]] #{loc[1] + 1}", data[head][loc[1]], loc[2:]
    if head == "materials" and len(loc) > 1:
        return f"[materials.{loc[1]}]", data["materials"][loc[1]], loc[2:]
    if head in SceneFile.model_fields:
        return f"[{head}]", data.get(head), loc[1:]
    return "", data, loc


def _key_path(raw, rest) -> str:
    """The TOML key path of ``rest`` (union tags dropped): ``kd``, ``lobes[0].cx``."""
    out = ""
    for el in rest:
        if isinstance(el, str) and el in _TAGS and not (isinstance(raw, dict) and el in raw):
            continue
        out += f"[{el}]" if isinstance(el, int) else (f".{el}" if out else el)
        raw = raw[el] if isinstance(raw, (dict, list)) and (el in raw if isinstance(raw, dict) else
                                                            isinstance(el, int) and el < len(raw)) else None
    return out


def error_message(err: dict, data: dict) -> str:
    """One line for one pydantic error dict (``ValidationError.errors()[i]``) on TOML ``data``."""
    loc, typ = tuple(err["loc"]), err["type"]
    label, raw, rest = _table_label(data, loc)
    key = _key_path(raw, rest)
    if typ == "missing":
        if label and not key:
            return f"table {label} is missing"
        text = f"key '{key}' is missing"
    elif typ in ("model_type", "dict_type", "model_attributes_type"):
        got = type(raw if not key else None).__name__
        text = (f"key '{key}' must be a table" if key else f"must be a table, got {got}")
    elif typ == "list_type":
        text = f"key '{key}' must be a list" if key else f"must be an array of tables ([{label}])"
    elif typ == "too_short":
        text = f"key '{key}' must not be empty"
    elif typ == "literal_error":
        text = f"key '{key}' must be {err['ctx']['expected']}"
    else:  # a failed check of ours (its words) or another pydantic error
        text = failure_text(err, key)
    return f"{label} {text}" if label else text


__all__ = ["SceneFile", "CameraTable", "RenderTable", "LightTable", "TextureTable", "FresnelTable", "MATERIAL_MODELS",
           "OBJECT_MODELS", "LIGHT_MODELS", "TEXTURE_PARAMS", "param_value", "error_message",
           "DRAFT"]

"""The scene schema: the typed models behind ``load_scene``, their JSON Schema
(``docs/scene.schema.json``, ``warp-sg schema``) checked with an independent validator (the
``jsonschema`` package, Draft 4 as Taplo reads it), and the one-line errors.

The JSON Schema and the loader are two validators of the same format; the tests feed both the same
TOML and require the same verdict, and compare the schema with the code it describes
(``warp_sg.brdf.MODELS``, the kernel's texture slots, the models' own parameter checks).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import jsonschema
import pytest
import tomllib
from conftest import BALL_ON_FLOOR, replace_once

from warp_sg.brdf import MODELS, make_model
from warp_sg.core.errors import InputError, SceneError
from warp_sg.scene.loader import load_scene

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "docs" / "scene.schema.json"

#: the shared scene (tests/conftest.py) with a gold ball, a floor of default resolution whose grey is
#: one number, and the sky
BASE = replace_once("[render]", """[[lights]]
type = "environment"
procedural = "sky"
options = { sun_intensity = 300.0 }
rotation = 90.0

[render]""", replace_once("kd = [0.8, 0.8, 0.8]", "kd = 0.8", replace_once(
    "size = [4.0, 4.0]\nresolution = [2, 2]\n", "size = [4.0, 4.0]\n", BALL_ON_FLOOR.replace("copper", "gold"))))


@pytest.fixture(scope="module")
def schema():
    return json.loads(COMMITTED.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def validator(schema):
    cls = jsonschema.validators.validator_for(schema)
    assert cls is jsonschema.Draft4Validator  # what Taplo (Even Better TOML) documents
    cls.check_schema(schema)
    return cls(schema)


def _sub(old, new, text=BASE):
    return replace_once(old, new, text)


def _write(tmp_path, text):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


# ---------------------------------------------------------------------------------------------
# the committed schema
# ---------------------------------------------------------------------------------------------
def test_committed_schema_equals_the_generated_one():
    from warp_sg.scene.json_schema import schema_text

    assert COMMITTED.read_text(encoding="utf-8") == schema_text(), \
        "docs/scene.schema.json is stale: run `warp-sg schema -o docs/scene.schema.json`"


def test_every_example_scene_validates_against_the_json_schema(validator):
    """Every ``examples/*.toml`` but the ``warp-sg batch`` job files (``*_job.toml``, which name a
    scene instead of being one) and the photographs of ``warp-sg fit`` (``*_views.toml``: cameras and
    images); ``.taplo.toml`` excludes them the same way."""
    files = sorted((ROOT / "examples").glob("*.toml"))
    jobs = [f for f in files if f.name.endswith("_job.toml")]
    for f in jobs:
        assert {"scene", "output"} <= set(tomllib.loads(f.read_text())), f"{f.name} is not a batch job"
    views = [f for f in files if f.name.endswith("_views.toml")]
    for f in views:
        assert set(tomllib.loads(f.read_text())) == {"views"}, f"{f.name} is not a list of photographs"
    assert views, "examples/fit_views.toml (the fit example's photographs) is gone"
    files = [f for f in files if f not in jobs and f not in views]
    assert len(files) >= 5
    for f in files:
        data = tomllib.loads(f.read_text())
        errors = [e.message for e in validator.iter_errors(data)]
        assert not errors, f"{f.name}: {errors[:3]}"


@pytest.mark.parametrize("material", ["lambert", "blinn_phong", "cook_torrance", "ward"])
def test_plain_input_scenes_validate_against_the_json_schema(tmp_path, validator, material):
    from warp_sg.scene.plain_scenes import write_plain_scene

    p = write_plain_scene(tmp_path, light="sky+point", material=material, render={"shadows": False})
    assert not list(validator.iter_errors(tomllib.loads(p.read_text())))
    assert load_scene(p).materials["object"].model == material


def test_schema_lists_every_model_with_exactly_its_parameters(schema):
    defs = schema["definitions"]
    branches = [r["$ref"].split("/")[-1] for r in
                schema["properties"]["materials"]["additionalProperties"]["oneOf"]]
    assert len(branches) == len(MODELS)
    for name, cls in MODELS.items():
        d = defs[f"Material_{name}"]
        assert f"Material_{name}" in branches
        assert d["properties"]["model"]["enum"] == [name] and d["required"] == ["model"]
        assert set(d["properties"]) == {"model", *cls.PARAMS, "normal_map", "tangent_map"}
        assert d["additionalProperties"] is False


def test_every_key_has_a_description_and_every_render_setting_is_in_the_schema(schema):
    from dataclasses import fields

    from warp_sg.scene.render_settings import RenderSettings

    render = schema["definitions"]["RenderTable"]["properties"]
    assert set(render) == {f.name for f in fields(RenderSettings)}
    for name, d in schema["definitions"].items():
        for key, prop in d.get("properties", {}).items():
            text = prop.get("description", "")
            assert text and text != key, f"{name}.{key} has no description"


def test_texture_parameters_are_the_kernel_texture_slots(schema):
    from warp_sg.scene.schema import TEXTURE_PARAMS
    from warp_sg.shading.surface import param_slots

    # every parameter the schema lets a texture drive has its texture slots (from its Param.kernel)
    slots = {(name, k): param_slots(name, k) for name, cls in MODELS.items() for k, p in cls.PARAMS.items()
             if p.texture}
    assert {k for _, k in slots} == set(TEXTURE_PARAMS) and all(slots.values()), slots
    ct = schema["definitions"]["Material_cook_torrance"]["properties"]
    assert any(b.get("type") == "string" for b in ct["m"]["oneOf"])  # m may be a texture path
    assert "oneOf" not in ct["fresnel"] or all(b.get("$ref", "").endswith("FresnelTable") or "enum" in b
                                               for b in ct["fresnel"]["oneOf"])


def _number_bound(prop):
    """(minimum, exclusive) of the numeric branch of a property schema, or None."""
    for b in [prop, *prop.get("oneOf", []), *prop.get("anyOf", [])]:
        for c in [b, *b.get("anyOf", [])]:
            if c.get("type") == "number" and "minimum" in c:
                return c["minimum"], bool(c.get("exclusiveMinimum"))
    return None


def test_schema_lower_bounds_agree_with_the_models_own_checks(schema):
    """For every bounded number of every model (but measured, which needs a file): the model
    constructor rejects the value just outside the schema's bound and accepts the bound (or just
    inside an exclusive one)."""
    checked = 0
    for name, cls in MODELS.items():
        if name == "measured":
            continue
        props = schema["definitions"][f"Material_{name}"]["properties"]
        for p in cls.PARAMS:
            bound = _number_bound(props[p])
            if bound is None:
                continue
            lo, exclusive = bound
            extra = {}  # roughness of models that take alpha or the pair alpha_x, alpha_y
            if p in ("alpha_x", "alpha_y"):
                extra = {"alpha_x": 0.3, "alpha_y": 0.3}
            elif "alpha" in cls.PARAMS and p != "alpha":
                extra = {"alpha": 0.3}
            with pytest.raises(InputError):
                make_model(name, **{**extra, p: lo if exclusive else lo - 1e-3})
            make_model(name, **{**extra, p: lo + 1e-3 if exclusive else lo})
            checked += 1
    assert checked >= 15


# ---------------------------------------------------------------------------------------------
# one format, two validators: the same verdict
# ---------------------------------------------------------------------------------------------
BAD = [  # (old, new, words of the loader's one-line message)
    ("m = 0.2", "rougness = 0.2", ["[materials.gold]", "key 'rougness' unknown"]),
    ("fov = 40.0", "fvo = 40.0", ["[camera]", "key 'fvo' unknown", "did you mean 'fov'"]),
    ("shadows = false", "shadowz = false", ["[render]", "did you mean 'shadows'"]),
    ("[render]", "[rendr]", ["key 'rendr' unknown", "did you mean 'render'"]),
    ("radius = 0.1", "radios = 0.1", ["[[lights]] #1", "did you mean 'radius'"]),
    ("rotation = 90.0", "rotaton = 90.0", ["[[lights]] #2", "did you mean 'rotation'"]),
    ("sun_intensity = 300.0", "sun_intensty = 300.0", ["[[lights]] #2", "options.sun_intensty",
                                                        "did you mean 'sun_intensity'"]),
    ("sun_intensity = 300.0", "sun_intensity = 300.0, width = 1", ["[[lights]] #2", "key 'options.width' must be >= 2"]),
    ("sun_intensity = 300.0", "sun_intensity = 300.0, sun_direction = [0, 0, 0]",
     ["key 'options.sun_direction' must be a non-zero vector"]),
    ("resolution = [8, 16]", "resolutoin = [8, 16]", ["[[objects]] #1", "did you mean 'resolution'"]),
    ('model = "lambert"', 'modle = "lambert"', ["[materials.floor]", "key 'modle' unknown"]),
    ('fresnel = "gold"', 'fresnel = { eta = 1.5, k = 2.0, schlick = 0.1 }', ["key 'fresnel'"]),
    ('fresnel = "gold"', 'fresnel = "gld"', ["key 'fresnel'", "did you mean 'gold'"]),
    ('fresnel = "gold"', "fresnel = { eta = 0.0 }", ["key 'fresnel", "eta", "> 0"]),  # (issue 51: the schema
    ('fresnel = "gold"', "fresnel = { schlick = [0.5, 1.5, 0.5] }", ["key 'fresnel", "schlick"]),  # allowed these)
    ("m = 0.2", "m = 0.0", ["key 'm' must be > 0"]),
    ("m = 0.2", 'm = { texture = "r.png", scael = 2.0 }', ["key 'm.scael' unknown", "did you mean 'scale'"]),
    ("kd = 0.8", "kd = [0.8, 0.8]", ["[materials.floor]", "key 'kd' must be a number or a list of 3"]),
    ("kd = 0.8", "kd = -0.8", ["key 'kd' must be >= 0"]),
    ("width = 16", "width = 16.0", ["key 'width' must be an integer"]),
    ("fov = 40.0", "fov = 0.0", ["key 'fov' must be > 0"]),
    ("shadows = false", "supersampling = 17", ["key 'supersampling' must be in [1, 16]"]),
    ("shadows = false", 'fh = "tabel"', ["key 'fh' must be 'table' or 'sigmoid'"]),
    ("shadows = false", "shadows = 1", ["key 'shadows' must be true or false"]),
    ('type = "point"', 'type = "spot"', ["[[lights]] #1", "key 'type': unknown light type 'spot'"]),
    ('procedural = "sky"', 'procedural = "sky"\nfile = "sky.exr"', ["give exactly one of 'file' or 'procedural'"]),
    ('primitive = "sphere"', 'primitive = "sphere"\nmesh = "a.obj"', ["give exactly one of 'mesh' or 'primitive'"]),
    ('primitive = "sphere"', 'primitive = "spere"', ["unknown primitive 'spere'", "did you mean 'sphere'"]),
    ('model = "lambert"', 'model = "ashikhmin_shirley"\nlobes = 4', ["key 'lobes' must be an odd integer"]),
    ('model = "lambert"', 'model = "lafortune"\nlobes = []', ["key 'lobes'"]),
    ('model = "lambert"', 'model = "lafortune"\nlobes = [{ cx = 1, cy = 1, cz = 1, m = 2 }]',
     ["key 'lobes[0].m' unknown", "valid keys: cx, cy, cz, n"]),
    ("size = [4.0, 4.0]", "size = [4.0, 0.0]", ["key 'size' must be > 0"]),
    ('type = "point"\nposition = [2.0, 3.0, 2.0]', 'type = "directional"\ndirection = [0.0, 0, 0.0]',
     ["[[lights]] #1 key 'direction' must be a non-zero vector"]),
    ('material = "floor"', "material = 3", ["key 'material' must be a string"]),
    ('primitive = "plane"\nsize = [4.0, 4.0]\nmaterial = "floor"', 'mesh = "floor.obj"',
     ["[[objects]] #2 key 'material' is missing"]),
]


@pytest.mark.parametrize("old,new,words", BAD, ids=[b[1].split("\n")[-1][:32] for b in BAD])
def test_bad_scene_fails_the_json_schema_and_the_loader_with_one_line(tmp_path, validator, old, new, words):
    text = _sub(old, new)
    assert list(validator.iter_errors(tomllib.loads(text))), "the JSON Schema accepts it: editors would not flag it"
    with pytest.raises(SceneError) as ei:
        load_scene(_write(tmp_path, text))
    msg = str(ei.value)
    assert msg.startswith("scene.toml: ") and "\n" not in msg and len(msg) < 400
    assert "pydantic" not in msg.lower() and "validation error" not in msg.lower() and "input_value" not in msg
    for w in words:
        assert w in msg, msg


GOOD = [
    ("kd = 0.8", 'kd = "../albedo.png"'),
    ("m = 0.2", 'm = { texture = "r.png", scale = 0.5, offset = 0.05, srgb = false }'),
    ('fresnel = "gold"', "fresnel = { eta = 1.5 }"),
    ('fresnel = "gold"', "fresnel = { eta = [0.2, 0.4, 1.4], k = 3.0 }"),
    ('fresnel = "gold"', "fresnel = { schlick = [0.9, 0.7, 0.3] }"),
    ('model = "lambert"', 'model = "ashikhmin_shirley"\nlobes = 5\nnu = 10.0\nnv = 100'),
    ('model = "lambert"', 'model = "lafortune"\nlobes = [{ cx = -1, cy = -1, cz = 1, n = 15 }]'),
    ('model = "lambert"', 'model = "ward"\nalpha_x = 0.1\nalpha_y = 0.3'),
    ("radius = 0.5\n", "radius = 0.5\nscale = [1, 2, 1]\nrotate = [0, 90, 0]\ntranslate = [1, 0, 0]\n"),
    ("size = [4.0, 4.0]", "size = 4"),
    ("resolution = [8, 16]", "resolution = 12"),
    ('primitive = "plane"\nsize = [4.0, 4.0]\nmaterial = "floor"', 'mesh = "assets/still_life.GLB"'),
    ('procedural = "sky"\noptions = { sun_intensity = 300.0 }', 'procedural = "constant"\noptions = { radiance = [1, 2, 3] }'),
    ("sun_intensity = 300.0", "sun_intensity = 300.0, sun_direction = [0, 1, 1], sun_color = 0.9, width = 64"),
]


@pytest.mark.parametrize("old,new", GOOD, ids=[g[1].split("\n")[-1][:32] for g in GOOD])
def test_valid_variants_pass_the_json_schema(validator, old, new):
    """Both validators accept these (the loader's side, which needs the texture files, is covered
    by the loading tests; here the structure)."""
    errors = [e.message for e in validator.iter_errors(tomllib.loads(_sub(old, new)))]
    assert not errors, errors


@pytest.mark.parametrize("old,new", [g for g in GOOD if not any(f in g[1] for f in ("texture", ".png", ".GLB"))])
def test_valid_variants_load(tmp_path, old, new):
    sc = load_scene(_write(tmp_path, _sub(old, new)))
    assert sc.material_names == ["gold", "floor"]


def test_loaded_values_keep_the_written_material_parameters_and_the_defaults(tmp_path):
    sc = load_scene(_write(tmp_path, BASE))
    gold = sc.materials["gold"]
    assert gold.params == {"kd": [0.0, 0.0, 0.0], "ks": [1.0, 1.0, 1.0], "m": 0.2, "fresnel": "gold"}
    assert sc.objects[1].params == {"size": (4.0, 4.0)}  # only what the file sets
    point, env = sc.lights
    assert list(point.intensity) == [20.0] * 3 and env.options == {"sun_intensity": 300.0}
    assert env.rotation == 90.0 and env.scale == 1.0
    assert sc.render.shadows is False and sc.render.antialias == 4


# ---------------------------------------------------------------------------------------------
# warp-sg schema
# ---------------------------------------------------------------------------------------------
def test_cli_schema_prints_the_schema_and_writes_it_atomically(tmp_path, capsys):
    from warp_sg.tools.cli import main

    assert main(["schema"]) == 0
    out = capsys.readouterr().out
    assert out == COMMITTED.read_text(encoding="utf-8")
    target = tmp_path / "new" / "scene.schema.json"
    assert main(["schema", "-o", str(target)]) == 0
    assert json.loads(target.read_text()) == json.loads(out)
    assert [p.name for p in target.parent.iterdir()] == ["scene.schema.json"]  # no temporary left
    rc = main(["schema", "-o", str(tmp_path)])  # a folder
    err = capsys.readouterr().err
    assert rc == 2 and "is a folder" in err and len(err.strip().splitlines()) == 1


def test_committed_key_reference_equals_the_generated_one(tmp_path, capsys):
    from warp_sg.scene.key_reference import keys_markdown
    from warp_sg.tools.cli import main

    committed = ROOT / "docs" / "scene-keys.md"
    assert committed.read_text(encoding="utf-8") == keys_markdown(), \
        "docs/scene-keys.md is stale: run `warp-sg schema --markdown -o docs/scene-keys.md`"
    assert main(["schema", "--markdown", "-o", str(tmp_path / "keys.md")]) == 0
    assert (tmp_path / "keys.md").read_text(encoding="utf-8") == committed.read_text(encoding="utf-8")


@pytest.mark.parametrize("node,text", [
    ({"type": "integer", "minimum": 1, "maximum": 16}, "integer in [1, 16]"),
    ({"type": "integer", "minimum": 1, "not": {"multipleOf": 2}}, "odd integer ≥ 1"),
    ({"type": "number", "minimum": 0, "exclusiveMinimum": True, "maximum": 179.0}, "number in (0, 179]"),
    ({"type": "number", "minimum": 0, "exclusiveMinimum": True}, "number > 0"),
    ({"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}, "3 × number"),
    ({"anyOf": [{"type": "number", "minimum": 0}, {"type": "boolean"}]}, "number ≥ 0 or true or false"),
    ({"enum": ["table", "sigmoid"]}, '`"table"` \\| `"sigmoid"`'),
    ({"$ref": "#/definitions/TextureTable"}, "a TextureTable"),
])
def test_key_reference_words_each_json_schema_rule(node, text):
    from warp_sg.scene.key_reference import value_text

    assert value_text(node) == text


def test_key_reference_lists_every_render_setting_and_model_parameter_with_its_rule():
    from dataclasses import fields

    from warp_sg.brdf import MODELS
    from warp_sg.scene.key_reference import keys_markdown
    from warp_sg.scene.render_settings import RenderSettings

    text = keys_markdown()
    render = text.split("## [render]")[1]
    for f in fields(RenderSettings):
        assert f"| `{f.name}` |" in render, f.name
    assert "| `supersampling` | integer in [1, 16] | `1` |" in render
    assert "| `fh` | `\"table\"` \\| `\"sigmoid\"` | `\"table\"` |" in render
    materials = text.split("## [materials.NAME]")[1].split("## Material values")[0]
    for name, cls in MODELS.items():
        block = materials.split(f"**Material_{name}**")[1].split("**Material_")[0]
        assert all(f"| `{p}` |" in block for p in cls.PARAMS), name


def test_fuzzed_values_give_one_line_input_errors_never_pydantic_errors(tmp_path):
    """Every key of the base scene replaced by values of the wrong kind: the loader either accepts
    it or raises one :class:`InputError` line (no ValidationError, TypeError, KeyError ...)."""
    data = tomllib.loads(BASE)
    junk = ["x", -1, 0, 2.5, math.inf, True, [], [1, "a"], {}, {"texture": 3}]
    paths = []

    def walk(node, path):
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, path + [k])
        elif isinstance(node, list) and node and isinstance(node[0], dict):
            for i, v in enumerate(node):
                walk(v, path + [i])
        if path:
            paths.append(path)

    walk(data, [])
    p = tmp_path / "scene.toml"
    failures = 0
    for path in paths:
        for j in junk:
            d = json.loads(json.dumps(data))
            node = d
            for k in path[:-1]:
                node = node[k]
            node[path[-1]] = j
            p.write_text(_toml(d))
            try:
                load_scene(p)
            except InputError as e:
                assert "\n" not in str(e) and str(e).startswith("scene.toml: "), str(e)
                failures += 1
    assert failures > len(paths)  # most junk is rejected


def _toml(d) -> str:
    """A small TOML writer for the fuzz test (tables, arrays of tables, inline values)."""
    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float) and math.isinf(v):
            return "inf" if v > 0 else "-inf"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return "{ " + ", ".join(f"{json.dumps(k)} = {val(x)}" for k, x in v.items()) + " }"

    out = []
    for k, v in d.items():
        if isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                out.append(f"[[{k}]]\n" + "".join(f"{json.dumps(a)} = {val(b)}\n" for a, b in x.items()))
        elif isinstance(v, dict) and k == "materials":
            for name, x in v.items():
                body = "".join(f"{json.dumps(a)} = {val(b)}\n" for a, b in x.items()) if isinstance(x, dict) else ""
                out.append(f"[materials.{json.dumps(name)}]\n{body}" if isinstance(x, dict)
                           else f"[materials]\n{json.dumps(name)} = {val(x)}\n")
        elif isinstance(v, dict):
            out.append(f"[{k}]\n" + "".join(f"{json.dumps(a)} = {val(b)}\n" for a, b in v.items()))
        else:
            out.insert(0, f"{json.dumps(k)} = {val(v)}\n")
    return "\n".join(out)

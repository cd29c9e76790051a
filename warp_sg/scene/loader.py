"""Scene files: :func:`load_scene` reads a TOML scene and validates it with the typed models of
:mod:`warp_sg.scene.schema` (pydantic; the same models give ``warp-sg schema``'s JSON Schema), then
builds the :class:`~warp_sg.scene.Scene` records: files resolved relative to the scene file and
checked, textures read, BRDF models built. Every mistake is one :class:`~warp_sg.core.errors.SceneError`
line naming the file, the table and the key (``scene.toml: [materials.copper] key 'rougness'
unknown (valid keys: ...)``); ``warp_sg.scene`` re-exports these names.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import tomllib
from pydantic import ValidationError

from warp_sg.brdf import MODELS
from warp_sg.brdf.energy import energy_excess
from warp_sg.core.errors import ImageError, InputError, InputWarning, SceneError
from warp_sg.scene.camera import Camera
from warp_sg.scene.geometry import MESH_SUFFIXES
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.model import COLOUR_PARAMS, Material, Scene, SceneObject, Transform
from warp_sg.scene.primitives import PRIMITIVE_PARAMS
from warp_sg.scene.render_settings import RenderSettings
from warp_sg.scene.textures import Texture

#: files that are assets (meshes, glTF), not scenes
ASSET_SUFFIXES = MESH_SUFFIXES


class _Builder:
    """Validated tables (:class:`~warp_sg.scene.schema.SceneFile`) -> scene records."""

    def __init__(self, path: Path):
        self.base = path.parent
        self.fname = path.name

    def err(self, table: str, msg: str) -> SceneError:
        return SceneError(f"{table} {msg}" if table else msg, where=self.fname)

    def file(self, table, key, v) -> Path:
        p = Path(v)
        if not p.is_absolute():
            p = self.base / p
        if p.is_dir():
            raise self.err(table, f"key '{key}': {v} is a folder, not a file")
        if not p.is_file():
            raise self.err(table, f"key '{key}': file not found: {v}")
        return p

    def camera(self, c) -> Camera:
        return Camera(**c.model_dump())  # the table is the record's own check: nothing left to fail

    def objects(self, objs) -> list:
        out, named = [], {}
        for i, ob in enumerate(objs):
            tab = f"[[objects]] #{i + 1}"
            given = ob.model_dump(exclude_unset=True)
            if given.get("name") is not None:  # objects are found by name (moving objects, batch variants)
                if given["name"] in named:
                    raise self.err(tab, f"name '{given['name']}' is also the name of [[objects]] "
                                        f"#{named[given['name']]}: object names must be unique")
                named[given["name"]] = i + 1
            prim = given.get("primitive")
            params = {k: v for k, v in given.items() if prim is not None and k in PRIMITIVE_PARAMS[prim]}
            tr = Transform()
            if "translate" in given:
                tr.translate = given["translate"]
            if "scale" in given:
                s = given["scale"]
                tr.scale = s if isinstance(s, tuple) else (s,) * 3
            if "rotate" in given:
                tr.rotate = given["rotate"]
            mesh = self.file(tab, "mesh", given["mesh"]) if "mesh" in given else None
            out.append(SceneObject(material=ob.material, mesh=mesh, primitive=prim, params=params, transform=tr,
                                   name=given.get("name"), dynamic=bool(given.get("dynamic", False))))
        return out

    def texture(self, table, key, v, *, colour: bool) -> Texture:
        if isinstance(v, str):
            tex = Texture(path=self.file(table, key, v))
        else:
            tex = Texture(path=self.file(table, f"{key}.texture", v["texture"]), srgb=v.get("srgb"),
                          scale=float(v.get("scale", 1.0)), offset=float(v.get("offset", 0.0)))
        try:
            tex.rgba(colour=colour)  # read it now: a bad file is an error at load time
        except ImageError as e:
            raise self.err(table, f"key '{key}': {e}") from None
        return tex

    def materials(self, raw: dict) -> dict:
        out = {}
        for name, md in raw.items():
            tab = f"[materials.{name}]"
            model = md["model"]
            params, textures = {}, {}
            for k, v in md.items():
                if k in ("model", "normal_map", "tangent_map"):
                    continue
                if k == "file":
                    params[k] = str(self.file(tab, k, v))
                elif MODELS[model].PARAMS[k].texture and isinstance(v, (str, dict)):
                    textures[k] = self.texture(tab, k, v, colour=k in COLOUR_PARAMS)
                else:
                    params[k] = v  # as written: the BRDF model reads it
            m = Material(model=model, params=params, textures=textures, name=name)
            for k in ("normal_map", "tangent_map"):
                if k in md:
                    setattr(m, k, self.texture(tab, k, md[k], colour=False))
            if "kd" in textures:  # the model sees the texture's mean; no texel may exceed 1 either
                top = float(textures["kd"].rgba(colour=True)[..., :3].max())
                if top > 1.0:
                    raise self.err(tab, f"key 'kd': texture values reach {top:.4g} > 1: a diffuse albedo above 1 "
                                        f"reflects more light than the surface receives (lower its scale)")
            try:
                _ = m.brdf  # builds the model: its own checks (combinations, files, kd <= 1) run now
                excess = energy_excess(m.brdf)
                if excess:
                    warnings.warn(f"{self.fname}: {tab} {excess}", InputWarning, stacklevel=2)
            except InputError as e:
                key = e.where or ""
                msg = str(e).split(": ", 1)[1] if e.where and str(e).startswith(f"{e.where}: ") else str(e)
                raise self.err(tab, f"key '{key}': {msg}" if key else msg) from None
            except (TypeError, ValueError) as e:
                raise self.err(tab, f"invalid parameters ({e})") from None
            out[name] = m
        return out

    def lights(self, lights) -> list:
        out = []
        for j, li in enumerate(lights):
            tab = f"[[lights]] #{j + 1}"
            try:
                if li.type == "point":
                    out.append(PointLight(position=li.position, radius=li.radius, intensity=li.intensity))
                elif li.type == "environment":
                    file, opts = getattr(li, "file", None), getattr(li, "options", None)
                    out.append(EnvironmentLight(
                        file=self.file(tab, "file", file) if file is not None else None,
                        procedural=getattr(li, "procedural", None), scale=li.scale, rotation=li.rotation,
                        options=opts.model_dump(exclude_unset=True) if opts is not None else {}))
                else:
                    out.append(DirectionalLight(direction=li.direction, radius=li.radius, intensity=li.intensity))
            except SceneError:
                raise
            except InputError as e:
                raise self.err(tab, str(e)) from None
        return out


def load_scene(path) -> Scene:
    """Read and validate a TOML scene file (relative paths are relative to the file)."""
    path = Path(path)
    if path.is_dir():
        raise SceneError("is a folder, not a scene file", where=str(path))
    if not path.is_file():
        raise SceneError("scene file not found", where=str(path))
    if path.suffix.lower() in ASSET_SUFFIXES:
        raise SceneError(f"is a {path.suffix} asset, not a scene file (.toml): `warp-sg render` takes assets "
                         f"directly; for other commands write its scene with `warp-sg render {path.name} "
                         f"--print-scene > scene.toml`", where=str(path))
    try:
        raw = path.read_bytes()
        data = tomllib.loads(raw.decode("utf-8-sig"))  # -sig: a byte-order mark (editors on Windows) is no error
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"not valid TOML: {e}", where=path.name) from None
    except RecursionError:
        raise SceneError("not valid TOML here: arrays or tables nested too deeply to read (a scene file nests "
                         "a few levels)", where=path.name) from None
    except (OSError, UnicodeDecodeError) as e:
        raise SceneError(f"cannot read scene file ({e})", where=str(path)) from None
    from warp_sg.scene.schema import SceneFile, error_message  # pydantic models: built on first use

    try:
        doc = SceneFile.model_validate(data)
    except ValidationError as e:
        raise SceneError(error_message(e.errors()[0], data), where=path.name) from None
    b = _Builder(path)
    cam = b.camera(doc.camera)
    mats = b.materials(data.get("materials", {}))
    objs = b.objects(doc.objects)
    lights = b.lights(doc.lights)
    rs = RenderSettings(**doc.render.model_dump())
    try:
        return Scene(camera=cam, objects=objs, materials=mats, lights=lights, render=rs, path=path)
    except SceneError as e:
        msg = str(e)
        if e.where and msg.startswith(f"{e.where}: "):
            msg = msg[len(e.where) + 2:]
        raise SceneError(msg, where=path.name) from None


__all__ = ["load_scene"]

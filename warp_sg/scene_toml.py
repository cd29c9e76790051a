"""Scene files: :func:`load_scene` reads a TOML scene (schema in :mod:`warp_sg.scene`) and validates
every table, key and value, raising :class:`~warp_sg.errors.SceneError` messages that name the file,
the table and the key (``scene.toml: [materials.copper] key 'rougness' unknown — did you mean 'm'?``).
``warp_sg.scene`` re-exports these names.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from .camera import Camera
from .errors import ImageError, InputError, SceneError
from .lights import DirectionalLight, EnvironmentLight, PointLight
from .primitives import PRIMITIVE_PARAMS, PRIMITIVES
from .scene_model import (COLOUR_PARAMS, NON_TEXTURE_PARAMS, RENDER_KEYS, Material, RenderSettings, Scene,
                          SceneObject, Transform, _suggest)
from .textures import Texture

CAMERA_KEYS = ("origin", "target", "up", "fov", "width", "height", "near", "far")


# --------------------------------------------------------------------------------------------
# TOML loading
# --------------------------------------------------------------------------------------------
TOP_KEYS = ("camera", "objects", "materials", "lights", "render")
OBJECT_KEYS = ("mesh", "primitive", "material", "name", "translate", "scale", "rotate")
LIGHT_KEYS = {
    "point": ("type", "position", "radius", "intensity"),
    "directional": ("type", "direction", "radius", "intensity"),
    "environment": ("type", "file", "procedural", "options", "scale", "rotation"),
}
TEXTURE_TABLE_KEYS = ("texture", "scale", "offset", "srgb")


class _Loader:
    def __init__(self, path: Path):
        self.path = path
        self.base = path.parent
        self.fname = path.name

    def err(self, table: str, msg: str) -> SceneError:
        if not table:
            return SceneError(msg, where=self.fname)
        head = table if table.startswith("[") else f"[{table}]"
        return SceneError(f"{head} {msg}", where=self.fname)

    def check_keys(self, table: str, d: dict, allowed) -> None:
        for k in d:
            if k not in allowed:
                hint = _suggest(k, allowed) or f" (valid keys: {', '.join(allowed)})"
                raise self.err(table, f"key '{k}' unknown{hint}")

    def need(self, table, d, key):
        if key not in d:
            raise self.err(table, f"key '{key}' is missing")
        return d[key]

    def table(self, name, value) -> dict:
        if not isinstance(value, dict):
            raise self.err(name, f"must be a table, got {type(value).__name__}")
        return value

    # typed values ----------------------------------------------------------------------
    def number(self, table, key, v, *, lo=None, lo_open=False, hi=None) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.err(table, f"key '{key}' must be a number, got {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise self.err(table, f"key '{key}' must be finite, got {v}")
        if lo is not None and (v < lo or (lo_open and v <= lo)):
            raise self.err(table, f"key '{key}' must be {'>' if lo_open else '>='} {lo}, got {v}")
        if hi is not None and v > hi:
            raise self.err(table, f"key '{key}' must be <= {hi}, got {v}")
        return v

    def integer(self, table, key, v, *, lo=None) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(table, f"key '{key}' must be an integer, got {v!r}")
        if lo is not None and v < lo:
            raise self.err(table, f"key '{key}' must be >= {lo}, got {v}")
        return v

    def vec(self, table, key, v, n=3) -> tuple:
        if (not isinstance(v, list) or len(v) != n
                or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)):
            raise self.err(table, f"key '{key}' must be a list of {n} numbers, got {v!r}")
        if not all(math.isfinite(x) for x in v):
            raise self.err(table, f"key '{key}' must be finite, got {v!r}")
        return tuple(float(x) for x in v)

    def rgb(self, table, key, v) -> tuple:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v, v, v]
        t = self.vec(table, key, v, 3)
        if any(x < 0 for x in t):
            raise self.err(table, f"key '{key}' must be >= 0, got {list(t)}")
        return t

    def file(self, table, key, v, *, must_exist=True) -> Path:
        if not isinstance(v, str) or not v:
            raise self.err(table, f"key '{key}' must be a file path (string), got {v!r}")
        p = Path(v)
        if not p.is_absolute():
            p = self.base / p
        if must_exist and not p.is_file():
            raise self.err(table, f"key '{key}': file not found: {v}")
        return p

    # sections --------------------------------------------------------------------------
    def camera(self, d) -> Camera:
        d = self.table("camera", d)
        self.check_keys("camera", d, CAMERA_KEYS)
        kw = {}
        for k in ("origin", "target", "up"):
            if k in d:
                kw[k] = self.vec("camera", k, d[k])
        if "fov" in d:
            kw["fov"] = self.number("camera", "fov", d["fov"], lo=0, lo_open=True, hi=179.0)
        for k in ("width", "height"):
            if k in d:
                kw[k] = self.integer("camera", k, d[k], lo=1)
        for k in ("near", "far"):
            if k in d:
                kw[k] = self.number("camera", k, d[k], lo=0, lo_open=True)
        o = np.asarray(kw.get("origin", (0.0, 1.0, 4.0)))
        t = np.asarray(kw.get("target", (0.0, 0.0, 0.0)))
        if np.allclose(o, t):
            raise self.err("camera", "origin and target coincide")
        u = np.asarray(kw.get("up", (0.0, 1.0, 0.0)))
        if np.linalg.norm(np.cross(t - o, u)) < 1e-9 * np.linalg.norm(t - o) * max(np.linalg.norm(u), 1e-30):
            raise self.err("camera", "up is parallel to the viewing direction (or zero)")
        defaults = {"origin": (0.0, 1.0, 4.0), "target": (0.0, 0.0, 0.0), "up": (0.0, 1.0, 0.0), "fov": 40.0,
                    "width": 256, "height": 256}
        args = {**defaults, **kw}
        try:
            return Camera(**args)
        except InputError as e:
            raise self.err("camera", str(e)) from None

    def objects(self, lst) -> list:
        if not isinstance(lst, list):
            raise self.err("objects", "must be an array of tables ([[objects]])")
        out = []
        for i, d in enumerate(lst):
            tab = f"[[objects]] #{i + 1}"
            d = self.table(tab, d)
            has_mesh, has_prim = "mesh" in d, "primitive" in d
            if has_mesh == has_prim:
                raise self.err(tab, "give exactly one of 'mesh' or 'primitive'")
            prim = None
            allowed = OBJECT_KEYS
            if has_prim:
                prim = d["primitive"]
                if prim not in PRIMITIVES:
                    raise self.err(tab, f"key 'primitive': unknown primitive {prim!r}{_suggest(prim, PRIMITIVES)} "
                                        f"(use {', '.join(PRIMITIVES)})")
                allowed = OBJECT_KEYS + tuple(PRIMITIVE_PARAMS[prim])
            self.check_keys(tab, d, allowed)
            mat = self.need(tab, d, "material")
            if not isinstance(mat, str):
                raise self.err(tab, f"key 'material' must be a material name (string), got {mat!r}")
            params = {}
            if prim is not None:
                for k in PRIMITIVE_PARAMS[prim]:
                    if k not in d:
                        continue
                    v = d[k]
                    if k == "center":
                        params[k] = self.vec(tab, k, v)
                    elif k in ("radius", "major_radius", "minor_radius"):
                        params[k] = self.number(tab, k, v, lo=0, lo_open=True)
                    elif k == "size":
                        params[k] = (self.number(tab, k, v, lo=0, lo_open=True) if not isinstance(v, list)
                                     else self.vec(tab, k, v, 2))
                        if isinstance(params[k], tuple) and min(params[k]) <= 0:
                            raise self.err(tab, f"key 'size' must be > 0, got {list(params[k])}")
                    elif k == "resolution":
                        if isinstance(v, list):
                            params[k] = tuple(self.integer(tab, k, x, lo=1) for x in v)
                        else:
                            params[k] = self.integer(tab, k, v, lo=1)
            tr = Transform()
            if "translate" in d:
                tr.translate = self.vec(tab, "translate", d["translate"])
            if "scale" in d:
                s = d["scale"]
                tr.scale = (self.number(tab, "scale", s, lo=0, lo_open=True),) * 3 if not isinstance(s, list) \
                    else self.vec(tab, "scale", s)
                if min(tr.scale) <= 0:
                    raise self.err(tab, f"key 'scale' must be > 0, got {list(tr.scale)}")
            if "rotate" in d:
                tr.rotate = self.vec(tab, "rotate", d["rotate"])
            name = d.get("name")
            if name is not None and not isinstance(name, str):
                raise self.err(tab, f"key 'name' must be a string, got {name!r}")
            mesh = self.file(tab, "mesh", d["mesh"]) if has_mesh else None
            out.append(SceneObject(material=mat, mesh=mesh, primitive=prim, params=params, transform=tr, name=name))
        return out

    def texture(self, table, key, v, *, colour: bool) -> Texture:
        if isinstance(v, str):
            tex = Texture(path=self.file(table, key, v))
        else:
            self.check_keys(f"{table}.{key}", v, TEXTURE_TABLE_KEYS)
            path = self.file(table, f"{key}.texture", self.need(f"{table}.{key}", v, "texture"))
            srgb = v.get("srgb")
            if srgb is not None and not isinstance(srgb, bool):
                raise self.err(table, f"key '{key}.srgb' must be true or false, got {srgb!r}")
            tex = Texture(path=path, srgb=srgb,
                          scale=self.number(table, f"{key}.scale", v.get("scale", 1.0)),
                          offset=self.number(table, f"{key}.offset", v.get("offset", 0.0)))
        try:
            tex.rgba(colour=colour)  # read it now: a bad file is an error at load time
        except ImageError as e:
            raise self.err(table, f"key '{key}': {e}") from None
        return tex

    def materials(self, d) -> dict:
        from .brdf import MODELS

        d = self.table("materials", d)
        out = {}
        for name, md in d.items():
            tab = f"materials.{name}"
            md = self.table(tab, md)
            model = self.need(tab, md, "model")
            if model not in MODELS:
                raise self.err(tab, f"key 'model': unknown model {model!r}{_suggest(model, MODELS)} "
                                    f"(models: {', '.join(MODELS)})")
            pnames = tuple(MODELS[model].PARAMS)
            self.check_keys(tab, md, ("model", *pnames, "normal_map", "tangent_map"))
            params, textures = {}, {}
            for k, v in md.items():
                if k in ("model", "normal_map", "tangent_map"):
                    continue
                colour = k in COLOUR_PARAMS
                is_tex = isinstance(v, str) and k not in NON_TEXTURE_PARAMS
                is_tex = is_tex or (isinstance(v, dict) and "texture" in v and k not in NON_TEXTURE_PARAMS)
                if k == "file":
                    params[k] = str(self.file(tab, k, v))
                elif is_tex:
                    textures[k] = self.texture(tab, k, v, colour=colour)
                else:
                    params[k] = v
            m = Material(model=model, params=params, textures=textures, name=name)
            for k in ("normal_map", "tangent_map"):
                if k in md:
                    v = md[k]
                    if not isinstance(v, (str, dict)):
                        raise self.err(tab, f"key '{k}' must be a texture path, got {v!r}")
                    setattr(m, k, self.texture(tab, k, v, colour=False))
            try:
                _ = m.brdf  # builds the model: validates types/values with the model's own checks
            except InputError as e:
                key = e.where or ""
                msg = str(e).split(": ", 1)[1] if e.where and str(e).startswith(f"{e.where}: ") else str(e)
                raise self.err(tab, f"key '{key}': {msg}" if key else msg) from None
            except (TypeError, ValueError) as e:
                raise self.err(tab, f"invalid parameters ({e})") from None
            out[name] = m
        return out

    def lights(self, lst) -> list:
        if not isinstance(lst, list):
            raise self.err("lights", "must be an array of tables ([[lights]])")
        out = []
        for j, d in enumerate(lst):
            tab = f"[[lights]] #{j + 1}"
            d = self.table(tab, d)
            typ = self.need(tab, d, "type")
            if typ not in LIGHT_KEYS:
                raise self.err(tab, f"key 'type': unknown light type {typ!r}{_suggest(typ, LIGHT_KEYS)} "
                                    f"(use {', '.join(LIGHT_KEYS)})")
            self.check_keys(tab, d, LIGHT_KEYS[typ])
            try:
                if typ == "point":
                    out.append(PointLight(position=self.vec(tab, "position", self.need(tab, d, "position")),
                                          radius=self.number(tab, "radius", d.get("radius", 0.1), lo=0),
                                          intensity=self.rgb(tab, "intensity", d.get("intensity", 1.0))))
                elif typ == "directional":
                    dv = self.vec(tab, "direction", self.need(tab, d, "direction"))
                    if not any(dv):
                        raise self.err(tab, "key 'direction' must be a non-zero vector")
                    out.append(DirectionalLight(direction=dv,
                                                radius=self.number(tab, "radius", d.get("radius", 0.02), lo=0,
                                                                   hi=math.pi / 2),
                                                intensity=self.rgb(tab, "intensity", d.get("intensity", 1.0))))
                else:
                    has_file, has_proc = "file" in d, "procedural" in d
                    if has_file == has_proc:
                        raise self.err(tab, "give exactly one of 'file' or 'procedural'")
                    opts = d.get("options", {})
                    if not isinstance(opts, dict):
                        raise self.err(tab, f"key 'options' must be a table, got {opts!r}")
                    proc = d.get("procedural")
                    if has_proc and proc not in ("sky", "constant"):
                        raise self.err(tab, f"key 'procedural': unknown environment {proc!r}"
                                            f"{_suggest(proc, ('sky', 'constant'))} (use sky or constant)")
                    out.append(EnvironmentLight(
                        file=self.file(tab, "file", d["file"]) if has_file else None,
                        procedural=proc, options=dict(opts),
                        scale=self.number(tab, "scale", d.get("scale", 1.0), lo=0),
                        rotation=self.number(tab, "rotation", d.get("rotation", 0.0))))
            except SceneError:
                raise
            except InputError as e:
                raise self.err(tab, str(e)) from None
        return out

    def render(self, d) -> RenderSettings:
        d = self.table("render", d)
        self.check_keys("render", d, RENDER_KEYS)
        rs = RenderSettings(**d)
        try:
            rs.validate("[render]")
        except SceneError as e:
            raise SceneError(str(e), where=self.fname) from None
        return rs


def load_scene(path) -> Scene:
    """Read and validate a TOML scene file (relative paths are relative to the file)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError("scene file not found", where=str(path))
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"not valid TOML: {e}", where=path.name) from None
    except (OSError, UnicodeDecodeError) as e:
        raise SceneError(f"cannot read scene file ({e})", where=str(path)) from None
    ld = _Loader(path)
    ld.check_keys("", data, TOP_KEYS)
    if "camera" not in data:
        raise SceneError("table [camera] is missing", where=path.name)
    cam = ld.camera(data["camera"])
    mats = ld.materials(data.get("materials", {}))
    objs = ld.objects(data.get("objects", []))
    lights = ld.lights(data.get("lights", []))
    rs = ld.render(data.get("render", {}))
    try:
        return Scene(camera=cam, objects=objs, materials=mats, lights=lights, render=rs, path=path)
    except SceneError as e:
        msg = str(e)
        if e.where and msg.startswith(f"{e.where}: "):
            msg = msg[len(e.where) + 2:]
        raise SceneError(msg, where=path.name) from None


__all__ = ["load_scene", "CAMERA_KEYS", "TOP_KEYS", "OBJECT_KEYS", "LIGHT_KEYS", "TEXTURE_TABLE_KEYS"]

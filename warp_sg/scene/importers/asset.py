r"""A scene for one asset file (``warp-sg render asset.glb --env sky.hdr -o out.png``, issue 15).

:func:`asset_scene_dict` writes the TOML document of a scene that shows the asset:

* the asset as one object (a glTF or USD file keeps its own materials, :mod:`warp_sg.scene.importers.gltf`,
  :mod:`warp_sg.scene.importers.usd`; any other mesh gets :data:`ASSET_MATERIAL`, a grey GGX dielectric);
* a ground plane under its bounding box (:data:`GROUND_MATERIAL`, side ``GROUND_SIZE × r``),
  where ``r`` is the bounding sphere's radius (half the box diagonal) about the box centre ``c``;
* a camera looking at ``c`` from azimuth ``az`` (about +Y, from +Z towards +X) and elevation ``el``
  at the distance that fits the bounding sphere in the vertical field of view with a margin:
  ``origin = c + d (cos el sin az, sin el, cos el cos az)``, ``d = MARGIN · r / sin(fov/2)``;
* the environment ``env`` (``.hdr`` or ``.exr``) or, without one, the default procedural sky
  (rotated as in the examples, so its cached fits are shared).

:func:`asset_scene` returns the :class:`~warp_sg.scene.Scene` built from that document together
with its TOML text (``--print-scene``): loading the text with :func:`warp_sg.scene.load_scene`
gives the same scene (paths are absolute).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError, MeshError
from warp_sg.scene.camera import Camera
from warp_sg.scene.importers import brings_materials
from warp_sg.scene.importers.gltf import is_gltf, load_gltf
from warp_sg.scene.importers.usd import is_usd, load_usd
from warp_sg.scene.lights import EnvironmentLight
from warp_sg.scene.model import Material, Scene, SceneObject, Transform
from warp_sg.scene.render_settings import RenderSettings

#: (azimuth, elevation) of the default view, degrees
DEFAULT_VIEW = (30.0, 20.0)
DEFAULT_SIZE = (480, 360)
FOV = 40.0
MARGIN = 1.1
GROUND_SIZE = 8.0
GROUND_RESOLUTION = [32, 32]
#: the default sky's rotation (examples/*.toml: brings the sun in front of the default view)
SKY_ROTATION = 160.0
GROUND_MATERIAL = {"model": "lambert", "kd": [0.45, 0.45, 0.45]}
ASSET_MATERIAL = {"model": "ggx", "kd": [0.5, 0.5, 0.5], "alpha": 0.1, "fresnel": {"schlick": 0.04}}


def asset_bounds(path) -> tuple[np.ndarray, np.ndarray]:
    """World-space bounding box (lo, hi) of an asset file (glTF: scene graph applied)."""
    import warnings

    from warp_sg.core.errors import InputWarning
    from warp_sg.scene.geometry import object_mesh

    path = Path(path)
    if path.is_dir():
        raise MeshError("is a folder, not an asset file", where=str(path))
    if is_gltf(path):
        # read as the scene's object will read it, and kept for that read (load_gltf keep)
        return load_gltf(path, images=brings_materials(path), keep=True).bounds()
    if is_usd(path):
        return load_usd(path).bounds()
    if not path.is_file():
        raise MeshError("asset file not found", where=str(path))
    with warnings.catch_warnings():  # the scene's own load reports them (once)
        warnings.simplefilter("ignore", InputWarning)
        v = object_mesh(SceneObject(material="asset", mesh=path), 0, None).vertices
    return v.min(0).astype(np.float64), v.max(0).astype(np.float64)


def frame_camera(lo, hi, view=DEFAULT_VIEW, width: int = DEFAULT_SIZE[0], height: int = DEFAULT_SIZE[1],
                 fov: float = FOV) -> dict:
    """``[camera]`` keys that frame the box ``lo..hi`` from ``view = (azimuth, elevation)`` degrees
    (module docstring)."""
    az, el = (float(x) for x in view)
    for name, v in (("azimuth", az), ("elevation", el)):
        if not math.isfinite(v):
            raise InputError(f"{name} must be a finite number of degrees, got {v}", where="--view")
    if not -89.0 <= el <= 89.0:
        raise InputError(f"elevation must be in [-89, 89] degrees, got {el}", where="--view")
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c = (lo + hi) / 2
    r = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
    fit = math.sin(math.radians(fov) / 2) * min(1.0, width / height)
    d = MARGIN * r / fit
    a, e = math.radians(az), math.radians(el)
    direction = np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])
    return {"origin": (c + d * direction).tolist(), "target": c.tolist(), "up": [0.0, 1.0, 0.0], "fov": fov,
            "width": int(width), "height": int(height), "near": 0.01 * d, "far": 10.0 * (d + GROUND_SIZE * r)}


def asset_scene_dict(asset, env=None, view=DEFAULT_VIEW, width: int = DEFAULT_SIZE[0],
                     height: int = DEFAULT_SIZE[1]) -> dict:
    """The TOML document (a dict) of the scene showing ``asset`` (module docstring)."""
    asset = Path(asset).resolve()
    lo, hi = asset_bounds(asset)
    c = (lo + hi) / 2
    r = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
    ob = {"mesh": str(asset), "name": "asset"}
    mats = {}
    if not brings_materials(asset):
        ob["material"] = "asset"
        mats["asset"] = dict(ASSET_MATERIAL)
    ground = {"primitive": "plane", "name": "ground", "material": "ground",
              "center": [float(c[0]), float(lo[1]), float(c[2])], "size": [GROUND_SIZE * r, GROUND_SIZE * r],
              "resolution": list(GROUND_RESOLUTION)}
    mats["ground"] = dict(GROUND_MATERIAL)
    if env is None:
        light = {"type": "environment", "procedural": "sky", "rotation": SKY_ROTATION}
    else:
        env = Path(env)
        if not env.is_file():
            raise InputError("environment map not found", where=str(env))
        light = {"type": "environment", "file": str(env.resolve())}
    return _rounded({"camera": frame_camera(lo, hi, view, width, height), "objects": [ob, ground],
                     "materials": mats, "lights": [light]})


def _rounded(v):
    """Floats to 7 significant digits (a readable file that loads back to the same values)."""
    if isinstance(v, float):
        return float(f"{v:.7g}")
    if isinstance(v, dict):
        return {k: _rounded(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_rounded(x) for x in v]
    return v


def scene_from_dict(doc: dict) -> Scene:
    """The :class:`Scene` of an :func:`asset_scene_dict` document (the keys it writes)."""
    objects = []
    for d in doc["objects"]:
        params = {k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()
                  if k in ("center", "size", "resolution")}
        mesh = Path(d["mesh"]) if "mesh" in d else None
        objects.append(SceneObject(material=d.get("material"), mesh=mesh, primitive=d.get("primitive"),
                                   params=params, name=d.get("name"), transform=Transform()))
    mats = {k: Material(model=v["model"], params={p: x for p, x in v.items() if p != "model"}, name=k)
            for k, v in doc["materials"].items()}
    lights = [EnvironmentLight(**{k: (Path(v) if k == "file" else v) for k, v in li.items() if k != "type"})
              for li in doc["lights"]]
    for li in lights:
        li.base_radiance()  # read the map now: a bad file fails before any work (cached for the render)
    return Scene(camera=Camera(**doc["camera"]), objects=objects, materials=mats, lights=lights,
                 render=RenderSettings(**doc.get("render", {})))


def _toml_value(v) -> str:
    if isinstance(v, str):
        return json.dumps(v)  # JSON string escapes are TOML basic-string escapes
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write {v} to TOML")
        return repr(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scene_toml(doc: dict, header: str = "written by `warp-sg render ASSET --print-scene`: edit it and "
                                        "render it again") -> str:
    """TOML text of a scene document: ``[camera]``, ``[[objects]]``, ``[materials.NAME]``,
    ``[[lights]]``, ``[render]`` tables, values inline; ``header`` the first line's comment."""
    out = [f"# warp-sg scene {header}\n"]

    def table(head, d):
        out.append(f"\n{head}\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in d.items()))

    table("[camera]", doc["camera"])
    for ob in doc["objects"]:
        table("[[objects]]", ob)
    for name, m in doc["materials"].items():
        table(f"[materials.{json.dumps(name) if not name.isidentifier() else name}]", m)
    for li in doc["lights"]:
        table("[[lights]]", li)
    if doc.get("render"):
        table("[render]", doc["render"])
    return "".join(out)


def asset_scene(asset, env=None, view=DEFAULT_VIEW, width: int = DEFAULT_SIZE[0],
                height: int = DEFAULT_SIZE[1]) -> tuple[Scene, str]:
    """The scene showing ``asset`` and its TOML text (module docstring)."""
    doc = asset_scene_dict(asset, env=env, view=view, width=width, height=height)
    return scene_from_dict(doc), scene_toml(doc)


__all__ = ["DEFAULT_VIEW", "asset_bounds", "frame_camera", "asset_scene_dict", "scene_from_dict", "scene_toml",
           "asset_scene"]

r"""Scenes built from the inputs people actually bring (issue 11's accuracy suite).

Every test scene of the first round was a finely tessellated primitive; users write something
else. :func:`write_plain_scene` writes, into a folder, exactly what a modelling tool exports:

* ``floor.obj`` — the floor as **one 6×6 quad: two triangles**, four vertices;
* the object: an icosphere (``sphere.ply``, trimesh's icosphere, 1280 triangles, radius 0.5 on the
  floor), a non-convex blob (``blob.obj``, the shipped example asset, lumpy and self-shadowing) or
  the Stanford bunny (the USD file that ships with warp-lang, :func:`warp_bunny`: 12 200 triangles,
  scaled to 0.97 m and set on the floor; reading it needs ``usd-core``);
* the light: an equirectangular sky EXR (``sky.exr``: blue gradient, a small sun of radiance
  ~1000 at 36° elevation holding about half of the irradiance, as outdoors;
  :func:`warp_sg.scene.sky.procedural_sky`), or one spherical point light, or a directional light;
* ``scene.toml`` referencing them, with the material asked for (Lambert, Blinn–Phong,
  Cook–Torrance or Ward).

The floor is named ``floor`` (:mod:`warp_sg.groundtruth.region_error` uses the name to split floor from object).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: material tables by name (TOML values)
MATERIALS = {
    "lambert": {"model": "lambert", "kd": [0.7, 0.55, 0.4]},
    "blinn_phong": {"model": "blinn_phong", "kd": [0.35, 0.25, 0.2], "ks": [0.4, 0.4, 0.4], "n": 50.0},
    "cook_torrance": {"model": "cook_torrance", "kd": [0.2, 0.2, 0.25], "ks": [0.8, 0.8, 0.8], "m": 0.25,
                      "fresnel": {"schlick": 0.9}},
    "ward": {"model": "ward", "kd": [0.3, 0.3, 0.3], "ks": [0.5, 0.5, 0.5], "alpha": 0.2},
}
SUN_ELEVATION_DEG = 36.0
SUN_AZIMUTH_DEG = 30.0


def sun_direction(elevation_deg: float = SUN_ELEVATION_DEG, azimuth_deg: float = SUN_AZIMUTH_DEG) -> np.ndarray:
    """Unit direction towards the sun (+Y up)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])


def _toml_value(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, (float, np.floating)) else str(v)


def toml_table(name: str, d: dict, array: bool = False) -> str:
    """A TOML table ``[name]``, or an entry ``[[name]]`` of an array of tables."""
    head = f"[[{name}]]" if array else f"[{name}]"
    return head + "\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in d.items()) + "\n"


def write_floor_obj(path: Path, size: float = 6.0) -> Path:
    """One quad at y = 0 (two triangles, normals +Y, uvs), as exporters write it."""
    h = size / 2
    path.write_text(
        "# floor: one quad\n"
        f"v {-h} 0 {-h}\nv {h} 0 {-h}\nv {h} 0 {h}\nv {-h} 0 {h}\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\n"
        "f 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\n")
    return path


def write_sphere_ply(path: Path, radius: float = 0.5, subdivisions: int = 3) -> Path:
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    m.apply_translation([0.0, radius, 0.0])
    m.export(path)
    return path


def write_sky_exr(path: Path, width: int = 256, height: int = 128, sun_radiance: float = 1000.0,
                  sun_radius: float = 0.03) -> Path:
    """Sky with a small bright sun (peak ~``sun_radiance``, angular radius ``sun_radius``)."""
    from warp_sg.core.image_io import save_image
    from warp_sg.scene.sky import procedural_sky

    sky = procedural_sky(width, height, sun_direction=tuple(sun_direction()), sun_angular_radius=sun_radius,
                         sun_intensity=sun_radiance, halo=0.1, sky_intensity=0.8)
    save_image(path, sky)
    return path


#: the bunny of :func:`warp_bunny` on the floor: 0.6 × its 1.62-unit height, its bounding box centred
#: on the vertical axis through the origin with its lowest point at y = 0
BUNNY_PLACEMENT = {"scale": 0.6, "translate": [0.0899, -0.0127, -0.0439]}


def warp_bunny() -> Path:
    """The Stanford bunny that ships with warp-lang (``warp/examples/assets/bunny.usd``, binary USD,
    6102 points, 12 200 triangles, metres, +Y up)."""
    import warp

    from warp_sg.core.errors import MeshError

    path = Path(warp.__file__).resolve().parent / "examples" / "assets" / "bunny.usd"
    if not path.is_file():
        raise MeshError("this warp-lang installation does not ship examples/assets/bunny.usd", where=str(path))
    return path


def write_plain_scene(folder, obj: str = "sphere", light: str = "sky", material: str = "lambert",
                      size: int = 96, render: dict | None = None, floor_material: str = "lambert",
                      dynamic: bool = False) -> Path:
    """Write a plain-input scene into ``folder`` and return the path of its ``scene.toml``.

    ``obj``: "sphere" | "blob" | "bunny"; ``light``: "sky" (EXR with a sun) | "point" | "sun" (a
    directional light) | "sky+point"; ``material``: a key of :data:`MATERIALS` for the object, or a
    material table (dict of TOML values, e.g. ``{"model": "ggx", "alpha": 0.3}``);
    ``render``: extra ``[render]`` keys; ``dynamic``: the object may move
    (``[[objects]] dynamic = true``, ``Renderer.set_object_transform``).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_floor_obj(folder / "floor.obj")
    if obj == "sphere":
        mesh = write_sphere_ply(folder / "sphere.ply").name
        ob = {"mesh": mesh, "material": "object", "name": "object"}
    elif obj == "blob":
        src = Path(__file__).resolve().parents[2] / "examples" / "assets" / "blob.obj"
        (folder / "blob.obj").write_text(src.read_text())
        ob = {"mesh": "blob.obj", "material": "object", "name": "object", "scale": 0.45,
              "translate": [0.0, 0.5, 0.0]}
    elif obj == "bunny":  # the file's own material is replaced by the scene's
        ob = {"mesh": warp_bunny().as_posix(), "material": "object", "name": "object", **BUNNY_PLACEMENT}
    else:
        raise ValueError(f"unknown object {obj!r}")
    if dynamic:
        ob["dynamic"] = True
    parts = [toml_table("camera", {"origin": [0.0, 2.2, 3.6], "target": [0.0, 0.35, 0.0], "fov": 40.0,
                               "width": size, "height": size})]
    parts.append(toml_table("objects", ob, array=True))
    parts.append(toml_table("objects", {"mesh": "floor.obj", "material": "floor", "name": "floor"}, array=True))
    parts.append(toml_table("materials.object", material if isinstance(material, dict) else MATERIALS[material]))
    parts.append(toml_table("materials.floor", MATERIALS[floor_material]))
    if "sky" in light:
        write_sky_exr(folder / "sky.exr")
        parts.append(toml_table("lights", {"type": "environment", "file": "sky.exr"}, array=True))
    if "point" in light:
        parts.append(toml_table("lights", {"type": "point", "position": [1.6, 3.0, 1.4], "radius": 0.15,
                                       "intensity": [9.0, 9.0, 9.0]}, array=True))
    if light == "sun":
        parts.append(toml_table("lights", {"type": "directional", "direction": sun_direction().tolist(),
                                       "radius": 0.03, "intensity": [3.0, 2.9, 2.7]}, array=True))
    if render:
        parts.append(toml_table("render", render))
    path = folder / "scene.toml"
    path.write_text("".join(parts))
    return path


__all__ = ["write_plain_scene", "toml_table", "warp_bunny", "BUNNY_PLACEMENT", "write_floor_obj", "write_sphere_ply",
           "write_sky_exr", "sun_direction", "MATERIALS"]

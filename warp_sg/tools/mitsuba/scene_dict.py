r"""A scene as a Mitsuba 3 scene dict whose materials and lights do not go through our code.

What comes from the scene file's own words, read here and handed to Mitsuba:

* **materials** — each ``[materials.NAME]`` table's model and values (``Material.model`` and
  ``Material.params``, as the user wrote them) go to the independent BRDFs of
  :mod:`warp_sg.tools.mitsuba.formulas` through the plugin of :mod:`warp_sg.tools.mitsuba.plugin`.
  Fresnel presets resolve to Mitsuba's own data: conductors ``gold``/``silver``/``copper`` to
  Mitsuba's spectral Au/Ag/Cu indices (RGB), dielectrics to their documented index;
* **environment maps** — read by Mitsuba's own image loader (``mi.Bitmap``: EXR and Radiance
  .hdr), scaled, turned about +Y by Mitsuba's ``rotate``; re-gridded so that Mitsuba's bilinear lookup
  is ours (:func:`warp_sg.tools.peer_mitsuba.mitsuba_envmap`); a procedural sky is the one map
  not read from a file (its pixels come from ``EnvironmentLight.base_radiance``);
* **point lights** — a sphere of radius r emitting ``s/(πr²)`` (s the intensity in W/sr);
  **directional lights** — a disc of angular radius r and irradiance E: a sphere of radiance
  ``E/(π sin²r)`` at 1000 scene radii (a delta light when r = 0);
* **camera** — ``perspective`` with ``look_at``, vertical field of view, box pixel filter.

What is ours: the triangles, shading normals and tangents (``Scene.geometry()``, the mesh the
renderer draws, moved objects at their pose), so that a difference is the shading and the light
transport, not the tessellation. The mesh loading itself is checked against Mitsuba's own PLY/OBJ
loaders by a test. Transport: Mitsuba's ``path`` integrator with ``max_depth`` (2: direct light,
the paper's transport; 8 or more: with interreflection).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from warp_sg.core.errors import InputError

from .plugin import PLUGIN, ensure_registered, register_material

#: distance of a directional light's emitter sphere, in scene bounding radii
DIRECTIONAL_DISTANCE = 1000.0
#: conductor presets → Mitsuba's spectral data names
CONDUCTOR_PRESETS = {"gold": "Au", "silver": "Ag", "copper": "Cu"}
#: dielectric presets → index of refraction (documented constants, sodium D line)
DIELECTRIC_PRESETS = {"vacuum": 1.0, "air": 1.00029, "ice": 1.31, "water": 1.333, "quartz": 1.46, "glass": 1.5,
                      "sapphire": 1.77, "diamond": 2.42}


class NotExpressible(InputError):
    """The scene uses something the independent peer does not translate (the message says what)."""


def resolve_fresnel(value, where: str) -> dict:
    """A scene file's ``fresnel`` value as ``{}``, ``{"schlick": f0}``, ``{"eta": η}`` or ``{"eta": η, "k": k}``."""
    import mitsuba as mi

    if value is None or value == "none":
        return {}
    if isinstance(value, str):
        if value in CONDUCTOR_PRESETS:
            p = mi.traverse(mi.load_dict({"type": "conductor", "material": CONDUCTOR_PRESETS[value]}))
            return {"eta": [float(x) for x in p["eta.value"]], "k": [float(x) for x in p["k.value"]]}
        if value in DIELECTRIC_PRESETS:
            return {"eta": DIELECTRIC_PRESETS[value]}
        raise NotExpressible(f"fresnel preset '{value}' has no independent data here", where=where)
    return dict(value)


def material_table(name: str, mat, folder: Path | None) -> dict:
    """The plain values of one scene material for the plugin (module docstring)."""
    where = f"[materials.{name}]"
    if getattr(mat, "textures", None) or getattr(mat, "normal_map", None) or getattr(mat, "tangent_map", None):
        raise NotExpressible(f"material '{name}' is textured; textures are not translated", where=where)
    lay = getattr(mat, "layers", None)
    if lay is not None and (lay.emissive or lay.cut_out or lay.coated or lay.occlusion_map is not None):
        raise NotExpressible(f"material '{name}' has layers (emission, coat, cut-outs); not translated", where=where)
    p = {"model": mat.model, **{k: v for k, v in dict(mat.params).items()}}
    if "fresnel" in p:
        p["fresnel"] = resolve_fresnel(p["fresnel"], where)
    if p["model"] == "measured":
        f = Path(p["file"])
        if not f.is_absolute() and folder is not None:
            f = folder / f
        p["path"] = str(f)
    return p


def _camera(mi, cam, spp: int) -> dict:
    return {"type": "perspective", "fov": float(cam.fov), "fov_axis": "y",
            "near_clip": float(cam.near), "far_clip": float(cam.far),
            "to_world": mi.ScalarTransform4f().look_at(origin=[float(x) for x in cam.origin],
                                                       target=[float(x) for x in cam.target],
                                                       up=[float(x) for x in cam.up]),
            "sampler": {"type": "independent", "sample_count": int(spp)},
            "film": {"type": "hdrfilm", "width": int(cam.width), "height": int(cam.height),
                     "pixel_format": "rgb", "rfilter": {"type": "box"}}}


def _meshes(mi, scene, folder) -> dict:
    ensure_registered()
    g = scene.geometry()
    out = {}
    for m, name in enumerate(g.material_names):
        sel = g.tri_material == m
        if not np.any(sel):
            continue
        key = f"{id(scene)}:{name}"
        register_material(key, material_table(name, scene.materials[name], folder))
        tris = g.triangles[sel]
        used, inv = np.unique(tris, return_inverse=True)
        faces = inv.reshape(-1, 3).astype(np.uint32)
        props = mi.Properties()
        props["bsdf"] = mi.load_dict({"type": PLUGIN, "material": key})
        mesh = mi.Mesh(f"mat_{m}", len(used), len(faces), props=props, has_vertex_normals=True)
        mesh.add_attribute("vertex_tangent", 3, np.ascontiguousarray(g.tangents[used], np.float32).ravel().tolist())
        params = mi.traverse(mesh)
        for k, a in (("vertex_positions", g.vertices[used]), ("vertex_normals", g.normals[used]), ("faces", faces)):
            params[k] = type(params[k])(np.ascontiguousarray(a, np.uint32 if k == "faces" else np.float32).ravel())
        params.update()
        out[f"mesh_{m}"] = mesh
    return out


def environment_pixels(light, folder) -> np.ndarray:
    """The unscaled, unrotated map: read by Mitsuba's loader from the light's file (a procedural or
    in-memory map: its pixels)."""
    import mitsuba as mi

    if light.file is None:
        return np.asarray(light.base_radiance(), np.float32)
    path = Path(light.file)
    if not path.is_absolute() and folder is not None:
        path = folder / path
    bmp = mi.Bitmap(str(path)).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
    return np.array(bmp, dtype=np.float32)


def _sphere_light(centre, radius, radiance) -> dict:
    return {"type": "sphere", "center": [float(x) for x in centre], "radius": float(radius),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [float(x) for x in radiance]}}}


def _lights(mi, scene, folder) -> dict:
    from warp_sg.scene.lights import DirectionalLight, PointLight

    from ..peer_mitsuba import mitsuba_envmap

    g = scene.geometry()
    lo, hi = g.vertices.min(0).astype(np.float64), g.vertices.max(0).astype(np.float64)
    centre, brad = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
    out = {}
    for j, li in enumerate(scene.lights):
        key = f"light_{j}"
        if isinstance(li, PointLight):
            s = np.asarray(li.intensity, np.float64)
            if li.radius == 0.0:
                out[key] = {"type": "point", "position": [float(x) for x in li.position],
                            "intensity": {"type": "rgb", "value": s.tolist()}}
            else:
                out[key] = _sphere_light(li.position, li.radius, s / (math.pi * li.radius ** 2))
        elif isinstance(li, DirectionalLight):
            e = np.asarray(li.intensity, np.float64)
            d = np.asarray(li.direction, np.float64)
            d = d / np.linalg.norm(d)
            if li.radius == 0.0:
                out[key] = {"type": "directional", "direction": (-d).tolist(), "irradiance": {"type": "rgb",
                                                                                             "value": e.tolist()}}
            else:
                dist = DIRECTIONAL_DISTANCE * max(brad, 1e-3)
                out[key] = _sphere_light(centre + dist * d, dist * math.sin(li.radius),
                                         e / (math.pi * math.sin(li.radius) ** 2))
        else:
            px = environment_pixels(li, folder)
            out[key] = {"type": "envmap", "bitmap": mi.Bitmap(mitsuba_envmap(px)), "scale": float(li.scale),
                        "to_world": mi.ScalarTransform4f().rotate([0.0, 1.0, 0.0], float(li.rotation))}
    return out


def independent_scene_dict(scene, spp: int = 64, max_depth: int = 2) -> dict:
    """The Mitsuba scene dict of ``scene`` (module docstring); the current Mitsuba variant must be set.
    Raises :class:`NotExpressible` for what is not translated (textures, layers, unknown presets)."""
    import mitsuba as mi

    folder = Path(scene.path).parent if getattr(scene, "path", None) else None
    d = {"type": "scene",
         "integrator": {"type": "path", "max_depth": int(max_depth), "hide_emitters": not scene.render.background},
         "sensor": _camera(mi, scene.camera, spp)}
    d.update(_meshes(mi, scene, folder))
    d.update(_lights(mi, scene, folder))
    return d


__all__ = ["independent_scene_dict", "material_table", "resolve_fresnel", "environment_pixels", "NotExpressible",
           "CONDUCTOR_PRESETS", "DIELECTRIC_PRESETS"]

"""Generated assets for the precompute benchmarks (tools layer).

:func:`textured_helmet` writes a glTF 2.0 file of a helmet-sized textured asset (about
``triangles`` triangles; base-colour, metallic-roughness and normal textures on every part) so the
"time to first image" benchmark and ``scripts/profile_cold.py`` have a textured 15–20 k-triangle
asset without shipping one: a helmet shell (the upper part of a UV sphere, tiled base colour and
metal bands), a visor (a torus arc) and a crest ridge, standing on a short plinth. The geometry
shadows itself (visor over the shell, crest over the top, the helmet on its plinth).
Deterministic; numpy + trimesh + Pillow.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: texture size of the generated asset (texels per side)
TEXTURE = 128


def _textures(n: int = TEXTURE):
    """(base colour sRGB uint8, metallicRoughness uint8 (G rough, B metal), normal uint8) of a
    tiled pattern: coloured tiles, dark grout, metal on every third tile, bumps at the tile edges."""
    c = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(c, 1.0 - c)
    tiles = 8
    fu, fv = (u * tiles) % 1.0, (v * tiles) % 1.0
    iu, iv = np.floor(u * tiles).astype(int), np.floor(v * tiles).astype(int)
    edge = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv))
    palette = np.array([[0.70, 0.15, 0.12], [0.85, 0.70, 0.30], [0.18, 0.35, 0.65], [0.80, 0.80, 0.78]])
    col = palette[(iu + 2 * iv) % len(palette)]
    grout = edge < 0.05
    col = np.where(grout[..., None], [0.10, 0.10, 0.10], col)
    base = (np.clip(col, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)
    metal = (((iu + 2 * iv) % 3 == 1) & ~grout).astype(np.uint8) * 255
    rough = np.where(grout, 230, 60 + 40 * ((iu + iv) % 2)).astype(np.uint8)
    mr = np.stack([np.zeros_like(rough), rough, metal], -1)
    h = np.clip(edge / 0.1, 0.0, 1.0)
    gy, gx = np.gradient(h)
    nrm = np.stack([-4 * gx, 4 * gy, np.ones_like(h)], -1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return base, mr, ((nrm * 0.5 + 0.5) * 255 + 0.5).astype(np.uint8)


def _sphere_uv(vertices, centre):
    d = vertices - centre
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return np.stack([0.5 + np.arctan2(d[:, 0], d[:, 2]) / (2 * math.pi), np.arccos(np.clip(d[:, 1], -1, 1)) / math.pi], 1)


def textured_helmet(path, triangles: int = 16000) -> Path:
    """Write the generated helmet (module docstring) as a ``.glb`` with about ``triangles`` triangles."""
    import trimesh
    from PIL import Image
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    base, mr, nrm = _textures()
    mat = PBRMaterial(name="helmet", baseColorTexture=Image.fromarray(base, "RGB"),
                      metallicRoughnessTexture=Image.fromarray(mr, "RGB"), normalTexture=Image.fromarray(nrm, "RGB"),
                      metallicFactor=1.0, roughnessFactor=1.0)
    # shell: about 70 % of the triangles; a UV sphere (about 4·rows·cols triangles), upper 70 % kept
    cells = max(0.7 * triangles / (4 * 0.7), 64)
    cols = int(round(math.sqrt(2 * cells)))
    rows = max(int(round(cells / cols)), 8)
    shell = trimesh.creation.uv_sphere(radius=1.0, count=[rows, cols])
    keep = shell.triangles_center[:, 1] > -0.4
    shell.update_faces(keep)
    shell.remove_unreferenced_vertices()
    visor = trimesh.creation.torus(1.0, 0.08, major_sections=max(int(0.12 * triangles / 24), 24), minor_sections=12)
    visor.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    visor.apply_scale([1.08, 1.0, 1.08])
    visor.apply_translation([0, -0.05, 0])
    crest = trimesh.creation.capsule(height=1.6, radius=0.09, count=[max(int(math.sqrt(0.1 * triangles)), 8)] * 2)
    crest.apply_translation([0, 1.02, 0])
    plinth = trimesh.creation.box(extents=[1.6, 0.25, 1.6])
    plinth.apply_translation([0, -0.55, 0])
    plinth = plinth.subdivide().subdivide()
    s = trimesh.Scene()
    for name, m in (("shell", shell), ("visor", visor), ("crest", crest), ("plinth", plinth)):
        m.visual = TextureVisuals(uv=_sphere_uv(m.vertices, np.array([0.0, 0.0, 0.0])), material=mat)
        s.add_geometry(m, node_name=name, geom_name=name)
    path = Path(path)
    path.write_bytes(s.export(file_type="glb"))
    return path


__all__ = ["textured_helmet"]


def lumpy_mesh(triangles: int = 12000):
    """A closed, non-convex, bunny-sized lump of about ``triangles`` triangles (a UV sphere with
    three bulges and a fold, about 1 unit across, standing on y = 0): it shadows itself and the floor."""
    import trimesh

    cells = max(triangles / 4.0, 64)
    cols = int(round(math.sqrt(2 * cells)))
    rows = max(int(round(cells / cols)), 8)
    m = trimesh.creation.uv_sphere(radius=1.0, count=[rows, cols])
    d = m.vertices / np.linalg.norm(m.vertices, axis=1, keepdims=True)
    r = (1.0 + 0.35 * np.exp(-8 * np.sum((d - [0.55, 0.75, 0.3]) ** 2, 1))
         + 0.30 * np.exp(-8 * np.sum((d - [-0.5, 0.8, 0.2]) ** 2, 1))
         + 0.25 * np.exp(-6 * np.sum((d - [0.0, -0.2, -0.95]) ** 2, 1))
         - 0.18 * np.exp(-10 * np.sum((d - [0.0, 0.35, 0.95]) ** 2, 1)))
    v = d * r[:, None] * np.array([0.45, 0.4, 0.35])
    v[:, 1] -= v[:, 1].min()
    return trimesh.Trimesh(vertices=v, faces=m.faces, process=False)


def write_report_scene(folder, triangles: int = 12000, size: int = 160) -> Path:
    """The error-vs-run-time report's benchmark scene (docs/benchmarks.md): :func:`lumpy_mesh` on
    a two-triangle floor under the plain-input sun-sky EXR (:func:`warp_sg.scene.plain_scenes.write_plain_scene`),
    ``size × size`` pixels. Returns the scene file."""
    from warp_sg.scene.plain_scenes import write_plain_scene

    folder = Path(folder)
    scene = write_plain_scene(folder, obj="blob", light="sky", material="cook_torrance", size=size)
    lumpy_mesh(triangles).export(folder / "blob.obj")
    text = scene.read_text().replace("scale = 0.45", "scale = 1.0").replace("translate = [0.0, 0.5, 0.0]",
                                                                             "translate = [0.0, 0.0, 0.0]")
    scene.write_text(text)
    return scene


__all__ += ["lumpy_mesh", "write_report_scene"]

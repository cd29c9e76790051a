"""Generate the small assets of the example scenes into ``examples/assets/`` (committed; rerun to rebuild).

* ``albedo.png``    sRGB colour tiles with thin grout lines (a spatially varying ``kd``/``ks``)
* ``roughness.png`` linear grey: smooth tiles, rough grout and a radial gradient (mapped to ``m``)
* ``normal.png``    tangent-space normal map of rounded tile bumps (``2·rgb − 1``, z up)
* ``tangent.png``   tangent map: a swirl of tangent directions (``(2r − 1, 2g − 1)`` in the tangent plane)
* ``blob.obj``      a lumpy sphere (icosphere with a smooth radial displacement), to show mesh loading
* ``still_life.glb`` a glTF 2.0 asset (README "Render your own asset"): a tiled pedestal (base
  colour, metallic-roughness and normal textures; some tiles metal), a gold ball, a copper ring and a
  red plastic capsule, placed by a node hierarchy (root scale, a tilted group)
* ``sky.hdr``       an equirectangular Radiance HDR sky with a low warm sun (``warp_sg.scene.sky.procedural_sky``)

Usage: ``python examples/make_assets.py``. Pure numpy + Pillow + trimesh (+ OpenCV for ``.hdr``),
deterministic.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

OUT = Path(__file__).resolve().parent / "assets"
N = 128  # texture size
TILES = 4  # tiles per side


def _uv(n=N):
    """Texel-centre UVs, row 0 at the top of the image (v = 1)."""
    c = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(c, 1.0 - c)
    return u, v


def _tiles():
    u, v = _uv()
    fu, fv = (u * TILES) % 1.0, (v * TILES) % 1.0
    iu, iv = np.floor(u * TILES).astype(int), np.floor(v * TILES).astype(int)
    edge = np.minimum(np.minimum(fu, 1 - fu), np.minimum(fv, 1 - fv))  # distance to the tile border
    return u, v, fu, fv, iu, iv, edge


def albedo():
    _, _, _, _, iu, iv, edge = _tiles()
    palette = np.array([[0.80, 0.25, 0.15], [0.90, 0.75, 0.30], [0.20, 0.45, 0.75], [0.30, 0.65, 0.35],
                        [0.85, 0.85, 0.80], [0.55, 0.30, 0.60]])
    col = palette[(iu * 3 + iv * 5) % len(palette)]
    grout = (edge < 0.04)[..., None]
    col = np.where(grout, [0.12, 0.11, 0.10], col)
    return (np.clip(col, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)  # ~sRGB encode


def roughness():
    u, v, _, _, _, _, edge = _tiles()
    r = 0.25 + 0.5 * np.hypot(u - 0.5, v - 0.5)  # smoother in the middle
    r = np.where(edge < 0.04, 1.0, r)
    return (np.clip(r, 0, 1) * 255 + 0.5).astype(np.uint8)


def normal():
    _, _, fu, fv, _, _, edge = _tiles()
    # height: rounded tile tops, falling off within 0.15 of the border
    h = np.clip(edge / 0.15, 0, 1)
    h = h * h * (3 - 2 * h)
    step = 1.0 / N
    dhdu = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) / (2 * step)
    dhdv = -(np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) / (2 * step)  # rows go down in v
    amp = 0.02
    n = np.stack([-amp * dhdu, -amp * dhdv, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return ((n * 0.5 + 0.5) * 255 + 0.5).astype(np.uint8)


def tangent():
    u, v = _uv()
    a = np.arctan2(v - 0.5, u - 0.5) + np.pi / 2 + 3.0 * np.hypot(u - 0.5, v - 0.5)  # swirl
    t = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], -1)
    return ((t * 0.5 + 0.5) * 255 + 0.5).astype(np.uint8)


def blob():
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    d = m.vertices
    r = 1.0 + 0.12 * np.sin(3 * d[:, 0]) * np.sin(3 * d[:, 1] + 1.0) * np.sin(3 * d[:, 2] + 2.0) \
        + 0.08 * np.sin(5 * d[:, 1])
    m = trimesh.Trimesh(vertices=d * r[:, None], faces=m.faces, process=False)
    return m


def metallic_roughness():
    """glTF metallicRoughness texture: G = roughness, B = metallic (the gold-palette tiles are metal)."""
    _, _, _, _, iu, iv, edge = _tiles()
    rough = roughness()
    metal = (((iu * 3 + iv * 5) % 6 == 1) & (edge >= 0.04)).astype(np.uint8) * 255
    return np.stack([np.zeros_like(rough), rough, metal], -1)


def _box_uv(m):
    """Unshared box vertices with planar UVs per face (projection on the two axes across its normal)."""
    m = m.copy()
    m.unmerge_vertices()
    n = np.abs(m.face_normals)
    axis = np.argmax(n, 1)
    v = m.vertices[m.faces]  # (F, 3, 3)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[axis]  # the two axes spanning each face
    uv = np.take_along_axis(v, keep[:, None, :].repeat(3, 1), 2)
    uv = (uv - uv.min(axis=(0, 1))) / np.ptp(uv.reshape(-1, 2), 0)
    out = np.zeros((len(m.vertices), 2))
    out[m.faces.reshape(-1)] = uv.reshape(-1, 2)
    return m, out


def still_life():
    """The glTF 2.0 example asset (module docstring), as a trimesh scene."""
    import trimesh
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    tf = trimesh.transformations
    tiles = PBRMaterial(name="tiles", baseColorTexture=Image.fromarray(albedo(), "RGB"),
                        metallicRoughnessTexture=Image.fromarray(metallic_roughness(), "RGB"),
                        normalTexture=Image.fromarray(normal(), "RGB"), metallicFactor=1.0, roughnessFactor=1.0)
    box, uv = _box_uv(trimesh.creation.box(extents=[1.6, 0.3, 1.6]))
    box.visual = TextureVisuals(uv=uv, material=tiles)

    def solid(mesh, name, colour, metallic, rough):
        mesh.visual = TextureVisuals(material=PBRMaterial(name=name, baseColorFactor=colour, metallicFactor=metallic,
                                                          roughnessFactor=rough))
        return mesh

    ball = solid(trimesh.creation.icosphere(subdivisions=3, radius=0.32), "gold", [1.0, 0.77, 0.34, 1.0], 1.0, 0.35)
    ring = solid(trimesh.creation.torus(0.28, 0.07, major_sections=48, minor_sections=16), "copper",
                 [0.95, 0.64, 0.54, 1.0], 1.0, 0.25)
    capsule = solid(trimesh.creation.capsule(height=0.4, radius=0.12, count=[24, 24]), "red_plastic",
                    [0.75, 0.06, 0.04, 1.0], 0.0, 0.4)
    s = trimesh.Scene()
    s.graph.update(frame_from=s.graph.base_frame, frame_to="still_life", matrix=np.diag([1.2, 1.2, 1.2, 1.0]))
    s.add_geometry(box, node_name="pedestal", geom_name="pedestal", parent_node_name="still_life",
                   transform=tf.translation_matrix([0, 0.15, 0]))
    s.add_geometry(ball, node_name="ball", geom_name="ball", parent_node_name="still_life",
                   transform=tf.translation_matrix([-0.3, 0.62, -0.15]))
    s.graph.update(frame_from="still_life", frame_to="group",
                   matrix=tf.translation_matrix([0.4, 0.3, 0.3]) @ tf.rotation_matrix(0.5, [0, 1, 0]))
    s.add_geometry(ring, node_name="ring", geom_name="ring", parent_node_name="group",
                   transform=tf.translation_matrix([0, 0.07, 0]))
    s.add_geometry(capsule, node_name="capsule", geom_name="capsule", parent_node_name="group",
                   transform=tf.translation_matrix([0.05, 0.32, -0.35]) @ tf.rotation_matrix(1.2, [1, 0, 0]))
    return s


def sky():
    from warp_sg.scene.sky import procedural_sky

    return procedural_sky(256, 128, sun_direction=(-0.81, 0.5, 0.3), sun_angular_radius=0.04, sun_intensity=800.0,
                          sun_color=(1.0, 0.8, 0.6), sky_intensity=0.9)


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    Image.fromarray(albedo(), "RGB").save(OUT / "albedo.png", optimize=True)
    Image.fromarray(roughness(), "L").save(OUT / "roughness.png", optimize=True)
    Image.fromarray(normal(), "RGB").save(OUT / "normal.png", optimize=True)
    Image.fromarray(tangent(), "RGB").save(OUT / "tangent.png", optimize=True)
    blob().export(OUT / "blob.obj", include_normals=True)
    (OUT / "still_life.glb").write_bytes(still_life().export(file_type="glb"))
    from warp_sg.core.image_io import save_image

    save_image(OUT / "sky.hdr", sky())
    for f in sorted(OUT.iterdir()):
        print(f"{f.relative_to(OUT.parent.parent)}  {f.stat().st_size / 1024:.1f} KiB")


if __name__ == "__main__":
    main()

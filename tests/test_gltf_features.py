"""glTF as exporters write it (issue 27): emission, occlusion, alpha cut-outs, KHR_texture_transform,
COLOR_0, KHR_materials_ior / specular / clearcoat, KHR_mesh_quantization and Draco, each in a
small file written here (tests/gltf_files.py). Each feature is checked against what the
specification says it means (closed forms, numpy) and, rendered, against the Monte-Carlo
reference, which implements the same features with its own code (exact BRDFs, ray-traced
visibility through the holes): the object's bias per region (warp_sg.groundtruth.region_error) is at most 3 %.

The scenes are flat quads seen from 45°: there the renderer's base material is within 2 % of the
reference (a sphere's grazing rim is not, which is no feature of these files)."""
from __future__ import annotations

import numpy as np
import pytest
from gltf_files import GltfWriter, quad

from warp_sg.core.errors import SceneError
from warp_sg.groundtruth.reference import reference
from warp_sg.groundtruth.region_error import region_errors, scene_regions
from warp_sg.renderer.renderer import Renderer
from warp_sg.scene.camera import Camera
from warp_sg.scene.importers.gltf import AssetWarning, load_gltf
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight
from warp_sg.scene.model import Material, Scene, SceneObject
from warp_sg.scene.render_settings import RenderSettings

CONST = [EnvironmentLight(procedural="constant", options={"radiance": [0.4, 0.45, 0.5]})]
SUN = [DirectionalLight(direction=(0.3, 1.0, 0.4), radius=0.1, intensity=(2.0, 2.0, 2.0))] + CONST
SKY = [EnvironmentLight(procedural="sky", rotation=160.0)]
CAM = dict(origin=(0.0, 1.3, 1.5), target=(0.0, 0.3, 0.0), fov=40.0, width=40, height=30)
GREY = {"baseColorFactor": [0.5, 0.4, 0.3, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5}
BIAS = 0.03


def quad_file(path, material: dict, *, colors=None, textures=None, size=1.0, y=0.3, n=4):
    """A one-quad glTF: ``textures`` {path in the material entry: (textureInfo extras, uint8 image)}."""
    w = GltfWriter()
    P, idx, N, uv = quad(size, y, n)
    mat = dict(material)
    for keys, (info, img) in (textures or {}).items():
        d = mat
        for k in keys[:-1]:
            d = d.setdefault(k, {})
        d[keys[-1]] = dict(info, index=w.image(img))
    m = w.material(mat)
    w.mesh(P, idx, N, uv, material=m, colors=None if colors is None else colors(P), name="thing")
    return w.glb(path)


def scene_of(path, lights, floor=False, shadows=False, **cam):
    objs = [SceneObject(material=None, mesh=path, name="asset")]
    mats = {}
    if floor:
        objs.append(SceneObject(material="floor", primitive="plane", name="floor",
                                params={"center": (0.0, 0.0, 0.0), "size": (4.0, 4.0), "resolution": (24, 24)}))
        mats["floor"] = Material(model="lambert", params={"kd": [0.5, 0.5, 0.5]})
    return Scene(camera=Camera(**{**CAM, **cam}), objects=objs, materials=mats, lights=list(lights),
                 render=RenderSettings(shadows=shadows, ssdf_resolution=16))


def errors_against_reference(scene, spp=128):
    img = Renderer(scene).render()
    ref, se = reference(scene, spp=spp, progress=False, return_stderr=True)
    return img, ref, region_errors(img, ref, scene_regions(scene), se)


# --------------------------------------------------------------------------------------------
# emission
# --------------------------------------------------------------------------------------------
def test_emission_is_factor_times_strength_times_texture_and_matches_the_reference(tmp_path):
    tex = np.zeros((4, 4, 3), np.uint8)
    tex[...] = (255, 128, 0)  # sRGB: linear (1, 0.2158605, 0) (IEC 61966-2-1)
    entry = {"name": "glow", "pbrMetallicRoughness": GREY, "emissiveFactor": [1.0, 0.5, 0.25],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}}
    lit = scene_of(quad_file(tmp_path / "e.glb", entry, textures={("emissiveTexture",): ({}, tex)}), CONST)
    dark = scene_of(quad_file(tmp_path / "d.glb", {"name": "glow", "pbrMetallicRoughness": GREY}), CONST)
    lay = lit.materials["asset/glow"].layers
    assert lay.emission == pytest.approx((2.0, 1.0, 0.5))
    img, ref, err = errors_against_reference(lit)
    assert abs(err["object"]["bias"]) <= BIAS, err["object"]
    # the emitted radiance adds: Le = (1, 0.5, 0.25) · 2 · (1, 0.2158605, 0)
    diff = img - Renderer(dark).render()
    obj = scene_regions(lit)["object"]
    np.testing.assert_allclose(diff[obj].mean(0), [2.0, 0.2158605, 0.0], rtol=1e-4, atol=1e-5)


# --------------------------------------------------------------------------------------------
# occlusion
# --------------------------------------------------------------------------------------------
def test_occlusion_multiplies_only_the_environments_diffuse_term(tmp_path):
    # a pure Lambert surface (KHR_materials_specular: no specular lobe) under a constant sky L and
    # a directional light E: radiance = kd (L occ + E cos θ / π), occ = 1 + strength (R - 1)
    occ = np.full((2, 2, 3), 100, np.uint8)
    entry = {"name": "m", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.5, 0.4, 1], "metallicFactor": 0.0},
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}
    sun = DirectionalLight(direction=(0.0, 1.0, 0.0), radius=0.0, intensity=(1.5, 1.5, 1.5))
    scene = scene_of(quad_file(tmp_path / "o.glb", entry, textures={("occlusionTexture",): ({"strength": 0.8}, occ)}),
                     CONST + [sun])
    img, ref, err = errors_against_reference(scene)
    assert abs(err["object"]["bias"]) <= BIAS, err["object"]
    o = 1.0 + 0.8 * (100 / 255 - 1.0)
    kd, L = np.array([0.6, 0.5, 0.4]), np.array([0.4, 0.45, 0.5])
    want = kd * (L * o + 1.5 / np.pi)
    inner = scene_regions(scene)["object"]
    np.testing.assert_allclose(img[inner].mean(0), want, rtol=5e-3)
    np.testing.assert_allclose(ref[inner].mean(0), want, rtol=1e-2)


# --------------------------------------------------------------------------------------------
# alpha cut-outs
# --------------------------------------------------------------------------------------------
def holed_quad(path, mode="MASK"):
    img = np.full((16, 16, 4), 255, np.uint8)
    img[..., :3] = (200, 180, 160)
    img[4:12, 4:12, 3] = 0  # a square hole in the middle half
    entry = {"name": "leaf", "alphaMode": mode, "doubleSided": True,
             "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.6}}
    if mode == "MASK":
        entry["alphaCutoff"] = 0.5
    return quad_file(path, entry, textures={("pbrMetallicRoughness", "baseColorTexture"): ({}, img)}, size=1.2,
                     y=0.5, n=6)


def test_mask_cut_out_lets_the_light_through_its_hole(tmp_path):
    sun = DirectionalLight(direction=(0.2, 1.0, 0.1), radius=0.05, intensity=(3.0, 3.0, 3.0))
    lights = [sun, EnvironmentLight(procedural="constant", options={"radiance": [0.2, 0.2, 0.2]})]
    scene = scene_of(holed_quad(tmp_path / "m.glb"), lights, floor=True, shadows=True, **MASK_VIEW)
    img, ref, err = errors_against_reference(scene, spp=64)
    assert abs(err["object"]["bias"]) <= BIAS, err
    assert abs(err["lit_floor"]["bias"]) <= BIAS, err
    assert abs(err["shadow"]["leak"]) <= 0.05, err
    # the ray from the floor point under the hole's centre towards the sun passes the hole
    from precompute.visibility.rays import ray_visibility
    from warp_sg.shading.cutout import cutout_data

    g = scene.geometry()
    d = np.asarray(sun.direction) / np.linalg.norm(sun.direction)
    p = np.array([[0.0, 0.5, 0.0]]) - 0.5 / d[1] * d[None]
    assert ray_visibility(g.vertices, g.triangles, p, [0, 1, 0], d, cutouts=cutout_data(g, scene.materials))[0] == 1
    assert ray_visibility(g.vertices, g.triangles, p, [0, 1, 0], d)[0] == 0  # (the quad without its hole)
    # the lit patch on the floor seen through the hole is lit, as brightly as under a frame of
    # four opaque strips around a real (geometric) hole: the SSDF's rays passed through the hole
    regions = scene_regions(scene)
    through = regions["lit_floor"] & _inside_quad_outline(scene)
    assert through.sum() >= 10
    assert img[through].mean() > 2.0 * img[regions["shadow"]].mean()
    frame = Renderer(scene_of(frame_file(tmp_path / "f.glb"), lights, floor=True, shadows=True, **MASK_VIEW)).render()
    np.testing.assert_allclose(img[through].mean(0), frame[through].mean(0), rtol=0.02)


MASK_VIEW = dict(origin=(0.0, 2.4, 2.0), target=(0.0, 0.2, 0.0), fov=45.0, width=48, height=36)


def frame_file(path):
    """:func:`holed_quad`'s shape as four opaque strips around its hole."""
    w = GltfWriter()
    m = w.material({"name": "leaf", "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.6}})
    for x0, x1, z0, z1 in ((-0.6, 0.6, -0.6, -0.3), (-0.6, 0.6, 0.3, 0.6), (-0.6, -0.3, -0.3, 0.3), (0.3, 0.6, -0.3, 0.3)):
        P = np.array([[x0, 0.5, z0], [x0, 0.5, z1], [x1, 0.5, z0], [x1, 0.5, z1]])
        w.mesh(P, np.array([[0, 1, 2], [2, 1, 3]]), np.tile([0.0, 1.0, 0.0], (4, 1)), material=m, name=f"s{x0}{z0}")
    return w.glb(path)


def _inside_quad_outline(scene):
    """Pixels inside the quad's outline (its hole included): the raster of the quad alone."""
    import raster

    g = scene.geometry()
    keep = np.asarray([g.object_names[o] != "floor" for o in g.tri_object])
    return raster.rasterize(g.vertices, g.triangles[keep], scene.camera).tri_id.numpy() >= 0


def test_blend_renders_as_mask_at_one_half_with_one_warning_line(tmp_path):
    path = holed_quad(tmp_path / "b.glb", mode="BLEND")
    with pytest.warns(AssetWarning) as rec:
        scene = scene_of(path, CONST)
    lines = [str(w.message) for w in rec if issubclass(w.category, AssetWarning)]
    assert len(lines) == 1 and "BLEND" in lines[0] and "MASK" in lines[0] and "'leaf'" in lines[0]
    lay = scene.materials["asset/leaf"].layers
    assert lay.alpha_cutoff == 0.5 and lay.alpha_map is not None


# --------------------------------------------------------------------------------------------
# KHR_texture_transform
# --------------------------------------------------------------------------------------------
def test_texture_transform_moves_texels_as_the_extension_defines(tmp_path):
    rng = np.random.default_rng(7)
    img = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    t = {"offset": [0.25, -0.1], "rotation": 0.4, "scale": [1.5, 0.75]}
    info = {"extensions": {"KHR_texture_transform": t}}
    entry = {"name": "m", "pbrMetallicRoughness": dict(GREY, baseColorFactor=[1, 1, 1, 1])}
    path = quad_file(tmp_path / "t.glb", entry, textures={("pbrMetallicRoughness", "baseColorTexture"): (info, img)})
    scene = scene_of(path, SUN)
    g = scene.geometry()
    # the spec's matrix on glTF uvs (origin top-left): T(offset) R(rotation) S(scale)
    c, s = np.cos(0.4), np.sin(0.4)
    M = np.array([[1, 0, 0.25], [0, 1, -0.1], [0, 0, 1]]) @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) \
        @ np.diag([1.5, 0.75, 1.0])
    P, _, _, uv_gltf = quad(1.0, 0.3, 4)
    want = (np.c_[uv_gltf, np.ones(len(uv_gltf))] @ M.T)[:, :2]
    order = [int(np.argmin(np.linalg.norm(P - v, axis=1))) for v in g.vertices]
    np.testing.assert_allclose(np.c_[g.uvs[:, 0], 1.0 - g.uvs[:, 1]], want[order], atol=1e-6)
    # the base colour at each vertex: the image's, bilinear at the transformed glTF uv (x = u W - ½,
    # y = v H - ½ with row 0 at the top, wrapping), sRGB decoded
    from warp_sg.scene.textures import sample_bilinear_np, srgb_to_linear

    lin = srgb_to_linear(img / 255.0)
    x, y = want[order, 0] * 8 - 0.5, want[order, 1] * 8 - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    t = lambda yy, xx: lin[yy % 8, xx % 8]  # noqa: E731
    expect = (t(y0, x0) * (1 - fx) + t(y0, x0 + 1) * fx) * (1 - fy) + (t(y0 + 1, x0) * (1 - fx) + t(y0 + 1, x0 + 1) * fx) * fy
    kd = sample_bilinear_np(scene.materials["asset/m"].textures["kd"].rgba(colour=True), g.uvs)[:, :3]
    np.testing.assert_allclose(kd, expect, atol=1e-5)
    img_r, ref, err = errors_against_reference(scene)
    assert abs(err["object"]["bias"]) <= BIAS, err["object"]


# --------------------------------------------------------------------------------------------
# COLOR_0
# --------------------------------------------------------------------------------------------
def test_vertex_colours_multiply_the_base_colour(tmp_path):
    def colours(P):
        return np.c_[0.5 + P[:, 0], 0.5 - 0.8 * P[:, 2], np.full(len(P), 0.7), np.ones(len(P))]

    path = quad_file(tmp_path / "c.glb", {"name": "m", "pbrMetallicRoughness": GREY}, colors=colours)
    scene = scene_of(path, SKY)
    g = scene.geometry()
    np.testing.assert_allclose(g.colors, colours(g.vertices.astype(np.float64)), atol=1e-6)
    np.testing.assert_allclose(g.specular_colors, 1.0)  # a dielectric's F0 does not take the colour
    img, ref, err = errors_against_reference(scene)
    assert abs(err["object"]["bias"]) <= BIAS, err["object"]
    plain = Renderer(scene_of(quad_file(tmp_path / "p.glb", {"name": "m", "pbrMetallicRoughness": GREY}), SKY)).render()
    obj = scene_regions(scene)["object"]
    assert img[obj][:, 2].mean() < 0.85 * plain[obj][:, 2].mean()  # blue × 0.7


def test_vertex_colour_of_a_metal_scales_its_specular_colour():
    from warp_sg.scene.importers.gltf_material import pbr_to_ggx, vertex_colour_factors

    entry = {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.6, 0.2, 1], "metallicFactor": 0.7}}
    c = np.array([[0.5, 1.0, 0.25, 1.0]])
    kd, ks = vertex_colour_factors(entry, c)
    g = pbr_to_ggx(np.array([0.9, 0.6, 0.2]), 0.7, 0.5)
    gc = pbr_to_ggx(np.array([0.9, 0.6, 0.2]) * c[0, :3], 0.7, 0.5)
    np.testing.assert_allclose(kd[0, :3] * g["kd"], gc["kd"], rtol=1e-6)
    np.testing.assert_allclose(ks[0] * g["f0"], gc["f0"], rtol=1e-6)


# --------------------------------------------------------------------------------------------
# KHR_materials_ior, KHR_materials_specular, KHR_materials_clearcoat
# --------------------------------------------------------------------------------------------
def test_ior_and_specular_set_f0_and_f90(tmp_path):
    ext = {"KHR_materials_ior": {"ior": 2.0},
           "KHR_materials_specular": {"specularFactor": 0.7, "specularColorFactor": [1.0, 0.8, 0.6]}}
    entry = {"name": "m", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.3, 0.6, 1], "metallicFactor": 0.0,
                                                   "roughnessFactor": 0.3}, "extensions": ext}
    scene = scene_of(quad_file(tmp_path / "i.glb", entry), SKY)
    p = scene.materials["asset/m"].params
    f0 = ((2.0 - 1.0) / (2.0 + 1.0)) ** 2 * np.array([1.0, 0.8, 0.6]) * 0.7  # F0 at normal incidence
    np.testing.assert_allclose(np.array(p["ks"]) * np.array(p["fresnel"]["schlick"]), f0, rtol=1e-6)
    np.testing.assert_allclose(p["ks"], 0.7)  # F90 = specularFactor
    img, ref, err = errors_against_reference(scene)
    assert abs(err["object"]["bias"]) <= BIAS, err["object"]


#: a small sun whose mirror reflection off the quads is in view (the coat's highlight)
GLINT = [DirectionalLight(direction=(0.0, 1.0, -1.5), radius=0.05, intensity=(2.0, 2.0, 2.0))] + CONST


@pytest.mark.parametrize("lights", ["sun", "sky", "sky, coat normal map"])
def test_clearcoat_is_a_second_lobe_that_matches_the_reference(tmp_path, lights):
    coat = {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.2}}
    textures = {}
    if "normal" in lights:  # the coat's own normals, tilted 20° towards +u (tangent-space RGB)
        n = np.array([np.sin(0.35), 0.0, np.cos(0.35)])
        textures[("extensions", "KHR_materials_clearcoat", "clearcoatNormalTexture")] = (
            {}, np.tile(np.round((n + 1) / 2 * 255).astype(np.uint8), (4, 4, 1)))
    lights = GLINT if lights == "sun" else SKY
    path = quad_file(tmp_path / "c.glb", {"name": "m", "pbrMetallicRoughness": GREY, "extensions": coat},
                     textures=textures)
    scene = scene_of(path, lights)
    lay = scene.materials["asset/m"].layers
    assert lay.clearcoat == 1.0 and lay.clearcoat_alpha == pytest.approx(0.04)
    assert (lay.clearcoat_normal_map is not None) == bool(textures)
    img, ref, err = errors_against_reference(scene)
    assert abs(err["object"]["bias"]) <= BIAS, err["object"]
    if lights is GLINT:  # the coat's sharp highlight of the sun, where the base has a dim one
        base = Renderer(scene_of(quad_file(tmp_path / "p.glb", {"name": "m", "pbrMetallicRoughness": GREY}),
                                 lights)).render()
        obj = scene_regions(scene)["object"]
        assert img[obj].max() > 3.0 * base[obj].max() and ref[obj].max() > 3.0 * base[obj].max()


# --------------------------------------------------------------------------------------------
# geometry: Draco, KHR_mesh_quantization, units
# --------------------------------------------------------------------------------------------
def _mesh_sets(path):
    a = load_gltf(path, images=False)
    (p,) = a.parts
    return p.vertices[p.triangles].reshape(-1, 9)


def test_draco_and_quantized_files_decode_to_the_mesh_they_were_written_from(tmp_path):
    P, idx, N, uv = quad(1.0, 0.3, n=5)
    P = P + np.array([0.1, 0.0, -0.2])
    files = {}
    for kind in ("plain", "draco", "quantized"):
        w = GltfWriter()
        w.mesh(P * 0.5, idx, N, uv, material=w.material({"name": "m"}), name="m", draco=kind == "draco",
               quantize=kind == "quantized")
        files[kind] = w.glb(tmp_path / f"{kind}.glb")
    want = _mesh_sets(files["plain"])
    for kind in ("draco", "quantized"):
        with _no_asset_warning():
            got = _mesh_sets(files[kind])
        # same triangles in the same order; positions within the codec's step (16 bits over the
        # range: Draco; int16 / 32767: the accessor's normalisation)
        np.testing.assert_allclose(got, want, atol=2e-5)
    a = load_gltf(files["quantized"])
    (part,) = a.parts
    np.testing.assert_allclose(part.uvs[:, 0], uv[:, 0], atol=1e-4)  # normalized uint16 / 65535


class _no_asset_warning:
    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings(record=True)
        self.rec = self._w.__enter__()
        warnings.simplefilter("always")
        return self

    def __exit__(self, *exc):
        self._w.__exit__(*exc)
        notes = [str(w.message) for w in self.rec if issubclass(w.category, AssetWarning)]
        assert not notes, notes
        return False


def test_unsupported_extension_is_one_warning_line_from_the_cli(tmp_path, capsys):
    from warp_sg.tools.cli import main

    entry = {"name": "m", "pbrMetallicRoughness": GREY, "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1, 0, 0]}},
             "emissiveFactor": [0.1, 0.1, 0.1]}
    path = quad_file(tmp_path / "s.glb", entry)
    out = tmp_path / "o.png"
    assert main(["render", str(path), "-o", str(out), "--width", "32", "--height", "24", "--no-shadows",
                 "--no-progress"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    warn = [line for line in err if line.startswith("warp-sg: warning:")]
    assert len(warn) == 1 and "KHR_materials_sheen" in warn[0], err
    assert out.is_file()


TILT = np.array([[1, 0, 0], [0, np.cos(0.35), -np.sin(0.35)], [0, np.sin(0.35), np.cos(0.35)]])


def test_an_asset_renders_the_same_in_any_unit(tmp_path):
    # the same holed quad over a tile at 1e-3, 1 and 1e4 units: the framing, ray offsets, SSDF
    # precompute and the reference all scale with the asset
    from warp_sg.scene.importers.asset import asset_scene

    imgs, refs = [], []
    for scale in (1e-3, 1.0, 1e4):
        w = GltfWriter()
        P, idx, N, uv = quad(1.0, 0.0, n=8)
        P, N = P @ TILT.T, N @ TILT.T  # (not flat on the ground plane the asset scene puts under it)
        w.mesh(P * scale, idx, N, uv, material=w.material({"name": "tile", "pbrMetallicRoughness": GREY}), name="tile")
        Pq, iq, Nq, uq = quad(0.4, 0.25, n=2)
        w.mesh(Pq * scale, iq, Nq, uq, material=w.material({"name": "top", "pbrMetallicRoughness": GREY}), name="top")
        sc, _ = asset_scene(w.glb(tmp_path / f"s{scale:g}.glb"), width=32, height=24)
        sc.render.ssdf_resolution = 16
        imgs.append(Renderer(sc).render())
        refs.append(reference(sc, spp=32, progress=False, seed=1))
    assert imgs[1].std() > 0.05  # a real image: the quads, their shadows and the sky
    for img, ref in zip(imgs[::2], refs[::2]):
        np.testing.assert_allclose(img, imgs[1], rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(ref, refs[1], rtol=1e-4, atol=1e-5)


def test_a_draco_blob_that_does_not_decode_is_an_error_not_an_empty_mesh(tmp_path):
    from warp_sg.core.errors import MeshError

    P, idx, N, uv = quad(1.0, 0.3, n=2)
    w = GltfWriter()
    w.mesh(P, idx, N, uv, material=w.material({"name": "m"}), name="m", draco=True)
    view = w.h["bufferViews"][w.h["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]]
    w.bin[view["byteOffset"]:view["byteOffset"] + view["byteLength"]] = b"\x07" * view["byteLength"]
    path = w.glb(tmp_path / "bad.glb")
    with pytest.raises(MeshError, match="bad.glb"):
        load_gltf(path)


def test_a_cut_out_in_a_scene_with_a_dynamic_object_is_refused_naming_the_cut_out_object(tmp_path):
    """The groups' SSDFs and the moving objects' proxies are solid, so a hole would cast a shadow:
    refused, whichever object moves, with the cut-out object's name."""
    sun = DirectionalLight(direction=(0.2, 1.0, 0.1), radius=0.05, intensity=(3.0, 3.0, 3.0))
    scene = scene_of(holed_quad(tmp_path / "m.glb"), [sun], floor=True, shadows=True, **MASK_VIEW)
    scene.objects[1].dynamic = True  # the floor moves, the holed asset stays
    with pytest.raises(SceneError, match=r"alpha cut-outs \(asset/thing\) are not supported in a scene with dynamic objects"):
        Renderer(scene)

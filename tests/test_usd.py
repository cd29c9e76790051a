"""USD stages as scene objects (:mod:`warp_sg.scene.importers.usd`): warp-lang's Stanford bunny
against its own points read with ``pxr`` and against trimesh, small stages written here with
``pxr`` (units, up axis, transforms, fans, face-varying normals, materials), and bad files as one
line naming the file."""
from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

pxr = pytest.importorskip("pxr", reason="usd-core is not installed (pip install warp-sg[usd])")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade  # noqa: E402

from warp_sg.core.errors import MeshError  # noqa: E402
from warp_sg.scene import load_scene  # noqa: E402
from warp_sg.scene.importers.gltf import AssetWarning  # noqa: E402
from warp_sg.scene.importers.usd import load_usd  # noqa: E402
from warp_sg.scene.plain_scenes import warp_bunny  # noqa: E402
from warp_sg.tools.cli import main  # noqa: E402


def _scene_file(folder, mesh, material=None):
    """A scene holding ``mesh`` (the file's materials unless ``material``), written by ``scene_toml``."""
    from warp_sg.scene.importers.asset import scene_toml

    ob = {"mesh": mesh, **({"material": material} if material else {})}
    doc = {"camera": {"origin": [0.0, 1.0, 4.0], "target": [0.0, 0.5, 0.0], "width": 16, "height": 16},
           "objects": [ob], "materials": {"red": {"model": "lambert", "kd": [0.8, 0.1, 0.1]}},
           "lights": [{"type": "directional", "direction": [0.0, 1.0, 0.0], "intensity": [1.0, 1.0, 1.0]}]}
    path = folder / "s.toml"
    path.write_text(scene_toml(doc))
    return path


def _stage(path, up="Y", mpu=1.0):
    st = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(st, up)
    UsdGeom.SetStageMetersPerUnit(st, mpu)
    return st


def _mesh(st, where, points, counts, indices, **attrs):
    m = UsdGeom.Mesh.Define(st, where)
    m.CreatePointsAttr([Gf.Vec3f(*map(float, p)) for p in points])
    m.CreateFaceVertexCountsAttr([int(c) for c in counts])
    m.CreateFaceVertexIndicesAttr([int(i) for i in indices])
    for k, v in attrs.items():
        getattr(m, f"Create{k}Attr")(v)
    return m


def test_warp_bunny_loads_every_face_with_its_points():
    """The bunny's triangles are its faces fanned (pxr read here: Σ(c − 2)), its vertices its
    points (smooth normals split nothing; metres, +Y up, identity transforms), and it is one
    closed, outward mesh whose area and volume trimesh computes alike from the file's own faces."""
    import trimesh

    path = warp_bunny()
    st = Usd.Stage.Open(str(path))
    meshes = [UsdGeom.Mesh(p) for p in st.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) == 1
    counts = np.asarray(meshes[0].GetFaceVertexCountsAttr().Get())
    pts = np.asarray(meshes[0].GetPointsAttr().Get(), np.float64)
    idx = np.asarray(meshes[0].GetFaceVertexIndicesAttr().Get())
    a = load_usd(path)
    assert len(a.parts) == 1
    p = a.parts[0]
    assert len(p.triangles) == int(np.sum(counts - 2)) == 12200
    assert np.allclose(p.vertices.min(0), pts.min(0)) and np.allclose(p.vertices.max(0), pts.max(0))
    ours = trimesh.Trimesh(p.vertices, p.triangles, process=False)
    assert np.all(counts == 3)
    theirs = trimesh.Trimesh(pts, idx.reshape(-1, 3), process=False)
    assert ours.is_watertight and ours.is_winding_consistent
    assert ours.area == pytest.approx(theirs.area, rel=1e-9)
    assert ours.volume == pytest.approx(abs(theirs.volume), rel=1e-9) and ours.volume > 0
    # the file's normals, carried per vertex, point out of the mesh
    assert np.mean(np.sum(p.normals * ours.vertex_normals, 1) > 0.5) > 0.99


def test_units_up_axis_and_transforms_place_a_quad(tmp_path):
    """A quad in centimetres, Z up, under a translated parent and turned 90° about Z: its scene
    vertices are C·0.01·(t + Rz·P), C: (x, y, z) → (x, z, −y); its normal +Z becomes +Y."""
    path = tmp_path / "quad.usda"
    st = _stage(path, up="Z", mpu=0.01)
    parent = UsdGeom.Xform.Define(st, "/world")
    parent.AddTranslateOp().Set(Gf.Vec3d(100.0, 200.0, 300.0))
    P = np.array([[0, 0, 0], [50, 0, 0], [50, 20, 0], [0, 20, 0]], np.float64)
    m = _mesh(st, "/world/quad", P, [4], [0, 1, 2, 3], Normals=[Gf.Vec3f(0, 0, 1)] * 4)
    m.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    m.AddRotateZOp().Set(90.0)
    st.Save()
    part = load_usd(path).parts[0]
    local = np.c_[-P[:, 1], P[:, 0], P[:, 2]] + [100.0, 200.0, 300.0]  # Rz(90°)·P + t
    want = 0.01 * np.c_[local[:, 0], local[:, 2], -local[:, 1]]
    got = part.vertices
    assert len(got) == 4 and len(part.triangles) == 2
    order = [int(np.argmin(np.linalg.norm(got - w, axis=1))) for w in want]
    assert np.allclose(got[order], want, atol=1e-6)
    assert np.allclose(part.normals, [0.0, 1.0, 0.0], atol=1e-6)
    e = np.cross(got[part.triangles[:, 1]] - got[part.triangles[:, 0]], got[part.triangles[:, 2]] - got[part.triangles[:, 0]])
    assert np.all(e[:, 1] > 0)  # counter-clockwise seen from +Y: the winding agrees with the normal
    assert np.sum(np.linalg.norm(e, axis=1)) / 2 == pytest.approx(0.5 * 0.2)  # 50 cm × 20 cm


def test_left_handed_orientation_flips_the_winding(tmp_path):
    path = tmp_path / "lh.usda"
    st = _stage(path)
    _mesh(st, "/tri", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [3], [0, 1, 2], Orientation=UsdGeom.Tokens.leftHanded)
    st.Save()
    p = load_usd(path).parts[0]
    v = p.vertices[p.triangles[0]]
    assert np.cross(v[1] - v[0], v[2] - v[0])[2] < 0  # clockwise in the file: its front faces −Z
    assert p.normals[:, 2] == pytest.approx(-1.0)


def test_polygon_fans_keep_the_area_and_face_varying_normals_split_corners(tmp_path):
    """A regular pentagon (fan: 3 triangles, area (5/2) sin 72°) and a unit cube with one normal
    per face (faceVarying: 24 vertices, each with its face's normal, which is the face's outward
    geometric normal)."""
    path = tmp_path / "poly.usda"
    st = _stage(path)
    a = np.radians(72.0 * np.arange(5))
    _mesh(st, "/pentagon", np.c_[np.cos(a), np.sin(a), np.zeros(5)], [5], range(5))
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64) + [3.0, 0.0, 0.0]
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    normals = [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)]
    m = _mesh(st, "/cube", cube, [4] * 6, np.ravel(faces),
              Normals=[Gf.Vec3f(*n) for n in normals for _ in range(4)])
    m.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    st.Save()
    pent, box = load_usd(path).parts
    assert len(pent.triangles) == 3
    v = pent.vertices[pent.triangles]
    area = np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum() / 2
    assert area == pytest.approx(2.5 * np.sin(np.radians(72.0)))
    assert len(box.vertices) == 24 and len(box.triangles) == 12
    v = box.vertices[box.triangles]
    g = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    g /= np.linalg.norm(g, axis=1, keepdims=True)
    for k in range(3):
        assert np.allclose(box.normals[box.triangles[:, k]], g, atol=1e-6)
    centre = box.vertices.mean(0)
    assert np.all(np.sum((v.mean(1) - centre) * g, 1) > 0)  # outward


def test_display_colour_and_preview_surface_become_the_materials(tmp_path):
    """Without a bound material the mesh gets the UsdPreviewSurface defaults with its constant
    displayColor as the diffuse colour; a bound UsdPreviewSurface gives kd = diffuse·(1 − metallic),
    α = roughness² and Schlick F0 = 0.04·(1 − m) + m·diffuse; a scene ``material`` overrides both."""
    path = tmp_path / "mats.usda"
    st = _stage(path)
    plain = _mesh(st, "/plain", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [3], [0, 1, 2])
    plain.CreateDisplayColorAttr([Gf.Vec3f(0.2, 0.4, 0.6)])
    shiny = _mesh(st, "/shiny", [[2, 0, 0], [3, 0, 0], [2, 1, 0]], [3], [0, 1, 2])
    mat = UsdShade.Material.Define(st, "/Looks/gold")
    sh = UsdShade.Shader.Define(st, "/Looks/gold/surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.9, 0.7, 0.3))
    sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.25)
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.4)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(shiny.GetPrim()).Bind(mat)
    st.Save()
    toml = _scene_file(tmp_path, path.name)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AssetWarning)  # a plain file: not a word
        sc = load_scene(toml)
    assert sorted(sc.material_names) == ["mats.usda/displayColor", "mats.usda/gold", "red"]
    assert sc.materials["mats.usda/displayColor"].params["kd"] == pytest.approx([0.2, 0.4, 0.6])
    gold = sc.materials["mats.usda/gold"].params
    m, d = 0.25, np.array([0.9, 0.7, 0.3])
    assert gold["kd"] == pytest.approx(d * (1 - m), rel=1e-6)
    assert gold["alpha"] == pytest.approx(0.16, rel=1e-6)
    assert gold["fresnel"]["schlick"] == pytest.approx(0.04 * (1 - m) + m * d, rel=1e-6)
    assert [ob.name for ob in sc.objects] == ["mats.usda/plain", "mats.usda/shiny"]
    sc = load_scene(_scene_file(tmp_path, path.name, "red"))
    assert sc.material_names == ["red"] and len(sc.geometry().triangles) == 2


def test_texture_driven_input_is_one_warning(tmp_path):
    path = tmp_path / "tex.usda"
    st = _stage(path)
    m = _mesh(st, "/m", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [3], [0, 1, 2])
    mat = UsdShade.Material.Define(st, "/Looks/wood")
    sh = UsdShade.Shader.Define(st, "/Looks/wood/surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    tex = UsdShade.Shader.Define(st, "/Looks/wood/tex")
    tex.CreateIdAttr("UsdUVTexture")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(
        tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3))
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(mat)
    st.Save()
    with pytest.warns(AssetWarning) as rec:
        load_scene(_scene_file(tmp_path, path.name))
    msgs = [str(w.message) for w in rec]
    assert len(msgs) == 1 and "'wood'" in msgs[0] and "diffuseColor" in msgs[0] and "\n" not in msgs[0]


def _no_mesh(path):
    st = _stage(path)
    UsdGeom.Sphere.Define(st, "/ball")
    st.Save()


def _two_corner_face(path):
    st = _stage(path)
    _mesh(st, "/m", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [3, 2], [0, 1, 2, 2, 3])
    st.Save()


def _index_past_points(path):
    st = _stage(path)
    _mesh(st, "/m", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [3], [0, 1, 7])
    st.Save()


def _short_normals(path):
    st = _stage(path)
    m = _mesh(st, "/m", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [3], [0, 1, 2], Normals=[Gf.Vec3f(0, 0, 1)] * 2)
    m.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    st.Save()


def _corrupt(path):
    path.write_bytes(b"PXR-USDC\x00\x01garbage" * 4)


@pytest.mark.parametrize("make, name, message", [
    (_no_mesh, "none.usda", "no UsdGeom.Mesh with faces (it has Sphere)"),
    (_two_corner_face, "two.usda", "mesh '/m': face #1 has 2 vertices (a face needs at least 3)"),
    (_index_past_points, "far.usda", "faceVertexIndices[2] = 7 is out of range (the mesh has 3 points)"),
    (_short_normals, "short.usda", "normals has 2 values; 'faceVarying' interpolation needs 3"),
    (_corrupt, "bad.usd", "cannot read USD file"),
])
def test_bad_usd_is_one_line_naming_the_file_and_exits_2(tmp_path, capsys, make, name, message):
    path = tmp_path / name
    make(path)
    with pytest.raises(MeshError) as e:
        load_usd(path)
    assert message in str(e.value) and str(path) in str(e.value)
    out = tmp_path / "o.png"
    rc = main(["render", str(path), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and name in err[0] and message in err[0] and not out.exists()


def test_missing_usd_core_names_the_file_and_the_extra(tmp_path, monkeypatch):
    path = tmp_path / "q.usda"
    _two_corner_face(path)
    monkeypatch.setitem(sys.modules, "pxr", None)  # as if usd-core were not installed
    with pytest.raises(MeshError, match=r"q\.usda: reading USD needs the usd-core package: pip install warp-sg\[usd\]"):
        load_usd(path)

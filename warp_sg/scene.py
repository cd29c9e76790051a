r"""Scenes: TOML files (``tomllib``) and the equivalent Python objects.

``ws.load_scene(path)`` reads a scene file (schema in DESIGN.md, extended below) and returns a
:class:`Scene`; ``ws.Scene(camera=..., objects=[...], materials={...}, lights=[...])`` builds the
same thing in Python. Every mistake is a :class:`~warp_sg.errors.SceneError` (or
``MeshError``/``ImageError`` for unusable files) whose message names the file, the table and the
key or element, e.g. ``scene.toml: [materials.copper] key 'rougness' unknown — did you mean 'm'?``.

Records (what the renderer *and* the Monte-Carlo reference read)
------------------------------------------------------------------
* ``Scene.camera`` — :class:`warp_sg.camera.Camera` ``(origin, target, up, fov, width, height,
  near, far)`` (vertical ``fov`` in degrees, Mitsuba ``look_at`` meaning); ``raster.Camera`` is the
  same class.
* ``Scene.objects`` — :class:`SceneObject`: ``mesh`` (file path, any format trimesh reads) or
  ``primitive`` ("sphere" | "plane" | "torus" with ``params``) or inline ``vertices``/``triangles``
  (Python API); ``material`` (a key of ``Scene.materials``); a :class:`Transform`
  (``translate``, ``scale`` (number or 3), ``rotate`` = Euler angles in degrees about X, then Y,
  then Z: ``P' = translate + Rz·Ry·Rx·(scale ⊙ P)``).
* ``Scene.materials`` — ``{name: Material}``. :class:`Material` holds ``model`` (a key of
  ``warp_sg.brdf.MODELS``), constant ``params`` (scene-file names), ``textures``
  ``{param: Texture}`` for spatially varying parameters, ``normal_map``/``tangent_map``. Its
  ``brdf`` property is the ``warp_sg.brdf`` model instance (``make_model``), with every textured
  parameter replaced by the texture's mean (so the reference and the SG fits see a constant model).
* ``Scene.lights`` — :class:`~warp_sg.lights.PointLight` (position, radius, intensity s W/sr),
  :class:`~warp_sg.lights.DirectionalLight` (unit direction *towards* the light, angular radius in
  radians, intensity = irradiance E) and at most one :class:`~warp_sg.lights.EnvironmentLight`
  (file | procedural "sky"/"constant", options, scale, rotation degrees about +Y).
* ``Scene.render`` — :class:`RenderSettings` (the ``[render]`` table).
* ``Scene.geometry()`` — :class:`Geometry`: every object flattened into one triangle soup in world
  space (vertices, normals, uvs, tangents, triangles, ``tri_material`` indexing
  ``Scene.material_names``, ``tri_object``), validated (NaN vertex / out-of-range index →
  ``MeshError`` naming the object and element; zero-area triangles dropped and counted).

All objects share one geometry, so they shadow each other (multi-object composition).

Scene file schema (keys beyond DESIGN.md's are marked +)::

    [camera]    origin, target, up, fov, width, height, near+, far+
    [[objects]] mesh = "file" | primitive = "sphere"|"plane"|"torus"; material; name+;
                translate+, scale+, rotate+; primitive parameters:
                  sphere: center, radius, resolution = [n_theta, n_phi]
                  plane:  center, size = [sx, sz] (normal +Y), resolution = [nx, nz]
                  torus:  center, major_radius, minor_radius, resolution = [n_major, n_minor]
    [materials.NAME]  model + the model's parameters (DESIGN.md table; each numeric parameter a
                constant, a texture path "file.png"/"file.exr", or {texture = "f.png", scale = 1,
                offset = 0, srgb = bool}); normal_map+, tangent_map+ (texture paths or tables)
    [[lights]]  type = "point": position, radius, intensity
                type = "directional": direction, radius, intensity
                type = "environment": file | procedural ("sky" | "constant"), options+ (table),
                scale, rotation+ (degrees about +Y)
    [render]    shadows, supersampling, antialias, lobes, env_lobes, env_peaks, visibility_budget,
                pca_terms, ssdf_resolution, gamma_levels, gamma_resolution, fh, background, device
"""
from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from .errors import ImageError, InputError, MeshError, SceneError
from .lights import DirectionalLight, EnvironmentLight, PointLight
from .meshcheck import check_mesh
from .primitives import PRIMITIVE_PARAMS, PRIMITIVES, MeshData, make_primitive
from .textures import Texture

# --------------------------------------------------------------------------------------------
# camera
# --------------------------------------------------------------------------------------------
from .camera import Camera  # noqa: E402  (the rasterizer's camera is the scene's: raster.Camera)

CAMERA_KEYS = ("origin", "target", "up", "fov", "width", "height", "near", "far")


# --------------------------------------------------------------------------------------------
# records
# --------------------------------------------------------------------------------------------
@dataclass
class Transform:
    """``P' = translate + Rz·Ry·Rx·(scale ⊙ P)``; ``rotate`` = Euler angles (degrees) about X, Y, Z."""

    translate: tuple = (0.0, 0.0, 0.0)
    scale: tuple | float = (1.0, 1.0, 1.0)
    rotate: tuple = (0.0, 0.0, 0.0)

    def linear(self) -> np.ndarray:
        ax, ay, az = (math.radians(float(a)) for a in self.rotate)
        cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
        Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        s = np.broadcast_to(np.asarray(self.scale, np.float64), (3,))
        return Rz @ Ry @ Rx @ np.diag(s)

    def is_identity(self) -> bool:
        return (np.allclose(self.translate, 0) and np.allclose(self.scale, 1) and np.allclose(self.rotate, 0))

    def apply(self, mesh: MeshData) -> MeshData:
        if self.is_identity():
            return mesh
        A = self.linear()
        if abs(np.linalg.det(A)) < 1e-30:
            raise SceneError("transform is singular (a zero scale?)", where="transform")
        v = mesh.vertices.astype(np.float64) @ A.T + np.asarray(self.translate, np.float64)
        n = t = None
        if mesh.normals is not None:
            n = mesh.normals.astype(np.float64) @ np.linalg.inv(A)  # (A⁻ᵀ n)ᵀ = nᵀ A⁻¹
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        if mesh.tangents is not None:
            t = mesh.tangents.astype(np.float64) @ A.T
            t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-30)
        tri = mesh.triangles
        if np.linalg.det(A) < 0:  # mirror: keep the winding consistent with the normals
            tri = tri[:, [0, 2, 1]]
        return MeshData(v.astype(np.float32), tri, None if n is None else n.astype(np.float32), mesh.uvs,
                        None if t is None else t.astype(np.float32))


@dataclass
class SceneObject:
    """One object: ``mesh`` (file), ``primitive`` (+ ``params``) or inline arrays; a material name."""

    material: str
    mesh: str | Path | None = None
    primitive: str | None = None
    params: dict = field(default_factory=dict)
    transform: Transform = field(default_factory=Transform)
    name: str | None = None
    vertices: np.ndarray | None = None
    triangles: np.ndarray | None = None
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    tangents: np.ndarray | None = None

    def label(self, index: int) -> str:
        return self.name or (Path(self.mesh).name if self.mesh is not None else self.primitive) or f"objects[{index}]"


#: Parameters that are RGB colours (others are scalars); parameters that cannot be textures.
COLOUR_PARAMS = ("kd", "ks")
NON_TEXTURE_PARAMS = ("fresnel", "lobes", "file")


@dataclass
class Material:
    """A material: ``model`` name, constant ``params``, per-texel ``textures`` and normal/tangent maps."""

    model: str
    params: dict = field(default_factory=dict)
    textures: dict = field(default_factory=dict)  # {param: Texture}
    normal_map: Texture | None = None
    tangent_map: Texture | None = None
    name: str | None = None
    _brdf: object = field(default=None, repr=False, compare=False)

    @classmethod
    def from_brdf(cls, model, name=None) -> "Material":
        """Wrap a ``warp_sg.brdf`` model instance."""
        m = cls(model=model.NAME, params={}, name=name)
        m._brdf = model
        return m

    @property
    def brdf(self):
        """The ``warp_sg.brdf`` model (textured parameters replaced by the texture means)."""
        if self._brdf is None:
            from .brdf import make_model

            p = dict(self.params)
            for k, tex in self.textures.items():
                mean = tex.mean(colour=k in COLOUR_PARAMS)
                p[k] = mean.tolist() if k in COLOUR_PARAMS else float(mean[0])
            self._brdf = make_model(self.model, **p)
        return self._brdf

    def invalidate(self) -> None:
        """Forget the cached model (call after changing ``params``/``textures``)."""
        self._brdf = None


Light = PointLight | DirectionalLight | EnvironmentLight


@dataclass
class RenderSettings:
    """The ``[render]`` table: quality knobs of the SG renderer.

    * ``shadows`` — SSDF visibility (eq. 23–31); off → V = 1 and no SSDF precompute.
    * ``supersampling`` — k: raster and shade at k·H × k·W, box-resolved.
    * ``antialias`` — a (default 4; 1 = off; used when ``supersampling`` is 1): coverage at a×a
      sub-pixels, shading edge-adaptive (interior pixels once, edge pixels at every sub-pixel).
    * ``lobes`` — SG lobes of the NDF of isotropic models (anisotropic Ashikhmin-Shirley uses its
      own ``lobes`` parameter).
    * ``env_lobes`` — SG mixture of the environment for the diffuse term (eq. 39), < 10 in the paper.
    * ``env_peaks`` — at most this many sharp peaks of the environment (a sun) are separated from
      the map and shaded as directional lights (``precompute.env_peaks``; 0 = off).
    * ``visibility_budget`` — with shadows, the mesh is refined where its visibility changes, up to
      this many vertices (``precompute.refine_for_visibility``; 0 = use the mesh as given).
    * ``pca_terms``, ``ssdf_resolution`` — SSDF compression (NV) and map resolution.
    * ``gamma_levels`` — number of λ levels of the ΓL pyramid (0 = precompute's default ladder,
      λ0 = 0.5 growing by √2 up to the map's resolution); ``gamma_resolution`` — largest cube face.
    * ``fh`` — ``"table"`` (exact, tabulated) or ``"sigmoid"`` (paper appendix).
    * ``background`` — pixels that see no object show the environment.
    * ``device`` — default device for ``ws.render(scene)`` ("cpu", "cuda", "auto").
    """

    shadows: bool = True
    supersampling: int = 1
    antialias: int = 4
    lobes: int = 1
    env_lobes: int = 8
    env_peaks: int = 4
    visibility_budget: int = 20000
    pca_terms: int = 32
    ssdf_resolution: int = 32
    gamma_levels: int = 0
    gamma_resolution: int = 128
    fh: str = "table"
    background: bool = True
    device: str = "cpu"

    def validate(self, where="[render]"):
        ints = {"supersampling": (1, 16), "antialias": (1, 8), "lobes": (1, 16), "env_lobes": (1, 64), "env_peaks": (0, 16), "visibility_budget": (0, 10_000_000),
                "pca_terms": (1, 256), "ssdf_resolution": (4, 1024), "gamma_levels": (0, 64),
                "gamma_resolution": (4, 1024)}
        for k, (lo, hi) in ints.items():
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise SceneError(f"{where} key '{k}' must be an integer, got {v!r}")
            if not lo <= v <= hi:
                raise SceneError(f"{where} key '{k}' must be in [{lo}, {hi}], got {v}")
        for k in ("shadows", "background"):
            if not isinstance(getattr(self, k), bool):
                raise SceneError(f"{where} key '{k}' must be true or false, got {getattr(self, k)!r}")
        if self.fh not in ("table", "sigmoid"):
            raise SceneError(f"{where} key 'fh' must be 'table' or 'sigmoid', got {self.fh!r}")
        if not isinstance(self.device, str):
            raise SceneError(f"{where} key 'device' must be a string, got {self.device!r}")


RENDER_KEYS = tuple(f.name for f in fields(RenderSettings))


@dataclass
class Geometry:
    """All objects of a scene flattened into one world-space triangle mesh (float32 / int32).

    ``vertices`` (N, 3), ``normals`` (N, 3) unit shading normals, ``uvs`` (N, 2), ``tangents``
    (N, 3) unit and orthogonal to the normals (∂P/∂u, or the Duff frame tangent where there are no
    UVs), ``triangles`` (M, 3), ``tri_material`` (M,) index into ``material_names``,
    ``tri_object`` (M,) and ``vertex_object`` (N,) index into ``object_names``;
    ``dropped_triangles``: zero-area triangles removed while flattening.
    """

    vertices: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    tangents: np.ndarray
    triangles: np.ndarray
    tri_material: np.ndarray
    tri_object: np.ndarray
    vertex_object: np.ndarray
    material_names: list
    object_names: list
    dropped_triangles: int = 0


# --------------------------------------------------------------------------------------------
# Scene
# --------------------------------------------------------------------------------------------
@dataclass
class Scene:
    """A renderable scene (see the module docstring). ``path`` is the scene file, if any."""

    camera: Camera
    objects: list = field(default_factory=list)
    materials: dict = field(default_factory=dict)
    lights: list = field(default_factory=list)
    render: RenderSettings = field(default_factory=RenderSettings)
    path: Path | None = None

    def __post_init__(self):
        where = str(self.path) if self.path else "scene"
        mats = {}
        for name, m in dict(self.materials).items():
            if not isinstance(m, Material):
                if hasattr(m, "NAME") and hasattr(m, "eval"):
                    m = Material.from_brdf(m, name)
                else:
                    raise SceneError(f"[materials.{name}] must be a Material or a warp_sg.brdf model, got {m!r}",
                                     where=where)
            m.name = m.name or name
            mats[name] = m
        self.materials = mats
        if not self.objects:
            raise SceneError("the scene has no objects (add an [[objects]] table)", where=where)
        for i, ob in enumerate(self.objects):
            if ob.material not in self.materials:
                raise SceneError(f"[[objects]] #{i + 1} material '{ob.material}' is not defined"
                                 f"{_suggest(ob.material, self.materials)}", where=where)
        envs = [li for li in self.lights if isinstance(li, EnvironmentLight)]
        if len(envs) > 1:
            raise SceneError("at most one environment light is supported", where=where)
        for j, li in enumerate(self.lights):
            if not isinstance(li, (PointLight, DirectionalLight, EnvironmentLight)):
                raise SceneError(f"[[lights]] #{j + 1} is not a light record: {li!r}", where=where)
        if not self.lights:
            raise SceneError("the scene has no lights (add a [[lights]] table)", where=where)
        self.render.validate(f"[render]" if self.path is None else "[render]")
        self._geometry = None

    # convenience views -------------------------------------------------------------------
    @property
    def material_names(self) -> list:
        return list(self.materials)

    @property
    def environment(self) -> EnvironmentLight | None:
        return next((li for li in self.lights if isinstance(li, EnvironmentLight)), None)

    @property
    def local_lights(self) -> list:
        """Point and directional lights (in scene order)."""
        return [li for li in self.lights if isinstance(li, (PointLight, DirectionalLight))]

    def geometry(self) -> Geometry:
        """Flatten all objects into one validated world-space :class:`Geometry` (cached; call
        :meth:`invalidate_geometry` after changing objects)."""
        if self._geometry is None:
            self._geometry = build_geometry(self)
        return self._geometry

    def invalidate_geometry(self) -> None:
        self._geometry = None


def _suggest(name, options) -> str:
    m = difflib.get_close_matches(str(name), [str(o) for o in options], n=1, cutoff=0.5)
    return f" — did you mean '{m[0]}'?" if m else ""


# --------------------------------------------------------------------------------------------
# geometry
# --------------------------------------------------------------------------------------------
def validate_mesh(vertices, triangles, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check a mesh; returns (vertices f32, triangles i32, keep mask of non-degenerate triangles).

    Non-finite vertices and out-of-range / non-integer indices raise :class:`MeshError` naming
    the first bad element (:func:`warp_sg.meshcheck.check_mesh`)."""
    v, t, _ = check_mesh(vertices, triangles, where=where, require_triangles=True)
    e = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    area2 = np.linalg.norm(e, axis=1)
    scale = max(float(np.max(np.ptp(v, axis=0))), 1e-30)
    keep = area2 > 1e-12 * scale * scale
    if not keep.any():
        raise MeshError("every triangle has zero area", where=where)
    return v.astype(np.float32), t.astype(np.int32), keep


def vertex_normals(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (numpy, float64)."""
    e = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]).astype(np.float64)
    n = np.zeros((len(v), 3))
    for k in range(3):
        np.add.at(n, t[:, k], e)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    fallback = np.tile([0.0, 1.0, 0.0], (len(v), 1))
    return np.where(ln > 0, n / np.where(ln > 0, ln, 1), fallback)


def uv_tangents(v, t, uv, n) -> np.ndarray:
    """Per-vertex tangents ∂P/∂u from UVs (accumulated per triangle, Gram–Schmidt against ``n``);
    the Duff frame tangent of ``n`` where the UVs are degenerate or absent."""
    from .frames import frame_from_normal

    v = v.astype(np.float64)
    n = n.astype(np.float64)
    acc = np.zeros((len(v), 3))
    if uv is not None:
        uv = uv.astype(np.float64)
        d1 = v[t[:, 1]] - v[t[:, 0]]
        d2 = v[t[:, 2]] - v[t[:, 0]]
        w1 = uv[t[:, 1]] - uv[t[:, 0]]
        w2 = uv[t[:, 2]] - uv[t[:, 0]]
        det = w1[:, 0] * w2[:, 1] - w2[:, 0] * w1[:, 1]
        ok = np.abs(det) > 1e-20
        r = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        T = (d1 * w2[:, 1:2] - d2 * w1[:, 1:2]) * r[:, None]
        for k in range(3):
            np.add.at(acc, t[:, k], T)
    acc -= n * np.sum(acc * n, axis=1, keepdims=True)
    ln = np.linalg.norm(acc, axis=1, keepdims=True)
    duff, _ = frame_from_normal(n)
    return np.where(ln > 1e-12, acc / np.where(ln > 1e-12, ln, 1), duff)


def _read_simple_obj(path: Path) -> MeshData | None:
    """Minimal OBJ reader ('v' and 'f' lines, fans triangulated) used only to diagnose files that
    trimesh cannot load (e.g. out-of-range indices); None when it cannot parse the file either."""
    try:
        verts, faces = [], []
        for line in path.read_text(errors="replace").splitlines():
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
        return MeshData(np.asarray(verts, np.float64).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3))
    except (ValueError, IndexError, OSError):
        return None


def _load_mesh_file(path: Path, where: str) -> MeshData:
    import trimesh

    if not path.is_file():
        raise SceneError(f"mesh file not found: {path}", where=where)
    try:
        m = trimesh.load(str(path), force="mesh", process=False)
    except Exception as e:  # noqa: BLE001 - trimesh raises many types
        if path.suffix.lower() == ".obj":  # name the bad element when we can (trimesh crashes on bad indices)
            simple = _read_simple_obj(path)
            if simple is not None:
                validate_mesh(simple.vertices, simple.triangles, where=str(path))
        raise MeshError(f"cannot read mesh ({type(e).__name__}: {e})", where=str(path)) from None
    if not hasattr(m, "faces") or len(getattr(m, "faces", [])) == 0:
        raise MeshError("file contains no triangles", where=str(path))
    v = np.asarray(m.vertices)
    f = np.asarray(m.faces)
    uv = None
    vis = getattr(m, "visual", None)
    if vis is not None and getattr(vis, "uv", None) is not None and len(vis.uv) == len(v):
        uv = np.asarray(vis.uv, np.float32)
    normals = None
    if "vertex_normals" in getattr(m, "_cache", {}) or getattr(m, "_vertex_normals", None) is not None:
        normals = None  # trimesh keeps file normals in its cache; read them below when sane
    try:
        if np.all(np.isfinite(v)) and len(v):
            vn = np.asarray(m.vertex_normals, np.float64)
            if vn.shape == v.shape and np.all(np.isfinite(vn)):
                normals = vn.astype(np.float32)
    except Exception:  # noqa: BLE001 - normals are recomputed by us anyway
        normals = None
    return MeshData(v, f, normals, uv, None)


def object_mesh(ob: SceneObject, index: int, base: Path | None) -> MeshData:
    """The object's mesh in world space (transform applied), attributes filled in."""
    where = f"{'scene' if base is None else base}: [[objects]] #{index + 1}"
    if ob.primitive is not None:
        try:
            mesh = make_primitive(ob.primitive, dict(ob.params), where=f"{ob.primitive}")
        except InputError as e:
            raise SceneError(str(e), where=where) from None
    elif ob.mesh is not None:
        p = Path(ob.mesh)
        mesh = _load_mesh_file(p, where)
    elif ob.vertices is not None and ob.triangles is not None:
        mesh = MeshData(np.asarray(ob.vertices), np.asarray(ob.triangles),
                        None if ob.normals is None else np.asarray(ob.normals, np.float32),
                        None if ob.uvs is None else np.asarray(ob.uvs, np.float32),
                        None if ob.tangents is None else np.asarray(ob.tangents, np.float32))
    else:
        raise SceneError("needs 'mesh', 'primitive' or vertices + triangles", where=where)
    label = ob.label(index)
    v, t, keep = validate_mesh(mesh.vertices, mesh.triangles, where=f"{where} ({label})")
    n = mesh.normals
    if n is None or n.shape != v.shape or not np.all(np.isfinite(n)) or np.any(np.linalg.norm(n, axis=1) < 1e-12):
        n = vertex_normals(v, t[keep]).astype(np.float32)
    else:
        n = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    uv = mesh.uvs
    if uv is not None and (uv.shape != (len(v), 2) or not np.all(np.isfinite(uv))):
        raise MeshError(f"uvs must have shape ({len(v)}, 2) and be finite, got {uv.shape}", where=f"{where} ({label})")
    tan = mesh.tangents
    if tan is None or tan.shape != v.shape or not np.all(np.isfinite(tan)):
        tan = uv_tangents(v, t[keep], uv, n).astype(np.float32)
    mesh = MeshData(v, t[keep], n, np.zeros((len(v), 2), np.float32) if uv is None else uv.astype(np.float32), tan)
    mesh = ob.transform.apply(mesh)
    # re-orthogonalise the tangents against the (transformed) normals
    tn = mesh.tangents.astype(np.float64)
    nn = mesh.normals.astype(np.float64)
    tn -= nn * np.sum(tn * nn, 1, keepdims=True)
    ln = np.linalg.norm(tn, axis=1, keepdims=True)
    from .frames import frame_from_normal

    duff, _ = frame_from_normal(nn)
    mesh.tangents = np.where(ln > 1e-12, tn / np.where(ln > 1e-12, ln, 1), duff).astype(np.float32)
    mesh.dropped = int((~keep).sum())  # type: ignore[attr-defined]
    return mesh


def build_geometry(scene: Scene) -> Geometry:
    names = scene.material_names
    vs, ns, uvs, ts, tris, tm, to, vo, labels = [], [], [], [], [], [], [], [], []
    base = 0
    dropped = 0
    for i, ob in enumerate(scene.objects):
        m = object_mesh(ob, i, scene.path)
        vs.append(m.vertices)
        ns.append(m.normals)
        uvs.append(m.uvs)
        ts.append(m.tangents)
        tris.append(m.triangles + base)
        tm.append(np.full(len(m.triangles), names.index(ob.material), np.int32))
        to.append(np.full(len(m.triangles), i, np.int32))
        vo.append(np.full(len(m.vertices), i, np.int32))
        labels.append(ob.label(i))
        dropped += getattr(m, "dropped", 0)
        base += len(m.vertices)
    return Geometry(
        vertices=np.ascontiguousarray(np.concatenate(vs), np.float32),
        normals=np.ascontiguousarray(np.concatenate(ns), np.float32),
        uvs=np.ascontiguousarray(np.concatenate(uvs), np.float32),
        tangents=np.ascontiguousarray(np.concatenate(ts), np.float32),
        triangles=np.ascontiguousarray(np.concatenate(tris), np.int32),
        tri_material=np.concatenate(tm).astype(np.int32),
        tri_object=np.concatenate(to).astype(np.int32),
        vertex_object=np.concatenate(vo).astype(np.int32),
        material_names=names,
        object_names=labels,
        dropped_triangles=dropped,
    )


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


__all__ = ["Scene", "SceneObject", "Material", "Transform", "RenderSettings", "Geometry", "Camera", "load_scene",
           "PointLight", "DirectionalLight", "EnvironmentLight", "Texture", "validate_mesh", "build_geometry"]

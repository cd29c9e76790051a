"""The scene's data model: :class:`Scene` and its records :class:`SceneObject`, :class:`Transform`
and :class:`Material`, with the ``[render]`` settings of :mod:`warp_sg.scene.render_settings`
(what the renderer *and* the Monte-Carlo reference read; the fields are described in
:mod:`warp_sg.scene`, which re-exports every name). Validation of a whole scene happens in
``Scene.__post_init__``; the TOML file is read by :mod:`warp_sg.scene.loader`, the geometry
flattened by :mod:`warp_sg.scene.geometry`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from warp_sg.brdf import MODELS
from warp_sg.core.errors import SceneError
from warp_sg.core.suggest import did_you_mean
from warp_sg.scene.camera import Camera
from warp_sg.scene.geometry import Geometry, build_geometry
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.material_layers import MaterialLayers
from warp_sg.scene.primitives import MeshData
from warp_sg.scene.render_settings import RenderSettings
from warp_sg.scene.textures import Texture


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
        from warp_sg.numeric.rigid_motion import euler_rotation

        s = np.broadcast_to(np.asarray(self.scale, np.float64), (3,))
        return euler_rotation(self.rotate) @ np.diag(s)

    def is_identity(self) -> bool:
        return (np.allclose(self.translate, 0) and np.allclose(self.scale, 1) and np.allclose(self.rotate, 0))

    def apply(self, mesh: MeshData) -> MeshData:
        if self.is_identity():
            return mesh
        A = self.linear()
        if abs(np.linalg.det(A)) < 1e-30:
            raise SceneError("transform is singular (a zero scale?)", where="transform")
        v = mesh.vertices.astype(np.float64) @ A.T + np.asarray(self.translate, np.float64)
        v = np.clip(v, -np.finfo(np.float32).max, np.finfo(np.float32).max)  # (far vertices are refused later)
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
    """One object: ``mesh`` (file), ``primitive`` (+ ``params``) or inline arrays; a material name
    (``None`` for a glTF ``mesh``: the file's materials)."""

    material: str | None
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
    #: per-vertex colour (V, 4) linear RGBA multiplying kd (RGB) and the cut-out alpha (A), and the
    #: (V, 3) factor it puts on ks (glTF COLOR_0, :func:`warp_sg.scene.importers.gltf_material.vertex_colour_factors`)
    colors: np.ndarray | None = None
    specular_colors: np.ndarray | None = None
    #: may move after the precompute (``[[objects]] dynamic = true``; :mod:`warp_sg.renderer.dynamic_objects`)
    dynamic: bool = False
    #: (4, 4) rigid motion (rotation, translation, uniform scale) applied after ``transform``
    #: (``Renderer.set_object_transform``; None: none)
    motion: np.ndarray | None = None
    #: False: the back faces (clockwise as seen) are culled for camera rays, whatever the mesh's
    #: closedness (glTF 2.0 §3.9.5 ``doubleSided`` false, the glTF default; the raster and the
    #: Monte-Carlo reference: :mod:`warp_sg.scene.culling`); True: both sides are seen
    double_sided: bool = True

    def label(self, index: int) -> str:
        return self.name or (Path(self.mesh).name if self.mesh is not None else self.primitive) or f"objects[{index}]"


#: Parameters that are RGB colours (others are scalars): those the models declare so (``Param.kind``)
COLOUR_PARAMS = tuple(dict.fromkeys(k for cls in MODELS.values() for k, p in cls.PARAMS.items() if p.kind == "rgb"))


@dataclass
class Material:
    """A material: ``model`` name, constant ``params``, per-texel ``textures`` and normal/tangent maps."""

    model: str
    params: dict = field(default_factory=dict)
    textures: dict = field(default_factory=dict)  # {param: Texture}
    normal_map: Texture | None = None
    tangent_map: Texture | None = None
    name: str | None = None
    #: emission, occlusion, alpha cut-out and clear coat (:mod:`warp_sg.scene.material_layers`; glTF)
    layers: MaterialLayers | None = None
    _brdf: object = field(default=None, repr=False, compare=False)

    @classmethod
    def from_brdf(cls, model, name=None) -> "Material":
        """Wrap a ``warp_sg.brdf`` model instance."""
        from warp_sg.brdf.energy import check_diffuse_albedo

        check_diffuse_albedo(model)
        m = cls(model=model.NAME, params={}, name=name)
        m._brdf = model
        return m

    @property
    def brdf(self):
        """The ``warp_sg.brdf`` model (textured parameters replaced by the texture means)."""
        if self._brdf is None:
            from warp_sg.brdf import make_model

            p = dict(self.params)
            for k, tex in self.textures.items():
                mean = tex.mean(colour=k in COLOUR_PARAMS)
                p[k] = mean.tolist() if k in COLOUR_PARAMS else float(mean[0])
            self._brdf = make_model(self.model, **p)
        return self._brdf

    def updated(self, name: str, **params) -> "Material":
        """A checked copy with ``params`` changed (a :class:`Texture` value makes a parameter
        textured, ``normal_map``/``tangent_map`` set those maps, ``model=`` switches the model,
        whose constant parameters are then only these); this material is left as it was. A bad
        value raises :class:`SceneError` ``[materials.NAME] ...``."""
        from dataclasses import replace

        from warp_sg.core.errors import InputError

        m = replace(self, params=dict(self.params), textures=dict(self.textures), _brdf=None)
        params = dict(params)
        if "model" in params:
            m.model, m.params = str(params.pop("model")), {}
        for k, v in params.items():
            if k in ("normal_map", "tangent_map"):
                setattr(m, k, v)
            elif isinstance(v, Texture):
                m.textures[k] = v
                m.params.pop(k, None)
            else:
                m.textures.pop(k, None)
                m.params[k] = v
        try:
            _ = m.brdf
        except InputError as e:
            raise SceneError(f"[materials.{name}] {e}") from None
        return m

    def invalidate(self) -> None:
        """Forget the cached model (call after changing ``params``/``textures``)."""
        self._brdf = None


Light = PointLight | DirectionalLight | EnvironmentLight


# --------------------------------------------------------------------------------------------
# Scene
# --------------------------------------------------------------------------------------------
@dataclass
class Scene:
    """A renderable scene (see :mod:`warp_sg.scene`). ``path`` is the scene file, if any."""

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
        self.objects, self.materials = _expand_assets(list(self.objects), self.materials, where)
        if not self.objects:
            raise SceneError("the scene has no objects (add an [[objects]] table)", where=where)
        for i, ob in enumerate(self.objects):
            if ob.material not in self.materials:
                raise SceneError(f"[[objects]] #{i + 1} material '{ob.material}' is not defined"
                                 f"{did_you_mean(ob.material, self.materials)}", where=where)
        envs = [li for li in self.lights if isinstance(li, EnvironmentLight)]
        if len(envs) > 1:
            raise SceneError("at most one environment light is supported", where=where)
        for j, li in enumerate(self.lights):
            if not isinstance(li, (PointLight, DirectionalLight, EnvironmentLight)):
                raise SceneError(f"[[lights]] #{j + 1} is not a light record: {li!r}", where=where)
        if not self.lights:
            raise SceneError("the scene has no lights (add a [[lights]] table)", where=where)
        self.render.validate()
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


def _expand_assets(objects: list, materials: dict, where: str) -> tuple[list, dict]:
    """Every glTF or USD object (``mesh = "*.glb" | "*.gltf" | "*.usd" ...``) becomes one object per
    mesh primitive (USD: per mesh and material subset), in the file's world frame with the object's
    transform; without a ``material`` of its own, the file's materials join the scene as
    ``"<label>/<name>"`` (:mod:`warp_sg.scene.importers.gltf`, :mod:`warp_sg.scene.importers.usd`)."""
    from warp_sg.scene.importers import scene_asset_reader

    out, mats = [], dict(materials)
    for i, ob in enumerate(objects):
        read = None if ob.mesh is None else scene_asset_reader(ob.mesh)
        if read is None:
            out.append(ob)
            continue
        parts, specs = read(ob.mesh, ob.label(i), materials=ob.material is None)
        for key, spec in specs.items():
            if key in mats:
                raise SceneError(f"[[objects]] #{i + 1} material '{key}' of {Path(ob.mesh).name} is also defined "
                                 f"by the scene (give the object another name)", where=where)
            mats[key] = Material(name=key, **spec)
        out.extend(SceneObject(material=ob.material or p.material, transform=ob.transform, name=p.name,
                               dynamic=ob.dynamic, motion=ob.motion, double_sided=p.double_sided,
                               vertices=p.vertices, triangles=p.triangles, normals=p.normals, uvs=p.uvs,
                               tangents=p.tangents, colors=p.colors, specular_colors=p.specular_colors)
                   for p in parts)
    return out, mats


__all__ = ["Scene", "SceneObject", "Material", "Transform", "Light", "COLOUR_PARAMS"]

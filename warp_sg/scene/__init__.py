r"""Scenes: TOML files (``tomllib``) and the equivalent Python objects.

``ws.load_scene(path)`` reads a scene file (every key: docs/scene-keys.md; their use:
docs/rendering.md "Scene files") and returns a :class:`Scene`; ``ws.Scene(camera=..., objects=[...], materials={...},
lights=[...])`` builds the
same thing in Python. Every mistake is a :class:`~warp_sg.core.errors.SceneError` (or
``MeshError``/``ImageError`` for unusable files) whose message names the file, the table and the
key or element, e.g. ``scene.toml: [camera] key 'fvo' unknown — did you mean 'fov'?``.

Records (what the renderer *and* the Monte-Carlo reference read)
------------------------------------------------------------------
* ``Scene.camera`` — :class:`warp_sg.scene.camera.Camera` ``(origin, target, up, fov, width, height,
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
* ``Scene.lights`` — :class:`~warp_sg.scene.lights.PointLight` (position, radius, intensity s W/sr),
  :class:`~warp_sg.scene.lights.DirectionalLight` (unit direction *towards* the light, angular radius in
  radians, intensity = irradiance E) and at most one :class:`~warp_sg.scene.lights.EnvironmentLight`
  (file | procedural "sky"/"constant", options, scale, rotation degrees about +Y).
* ``Scene.render`` — :class:`RenderSettings` (the ``[render]`` table, :mod:`warp_sg.scene.render_settings`).
* ``Scene.geometry()`` — :class:`Geometry`: every object flattened into one triangle soup in world
  space (vertices, normals, uvs, tangents, triangles, ``tri_material`` indexing
  ``Scene.material_names``, ``tri_object``), validated (NaN vertex / out-of-range index →
  ``MeshError`` naming the object and element; zero-area triangles dropped and counted).

All objects share one geometry, so they shadow each other (multi-object composition).

Scene file keys: every table and key with its values, default and meaning is generated from the
scene-file models of :mod:`warp_sg.scene.schema` into ``docs/scene-keys.md`` (``warp-sg schema
--markdown``); the ``[render]`` table is :mod:`warp_sg.scene.render_settings`'s, which also checks
the :class:`RenderSettings` of a scene built in Python.

Files: this module is the public entry and re-exports every name; the data model is in
:mod:`warp_sg.scene.model` and :mod:`warp_sg.scene.render_settings`, the TOML loader in :mod:`warp_sg.scene.loader`, the typed models of the
file format it validates with (and their JSON Schema, ``warp-sg schema``, and key reference) in
:mod:`warp_sg.scene.schema`, :mod:`warp_sg.scene.values` and :mod:`warp_sg.scene.key_reference`, mesh
files, normals, tangents and the flattened :class:`Geometry` in :mod:`warp_sg.scene.geometry`, the camera
in :mod:`warp_sg.scene.camera`.
"""
from warp_sg.scene.camera import Camera
from warp_sg.scene.geometry import Geometry, build_geometry, object_mesh, uv_tangents, validate_mesh, vertex_normals
from warp_sg.scene.lights import DirectionalLight, EnvironmentLight, PointLight
from warp_sg.scene.loader import load_scene
from warp_sg.scene.model import COLOUR_PARAMS, Light, Material, Scene, SceneObject, Transform
from warp_sg.scene.render_settings import RenderSettings
from warp_sg.scene.textures import Texture

__all__ = ["Scene", "SceneObject", "Material", "Transform", "RenderSettings", "Geometry", "Camera", "load_scene",
           "PointLight", "DirectionalLight", "EnvironmentLight", "Texture", "validate_mesh", "build_geometry",
           "object_mesh", "uv_tangents", "vertex_normals", "COLOUR_PARAMS", "Light"]

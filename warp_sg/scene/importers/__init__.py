"""Scene layer, importers: glTF 2.0 assets as scene objects (``gltf``, ``gltf_checks``,
``gltf_material``) and the scene made around one asset file (``asset``)."""

"""Engines layer, kernel-side shading: the per-pixel kernel variants (``kernel``, eq. 36-43), per-texel
materials and frames (``surface``, ``surface_layers``), alpha cut-outs (``cutout``), the per-vertex
visibility caches (``vertex_visibility``), contour edges (``silhouette``) and the background.
May import base, math, scene and the other engines (``raster``, ``precompute``)."""

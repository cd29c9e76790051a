"""The kernel side of the BRDFs (Warp, float32): the ``Material`` struct and its packing, the
model-independent ``@wp.func`` pieces, the model switch generated from the registry
(:mod:`~warp_sg.brdf.kernel.material_variants`), the MERL lookups and the environment specular's
energy table. :mod:`~warp_sg.brdf.kernel.material_wp` is the entry the renderer and the
Monte-Carlo reference import (docs/architecture.md "BRDF contract").
"""

"""The BRDF models, one module each: a model class with its numpy evaluation, fit hooks and kernel
``@wp.func`` functions, registered in :mod:`warp_sg.brdf.registry` by ``@register``.

Importing this package imports every module in it, so a new model's file is found by itself.
"""
from __future__ import annotations

import importlib
import pkgutil

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    importlib.import_module(f"{__name__}.{_info.name}")
del _info

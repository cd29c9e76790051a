"""PEP 562 lazy attributes for package ``__init__`` modules (``warp_sg``, ``precompute``): a name
is imported on first use, so importing a package does not compile every module's kernels and
``raster``/``precompute`` can import ``warp_sg.errors`` without an import cycle."""
from __future__ import annotations

import importlib


def lazy_getattr(package_globals: dict, table: dict[str, tuple[str, str | None]]):
    """Return a module ``__getattr__`` resolving ``name -> (module, attribute or None for the module)``."""
    package = package_globals["__name__"]

    def __getattr__(name):
        if name in table:
            mod, attr = table[name]
            m = importlib.import_module(mod)
            val = m if attr is None else getattr(m, attr)
            package_globals[name] = val
            return val
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__

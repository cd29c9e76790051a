"""Public names that load on first use (PEP 562): a package lists ``{name: (module, attribute)}``
and its module ``__getattr__`` is :func:`lazy_getattr` of that table, so importing the package does
not import every layer below it (``warp_sg``, ``precompute``)."""
from __future__ import annotations

import importlib


def lazy_getattr(package: str, table: dict, namespace: dict):
    """The module ``__getattr__`` of ``package``: ``table[name] = (module, attribute or None for the
    module itself)``; the value found is kept in ``namespace`` (the package's globals), so the
    lookup runs once per name."""
    def __getattr__(name):
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attr = table[name]
        value = importlib.import_module(module)
        if attr is not None:
            value = getattr(value, attr)
        namespace[name] = value
        return value

    return __getattr__


__all__ = ["lazy_getattr"]

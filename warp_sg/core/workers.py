"""Worker-count policy for CPU thread pools (base layer; shared by warp_sg, raster and precompute).

Warp runs a CPU launch serially on one core; launching disjoint ranges of a kernel from a small
thread pool scales (docs/raster.md "Performance"). :func:`cpu_workers` is the one answer to
"how many threads": 1 on a GPU device; else ``$WARP_SG_THREADS`` when set (the rasterizer also
reads its older ``$RASTER_THREADS`` first); else the cores this process may run on, at most
``limit``.
"""
from __future__ import annotations

import os

#: Environment variable that overrides the number of CPU worker threads everywhere.
THREADS_ENV = "WARP_SG_THREADS"
#: Most threads of the ray-casting pools (visibility batches, the Monte-Carlo reference).
RAY_THREADS = 8


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity; ``os.cpu_count()`` where unknown)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def cpu_workers(device="cpu", limit: int | None = None, *, env: tuple[str, ...] = (THREADS_ENV,)) -> int:
    """Threads for CPU work on ``device``: 1 unless it is the CPU; else the first of the ``env``
    variables that is set (at least 1); else :func:`usable_cores`, at most ``limit``."""
    if not str(device).startswith("cpu"):
        return 1
    for name in env:
        value = os.environ.get(name)
        if value:
            return max(1, int(value))
    n = usable_cores()
    return max(1, min(n, int(limit)) if limit else n)


__all__ = ["RAY_THREADS", "THREADS_ENV", "cpu_workers", "usable_cores"]

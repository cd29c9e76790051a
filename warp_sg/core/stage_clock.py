"""Wall and CPU time of named stages (base layer; the precompute profile of ``docs/benchmarks.md``).

On a machine shared with other work the wall time of a stage says little about its cost; the CPU
time does. :class:`StageClock` records both for every stage it times:

* ``wall[name]`` — ``time.perf_counter`` seconds;
* ``cpu[name]`` — ``time.process_time`` seconds of the whole process (every thread's CPU, so a
  stage that keeps two cores busy shows about twice its wall time). A stage timed while another
  thread of the process works (the progressive renderer's background precompute) also counts
  that thread's CPU.

:func:`thread_cpu` is ``time.thread_time``: the CPU of the calling thread only, for work split
over a thread pool (each worker adds its own share, :meth:`StageClock.add`). :func:`load_average`
reads the 1-minute load (what else ran on the cores) so a profile can state it.
"""
from __future__ import annotations

import os
import threading
import time
from contextlib import contextmanager


def thread_cpu() -> float:
    """CPU seconds of the calling thread (``time.thread_time``)."""
    return time.thread_time()


def load_average() -> float:
    """The 1-minute load average (NaN where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):  # pragma: no cover - non-Unix
        return float("nan")


class StageClock:
    """Wall and CPU seconds per named stage; a stage timed twice adds up."""

    def __init__(self):
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {}
        self.counts: dict[str, int] = {}
        self._lock = threading.Lock()

    @contextmanager
    def stage(self, name: str):
        """Time the ``with`` body as stage ``name`` (wall: perf_counter; CPU: process_time)."""
        w0, c0 = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - w0, time.process_time() - c0)

    def add(self, name: str, wall: float = 0.0, cpu: float = 0.0) -> None:
        """Add ``wall`` and ``cpu`` seconds to stage ``name`` (thread-safe)."""
        with self._lock:
            self.wall[name] = self.wall.get(name, 0.0) + float(wall)
            self.cpu[name] = self.cpu.get(name, 0.0) + float(cpu)

    def count(self, name: str, n: int) -> None:
        """Add ``n`` to counter ``name`` (rays cast, vertices skipped; thread-safe)."""
        with self._lock:
            self.counts[name] = self.counts.get(name, 0) + int(n)

    def merge(self, other: dict | None, prefix: str = "") -> None:
        """Add the stages of another clock's :meth:`as_dict` (names prefixed)."""
        for name, (w, c) in (other or {}).items():
            self.add(prefix + name, w, c)

    def as_dict(self) -> dict[str, tuple[float, float]]:
        """``{name: (wall, cpu)}`` in the order the stages were first timed."""
        return {k: (self.wall[k], self.cpu.get(k, 0.0)) for k in self.wall}


__all__ = ["StageClock", "load_average", "thread_cpu"]

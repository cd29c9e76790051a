"""Warp's module loads while a block runs: which modules were compiled, and how long each took
(base layer; the first-run profile and ``warp-sg bench``'s "first run").

Warp times every module load and reports it through its logger at the info level (``Module NAME
HASH load on device 'cpu' took T ms (compiled|cached)``). :class:`ModuleLoads` lowers
``warp.config.log_level`` to info for the block, installs a logger (``wp.set_logger``, Warp ≥ 1.19)
that keeps those lines as records instead of printing them, and hands every other message to the
logger that was active. Warp versions without ``set_logger`` record nothing (the block runs as
usual). A load that ran on another thread counts too: a compiled module's seconds are its
thread's wall time, so loads on parallel threads overlap.
"""
from __future__ import annotations

import re
import threading
from dataclasses import dataclass

import warp as wp

_LINE = re.compile(r"Module (\S+)(?: [0-9a-f]+)? load on device '([^']+)' took ([0-9.]+) ms\s*\((compiled|cached)\)")


@dataclass(frozen=True)
class ModuleLoad:
    name: str
    device: str
    seconds: float
    compiled: bool
    thread: str


class _Collector:
    """A Warp logger (debug, info, warning, error) that keeps module-load lines."""

    def __init__(self, outer, loads: list, lock: threading.Lock):
        self.outer, self.loads, self.lock = outer, loads, lock

    def debug(self, message):
        self.outer.debug(message)

    def info(self, message):
        m = _LINE.search(str(message))
        if m is None:
            return  # (the other info lines the lowered level lets through: not ours to print)
        with self.lock:
            self.loads.append(ModuleLoad(m.group(1), m.group(2), float(m.group(3)) / 1000.0,
                                         m.group(4) == "compiled", threading.current_thread().name))

    def warning(self, message, category=None, stacklevel=1):
        self.outer.warning(message, category, stacklevel + 1)

    def error(self, message):
        self.outer.error(message)


class ModuleLoads:
    """``with ModuleLoads() as loads: ...``: ``loads.records`` (:class:`ModuleLoad` each),
    ``loads.compiled`` (names compiled), ``loads.compile_seconds`` (their summed load time)."""

    def __init__(self):
        self.records: list[ModuleLoad] = []
        self._lock = threading.Lock()
        self._saved = None

    def __enter__(self):
        set_logger = getattr(wp, "set_logger", None)
        if set_logger is None:  # pragma: no cover - Warp < 1.19
            return self
        self._saved = (wp.get_logger(), wp.config.log_level)
        set_logger(_Collector(self._saved[0], self.records, self._lock))
        wp.config.log_level = getattr(wp, "LOG_INFO", 20)
        return self

    def __exit__(self, *exc):
        if self._saved is not None:
            logger, level = self._saved
            wp.config.log_level = level
            wp.set_logger(logger)
            self._saved = None

    @property
    def compiled(self) -> list[str]:
        return [r.name for r in self.records if r.compiled]

    @property
    def compile_seconds(self) -> float:
        return sum(r.seconds for r in self.records if r.compiled)


__all__ = ["ModuleLoads", "ModuleLoad"]

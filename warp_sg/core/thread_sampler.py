"""Which of the process's threads work, sampled (base layer; the cold-path profile's per-thread view).

On a machine shared with other work the wall time says little, and whether *both cores would be
busy* on an idle machine cannot be read from it either. The scheduler's own record can: every
``interval`` seconds :class:`ThreadSampler` reads ``/proc/self/task/*/stat`` (Linux) and counts the
process's threads in state ``R`` (running, or runnable and waiting for a core another process
holds). A sample with at least as many runnable threads as cores is one in which an idle machine's
cores would all be busy; one with fewer leaves ``cores − runnable`` of them idle, whatever the
load. It also reads each thread's CPU seconds (``utime + stime``) by its Python thread name.

* :meth:`ThreadSampler.summary` — over a time window (a stage): the mean number of runnable
  threads, the share of samples with every core busy, the core-seconds left idle, and
* :meth:`ThreadSampler.thread_cpu` — CPU seconds per thread name (pool threads merged by the
  name's prefix up to its last ``_``), so a profile says which thread did what.

Elsewhere (no ``/proc``) the sampler records nothing and the summaries are empty.
"""
from __future__ import annotations

import os
import threading
import time

_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _read_tasks() -> dict[int, tuple[str, str, int]]:
    """{thread id: (name, state letter, CPU clock ticks)} of this process's threads."""
    out = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/stat", "rb") as f:
                s = f.read().decode("utf-8", "replace")
        except OSError:  # (a thread that ended meanwhile)
            continue
        lp, rp = s.find("("), s.rfind(")")
        rest = s[rp + 2:].split()
        out[int(tid)] = (s[lp + 1:rp], rest[0], int(rest[11]) + int(rest[12]))
    return out


class ThreadSampler:
    """Samples this process's threads every ``interval`` seconds on a daemon thread (module
    docstring); ``with ThreadSampler() as s: ...`` or :meth:`start` / :meth:`stop`."""

    def __init__(self, interval: float = 0.01, cores: int | None = None):
        self.interval = float(interval)
        self.cores = int(cores or os.cpu_count() or 1)
        self.samples: list[tuple[float, int]] = []  # (perf_counter, runnable threads of ours)
        self._cpu: dict[int, tuple[str, int]] = {}  # tid -> (name, last CPU ticks seen)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._me: int | None = None

    def start(self) -> "ThreadSampler":
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="warp-sg-sampler", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def _run(self):
        self._me = threading.get_native_id()
        while not self._stop.is_set():
            t = time.perf_counter()
            tasks = _read_tasks()
            names = {th.native_id: th.name for th in threading.enumerate()}  # (the OS name is "python")
            n = 0
            for tid, (comm, state, ticks) in tasks.items():
                if tid == self._me:
                    continue
                n += state == "R"
                self._cpu[tid] = (names.get(tid, self._cpu.get(tid, (comm,))[0]), ticks)
            self.samples.append((t, n))
            self._stop.wait(self.interval)

    def summary(self, t0: float | None = None, t1: float | None = None) -> dict:
        """Over samples with ``t0 <= t < t1`` (perf_counter; None: unbounded): ``runnable`` (mean
        runnable threads), ``all_busy`` (share of samples with at least one runnable thread per
        core), ``idle_core_s`` (core-seconds an idle machine would have left idle) and ``seconds``."""
        sel = [(t, n) for t, n in self.samples if (t0 is None or t >= t0) and (t1 is None or t < t1)]
        if not sel:
            return {}
        dt = self.interval if len(sel) < 2 else (sel[-1][0] - sel[0][0]) / (len(sel) - 1)
        return {"runnable": sum(n for _, n in sel) / len(sel),
                "all_busy": sum(n >= self.cores for _, n in sel) / len(sel),
                "idle_core_s": sum(max(self.cores - n, 0) for _, n in sel) * dt,
                "seconds": len(sel) * dt}

    def thread_cpu(self) -> dict[str, float]:
        """CPU seconds per thread name (pool threads, ``name_0``, ``name_1``, ..., merged by their
        prefix), the sampler itself left out; threads that ended count up to their last sample."""
        out: dict[str, float] = {}
        for name, ticks in self._cpu.values():
            head, sep, tail = name.rpartition("_")
            key = head if sep and tail.isdigit() else name
            out[key] = out.get(key, 0.0) + ticks / _TICK
        return dict(sorted(out.items(), key=lambda kv: -kv[1]))


__all__ = ["ThreadSampler"]

"""Spreading one kernel launch over CPU cores.

Warp runs a CPU launch serially on one core. Every data-parallel raster kernel takes an index
offset ``base`` as its first argument (element ``i = base + wp.tid()``, or ``base + wp.tid()·per +
s`` for a kernel launched with ``per_thread``), so disjoint index ranges
of the *same* compiled kernel can be launched from a small Python thread pool (Warp releases the
GIL while a CPU kernel runs; measured ≈1.9× on 2 cores). The calling thread takes ranges too, with
one pool thread fewer than the workers (it would otherwise wait idle, and every range handed to a
pool thread costs a wake-up). On CUDA a single launch covers the whole range.

Kernels launched this way must not rely on atomics between ranges: Warp's CPU atomics are
plain read-modify-writes, which are only safe when one range owns each written element.
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import warp as wp

from warp_sg.core.workers import THREADS_ENV
from warp_sg.core.workers import cpu_workers as _cpu_workers

_POOL: ThreadPoolExecutor | None = None
_LOADED: set = set()


def ensure_loaded(kernel, device) -> None:
    """Load (compile) the kernel's module once, before threads race to do it."""
    key = (id(kernel.module), str(device))
    if key not in _LOADED:
        wp.load_module(kernel.module, device=device)
        _LOADED.add(key)


def is_loaded(kernel, device) -> bool:
    """Whether :func:`launch` has loaded ``kernel``'s module on ``device`` (it then starts at once)."""
    return (id(kernel.module), str(device)) in _LOADED


def load_beside(make_kernel, device):
    """A future of ``make_kernel()`` with its module loaded on ``device`` (:func:`ensure_loaded`),
    made on a thread of its own: a frame whose kernel variant is new (built from its source and its
    module hashed: Python work, a few hundred ms for the shading kernel) prepares it while its other
    launches keep the pool's threads busy. Warp serialises its code generation itself."""
    import threading
    from concurrent.futures import Future

    fut: Future = Future()

    def run():
        try:
            k = make_kernel()
            ensure_loaded(k, device)
            fut.set_result(k)
        except BaseException as e:  # noqa: BLE001  (re-raised by fut.result() in the caller)
            fut.set_exception(e)

    threading.Thread(target=run, name="warp-sg-kernel-load", daemon=True).start()
    return fut


def cpu_workers() -> int:
    """Threads used for CPU launches (:func:`warp_sg.core.workers.cpu_workers`: ``RASTER_THREADS`` or
    ``WARP_SG_THREADS`` override; default = usable cores)."""
    return _cpu_workers("cpu", env=("RASTER_THREADS", THREADS_ENV))


def _pool() -> ThreadPoolExecutor:
    """The helper threads: one fewer than the workers, because the calling thread works too."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=max(cpu_workers() - 1, 1), thread_name_prefix="raster")
    return _POOL


def _run_ranges(run, ranges: list, workers: int) -> None:
    """``run(base, count)`` for every range, shared between the calling thread and ``workers − 1``
    pool threads that take the next range as they finish one (the calling thread would otherwise
    sit idle waiting, and each hand-off to a pool thread costs a wake-up)."""
    it = iter(ranges)
    lock = threading.Lock()

    def work():
        while True:
            with lock:
                r = next(it, None)
            if r is None:
                return
            run(*r)

    futs = [_pool().submit(work) for _ in range(min(workers, len(ranges)) - 1)]
    try:
        work()
    finally:
        for f in futs:  # a helper that has not started has nothing left to do (nor can it, when
            if not f.cancel():  # the caller is itself a pool thread): only running ones are awaited
                f.result()


def launch(kernel, n: int, inputs: list, device: str, chunks: int | None = None, min_chunk: int = 4096,
           per_thread: int | None = None):
    """Launch ``kernel`` over ``n`` elements; ``inputs`` excludes the leading ``base`` offset.

    CPU: split into ``chunks`` contiguous ranges (default 4 per worker) of at least ``min_chunk``
    elements (the last may be shorter) run on the pool. A range costs ~30 µs to dispatch (pool hand-off and Warp's launch):
    the default keeps ranges at ≥ 4096 elements, so a kernel over a few thousand elements (the
    antialiasing candidates) is not split into ranges that cost more than their work; kernels with
    heavy elements (shading, ray casts) pass a smaller ``min_chunk``.
    CUDA: one launch of ``n`` threads.

    ``per_thread`` (kernels with arguments ``(base, per, ...)``): each CPU thread handles ``per``
    consecutive elements ``base + tid·per + s`` (s < per; the kernel skips indices ≥ n). A Warp
    CPU kernel copies its struct arguments at every thread's entry; a kernel with many array
    structs (the shading kernel: ~26 ns per element) spends more there than a background pixel
    costs to shade, so the CPU amortises it over ``per`` elements. CUDA keeps one element per
    thread (``per`` = 1).
    """
    n = int(n)
    if n <= 0:
        return
    ensure_loaded(kernel, device)
    cpu = str(device).startswith("cpu")
    per = max(int(per_thread), 1) if (per_thread is not None and cpu) else 1
    head = [] if per_thread is None else [per]

    def one(b, m):
        wp.launch(kernel, dim=-(-m // per), inputs=[b, *head, *inputs], device=device)

    if not cpu:
        one(0, n)
        return
    workers = cpu_workers()
    if chunks is None:
        chunks = 4 * workers
    chunks = max(1, min(int(chunks), (n + min_chunk - 1) // min_chunk))
    if workers == 1 or chunks == 1:
        one(0, n)
        return
    step = -(-((n + chunks - 1) // chunks) // per) * per  # a multiple of per: ranges never overlap
    _run_ranges(one, [(b, min(step, n - b)) for b in range(0, n, step)], workers)


def launch_split(kernel, bounds, inputs: list, device: str):
    """Launch ``kernel`` over the ranges ``[bounds[i], bounds[i+1])`` (ascending element indices,
    e.g. of equal work where elements cost unequally), one pool task each on the CPU; one launch
    of them all on CUDA."""
    b = [int(x) for x in bounds]
    ranges = [(lo, hi - lo) for lo, hi in zip(b[:-1], b[1:]) if hi > lo]
    if not ranges:
        return
    ensure_loaded(kernel, device)
    if len(ranges) == 1 or not str(device).startswith("cpu"):
        wp.launch(kernel, dim=b[-1] - b[0], inputs=[b[0], *inputs], device=device)
        return
    _run_ranges(lambda lo, m: wp.launch(kernel, dim=m, inputs=[lo, *inputs], device=device), ranges, cpu_workers())


def launch_rows(kernel, n: int, rows: int, inputs: list, device: str):
    """Launch over ``n`` elements split into exactly ``rows`` contiguous ranges of
    ``ceil(n / rows)`` elements, one thread each (range r owns row r of a per-row output)."""
    n = int(n)
    if n <= 0:
        return
    ensure_loaded(kernel, device)
    if rows == 1 or not str(device).startswith("cpu"):
        wp.launch(kernel, dim=n, inputs=[0, *inputs], device=device)
        return
    step = (n + rows - 1) // rows
    _run_ranges(lambda b, m: wp.launch(kernel, dim=m, inputs=[b, *inputs], device=device),
                [(b, min(step, n - b)) for b in range(0, n, step)], cpu_workers())


@wp.kernel(enable_backward=False)
def _compact_kernel(base: int, flag: wp.array(dtype=int), offset: wp.array(dtype=int), idx: wp.array(dtype=int)):
    k = base + wp.tid()
    if flag[k] != 0:
        idx[offset[k]] = k


def exclusive_scan(values: wp.array) -> tuple[wp.array, int]:
    """``(offset, total)``: the exclusive prefix sum of the int ``values`` (``wp.utils.array_scan``)
    and their sum (offset of one past the last)."""
    offset = wp.empty_like(values)
    n = int(values.shape[0])
    if n == 0:
        return offset, 0
    wp.utils.array_scan(values, offset, inclusive=False)
    if offset.device.is_cpu:  # (views of the arrays' memory: no copies)
        return offset, int(offset.numpy()[n - 1]) + int(values.numpy()[n - 1])
    return offset, int(offset[n - 1: n].numpy()[0] + values[n - 1: n].numpy()[0])


def compact(flag: wp.array, device) -> wp.array:
    """The indices k with ``flag[k]`` ≠ 0 (int 0/1 flags), ascending: :func:`exclusive_scan`, then
    a scatter — stream compaction, so that later kernels run over the few flagged elements instead
    of all of them."""
    offset, total = exclusive_scan(flag)
    idx = wp.empty(total, dtype=int, device=device)
    if total > 0:
        launch(_compact_kernel, int(flag.shape[0]), [flag, offset, idx], device)
    return idx

r"""Connecting to a Dask cluster (:func:`connect`), the version check, and task helpers shared by
:mod:`warp_sg.distributed.rendering` and :mod:`warp_sg.distributed.precompute`.

``cluster`` everywhere: a spec string (``"local"``, ``"local:N"``, a scheduler address
``"tcp://host:8786"``), a ``distributed.Client``, a ``distributed`` cluster object, or ``None``
(= ``"local"``: a :class:`distributed.LocalCluster` of one single-threaded worker process per
usable core). Dask is imported only inside these functions.

* An unreachable scheduler is a :class:`ClusterError` (an :class:`InputError`: one line on the
  command line, exit status 2) after ``timeout`` seconds (:data:`CONNECT_TIMEOUT`,
  ``$WARP_SG_DASK_TIMEOUT``); so is a scheduler without workers.
* A worker whose ``warp_sg.__version__`` differs from the client's is refused at connect
  (:func:`check_versions`, one line naming both versions); tasks carry the client's version and
  check it again (:func:`ensure_version`), so a worker that joins later is refused too.
"""
from __future__ import annotations

import contextlib
import logging
import threading

from warp_sg.core.errors import InputError, reason

#: Seconds to wait for a scheduler (and for its first worker) before giving up
#: (``$WARP_SG_DASK_TIMEOUT`` overrides it).
CONNECT_TIMEOUT = 5.0
#: Retries of every task (a worker killed mid-task counts against the scheduler's own
#: ``allowed-failures``, exceptions against this).
RETRIES = 3


class ClusterError(InputError):
    """The cluster is unusable: unreachable scheduler, no workers, a worker of another version."""


# --------------------------------------------------------------------------------------------
# connecting
# --------------------------------------------------------------------------------------------
def add_cluster_argument(p) -> None:
    """``--cluster local[:N] | tcp://HOST:PORT`` on an argparse parser."""
    p.add_argument("--cluster", default=None, metavar="local:N|tcp://HOST:PORT",
                   help="run the precompute (and batch work) on Dask: 'local:N' starts N worker processes here, "
                        "an address connects to a running scheduler (docs/distributed.md)")


def parse_cluster(spec: str):
    """``("local", n_workers)`` or ``("address", address)``; :class:`ClusterError` otherwise."""
    from warp_sg.core.workers import usable_cores

    s = str(spec).strip()
    if s == "local":
        return "local", usable_cores()
    if s.startswith("local:"):
        n = s.partition(":")[2]
        if not n.isdigit() or int(n) < 1:
            raise ClusterError(f"expected local:N with N >= 1 workers, got {spec!r}", where="--cluster")
        return "local", int(n)
    if "://" in s:
        proto = s.partition("://")[0]
        if proto not in ("tcp", "tls", "ucx", "inproc", "ws", "wss"):
            raise ClusterError(f"unknown scheduler protocol {proto!r} in {spec!r}", where="--cluster")
        host, _, port = s.partition("://")[2].rpartition(":")
        if proto != "inproc" and (not host or not port.isdigit() or not 0 < int(port) < 65536):
            raise ClusterError(f"a scheduler address needs a host and a port, like {proto}://host:8786, got {spec!r}",
                               where="--cluster")
        return "address", s
    host, _, port = s.rpartition(":")
    if host and port.isdigit() and 0 < int(port) < 65536:
        return "address", f"tcp://{s}"
    raise ClusterError(f"expected 'local', 'local:N' or a scheduler address like tcp://host:8786, got {spec!r}",
                       where="--cluster")


def project_version() -> str:
    """The version a worker must run: ``warp_sg.__version__``."""
    import warp_sg

    return str(warp_sg.__version__)


def _worker_version() -> str:
    import warp_sg

    return str(warp_sg.__version__)


def check_versions(client) -> None:
    """Refuse workers whose ``warp_sg.__version__`` differs from this process's (one line, both versions)."""
    mine = project_version()
    try:
        versions = client.run(_worker_version)
    except Exception as e:  # noqa: BLE001 - e.g. warp_sg missing on a worker
        raise ClusterError(f"cannot ask the workers for their warp-sg version ({reason(e)})",
                           where="--cluster") from None
    for worker, v in sorted(versions.items()):
        if v != mine:
            raise ClusterError(f"worker {worker} runs warp-sg {v}, this client runs warp-sg {mine}; "
                               "install the same version on every worker", where="--cluster")


def ensure_version(expected: str) -> None:
    """Inside a task, first thing: raise :class:`ClusterError` if this worker's version is not
    ``expected``; and keep Warp's banner and module-load lines off the worker's terminal, as the
    CLI does (:func:`warp_sg.core.device.quiet_warp`)."""
    from warp_sg.core.device import quiet_warp

    quiet_warp()
    v = _worker_version()
    if v != expected:
        raise ClusterError(f"this worker runs warp-sg {v}, the client runs warp-sg {expected}", where="worker")


def _local_cluster(n_workers: int):
    from distributed import LocalCluster

    # one single-threaded process per worker; Warp's own CPU thread pool is off (WARP_SG_THREADS=1):
    # Dask provides the parallelism, one task per core
    # dashboard_address=":0": a free port (None still binds 8787 and warns when another cluster has it)
    return LocalCluster(n_workers=int(n_workers), threads_per_worker=1, processes=True, dashboard_address=":0",
                        silence_logs=logging.ERROR, env={"WARP_SG_THREADS": "1"})


@contextlib.contextmanager
def connect(cluster=None, timeout: float | None = None):
    """A ``distributed.Client`` for ``cluster`` (see the module docstring), version-checked;
    what this call started (a client, a local cluster) is closed on exit. ``timeout``: seconds
    (default ``$WARP_SG_DASK_TIMEOUT`` or :data:`CONNECT_TIMEOUT`)."""
    import os

    import distributed

    if timeout is None:
        try:
            timeout = float(os.environ.get("WARP_SG_DASK_TIMEOUT") or CONNECT_TIMEOUT)
        except ValueError:
            raise ClusterError(f"not a number of seconds: {os.environ['WARP_SG_DASK_TIMEOUT']!r}",
                               where="WARP_SG_DASK_TIMEOUT") from None

    if isinstance(cluster, distributed.Client):
        check_versions(cluster)
        yield cluster
        return
    owned = None
    if cluster is None or isinstance(cluster, str):
        kind, value = parse_cluster("local" if cluster is None else cluster)
        if kind == "local":
            owned = _local_cluster(value)
            target = owned
        else:
            target = value
    elif hasattr(cluster, "scheduler_address"):
        target = cluster
    else:
        raise ClusterError(f"expected a cluster spec, a distributed.Client or a cluster object, got {cluster!r}",
                           where="cluster")
    try:
        try:
            client = distributed.Client(target, timeout=timeout)
        except (OSError, TimeoutError) as e:
            raise ClusterError(f"cannot reach the Dask scheduler at {target} within {timeout:g} s "
                               f"({reason(e)})", where="--cluster") from None
        try:
            try:
                client.wait_for_workers(1, timeout=timeout)
            except (OSError, TimeoutError):
                raise ClusterError(f"the Dask scheduler at {client.scheduler.address} has no workers "
                                   f"(waited {timeout:g} s)", where="--cluster") from None
            check_versions(client)
            yield client
        finally:
            client.close()
    finally:
        if owned is not None:
            owned.close()


def gather_in_order(futures, progress=None, on_result=None):
    """Results of ``futures`` in submission order, collected as they finish (``as_completed``);
    ``on_result(index, result)`` runs on the client as each arrives; ``progress``: a tqdm bar
    ticked once per future. A task that failed for good (a worker killed too often, an error on
    every retry) raises here; a ``KilledWorker`` becomes a :class:`ClusterError`."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    index = {f.key: i for i, f in enumerate(futures)}
    out = [None] * len(futures)
    try:
        for fut in as_completed(futures):
            i = index[fut.key]
            out[i] = fut.result()
            fut.release()
            if on_result is not None:
                on_result(i, out[i])
            if progress is not None:
                progress.update(1)
    except KilledWorker as e:
        raise ClusterError(f"a task killed its worker too often, giving up ({e})", where="cluster") from None
    finally:
        for f in futures:
            f.cancel()
    return out


# --------------------------------------------------------------------------------------------
# worker-local pools (one per worker process; tasks of the same job reuse what they built)
# --------------------------------------------------------------------------------------------
_POOL_LOCK = threading.Lock()
_POOLS: dict = {}  # token -> list of free objects
_POOL_TOKENS: list = []  # least recently created last; at most _POOL_KEEP jobs kept


_POOL_KEEP = 2


@contextlib.contextmanager
def worker_object(token: str, build):
    """An object built by ``build()`` once per job ``token`` and worker thread, reused by the
    job's later tasks on this worker (a free list, so concurrent tasks never share one)."""
    with _POOL_LOCK:
        free = _POOLS.get(token)
        obj = free.pop() if free else None
    if obj is None:
        obj = build()
    try:
        yield obj
    finally:
        with _POOL_LOCK:
            if token not in _POOLS:
                _POOLS[token] = []
                _POOL_TOKENS.append(token)
                while len(_POOL_TOKENS) > _POOL_KEEP:
                    _POOLS.pop(_POOL_TOKENS.pop(0), None)
            _POOLS[token].append(obj)


__all__ = ["ClusterError", "CONNECT_TIMEOUT", "RETRIES", "add_cluster_argument", "parse_cluster", "connect",
           "check_versions", "ensure_version", "project_version", "gather_in_order", "worker_object"]

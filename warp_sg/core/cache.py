"""On-disk precompute cache (docs/precompute.md "Cache", docs/architecture.md "Precompute contract").

Base layer: generic (arrays in, arrays out), used by the precompute engines and by the measured-BRDF
fit; the precompute facade names it ``precompute.cache``.


* :func:`cache_dir` — ``$WARP_SG_CACHE_DIR`` or ``~/.cache/warp-sg``; deleting it is always safe.
* :func:`fresh_cache` — a private empty cache folder for a ``with`` block (timings of precompute).
* :func:`content_key` — a stable SHA-256 over numpy arrays (dtype, shape and bytes) and JSON-able
  parameters, plus :data:`FORMAT_VERSION` (bump it whenever the file format itself changes).
* :func:`code_key` — a hash of the source of the modules that produce an entry; every producer
  puts it in its ``content_key`` parts, so an algorithm change misses the old entries by itself
  (no hand-kept version numbers).
* :func:`load_or_build` — ``kind/key.npz`` files holding ``dict[str, np.ndarray]``. Files are
  written atomically (a temporary file in the same folder, flushed and fsync-ed, then
  ``os.replace``) and carry the fingerprint of their inputs (``__key__``: the kind and the
  :func:`content_key` they were built for) and a SHA-256 checksum of their own contents
  (``__checksum__``). An entry that is truncated, corrupt, of other inputs (a valid entry of
  another scene copied under this key), or not a file at all (a folder in its place) is never
  trusted: it is removed, one warning is issued, and the entry is rebuilt (when it cannot be
  removed, the build is used without caching, still with one warning). Entries are read through
  a file the reader closes, whatever the failure (no handle left open).
* :func:`cached_table` — a constant table that depends on no input, only on the code computing it
  (the SG irradiance and ``fh`` tables): kind ``tables``, keyed by that code's :func:`code_key`,
  so a cold start on a new asset reads it instead of recomputing it.
* :func:`record_builds` — a :class:`BuildLedger` of the builds and hits of a ``with`` block, with
  the wall and CPU seconds of every build: what an entry found in the cache would have cost
  (``warp-sg report`` reuses entries across its settings and still reports fresh-cache times).
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import json
import os
import sys
import tempfile
import threading
import time
import tokenize
import warnings
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from warp_sg.core.errors import CacheError
from warp_sg.core.files import atomic_output

#: Bump whenever the layout or meaning of any cached entry changes (old entries then miss).
#: 2: entries record their key (``__key__``)
FORMAT_VERSION = 2

_CHECKSUM = "__checksum__"
_KEY = "__key__"
#: entry paths that could not be cleared this process (a folder in the way): built, not written
_BLOCKED: set = set()


def cache_dir() -> Path:
    """The cache folder: ``$WARP_SG_CACHE_DIR`` if set (and non-empty), else ``~/.cache/warp-sg``."""
    env = os.environ.get("WARP_SG_CACHE_DIR")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "warp-sg"


@contextlib.contextmanager
def fresh_cache():
    """A private, empty cache folder for the duration (so precompute is really measured): sets
    ``$WARP_SG_CACHE_DIR`` to a temporary folder, restores it and deletes the folder afterwards."""
    old = os.environ.get("WARP_SG_CACHE_DIR")
    with tempfile.TemporaryDirectory(prefix="warp-sg-report-") as d:
        os.environ["WARP_SG_CACHE_DIR"] = d
        try:
            yield Path(d)
        finally:
            if old is None:
                os.environ.pop("WARP_SG_CACHE_DIR", None)
            else:
                os.environ["WARP_SG_CACHE_DIR"] = old


def _update(h, part) -> None:
    if isinstance(part, np.ndarray) or (hasattr(part, "__array__") and not isinstance(part, (str, bytes))):
        a = np.ascontiguousarray(np.asarray(part))
        h.update(b"A")
        h.update(str(a.dtype.str).encode())
        h.update(json.dumps(list(a.shape)).encode())
        h.update(_raw_bytes(a))
    elif isinstance(part, bytes):
        h.update(b"B")
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    else:
        try:
            s = json.dumps(part, sort_keys=True, separators=(",", ":"), default=_json_default)
        except TypeError as e:  # pragma: no cover - message clarity only
            raise TypeError(f"content_key: cannot hash {type(part).__name__}: {e}") from None
        h.update(b"J")
        h.update(len(s).to_bytes(8, "little"))
        h.update(s.encode())


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-able: {type(o).__name__}")


def content_key(*parts) -> str:
    """Stable hex key of ``parts`` (numpy arrays: dtype + shape + bytes; others: canonical JSON).

    The same inputs give the same key across processes and machines; any change of array
    contents, dtype, shape, parameter value or :data:`FORMAT_VERSION` changes the key.
    """
    h = hashlib.sha256()
    h.update(f"warp-sg-cache-v{FORMAT_VERSION}".encode())
    for p in parts:
        _update(h, p)
    return h.hexdigest()[:40]


#: tokens that are layout only
_LAYOUT_TOKENS = frozenset({tokenize.COMMENT, tokenize.NL, tokenize.ENCODING})


@functools.lru_cache(maxsize=256)
def _source_digest(path: str, mtime_ns: int, size: int) -> str:
    """SHA-256 of a Python file's tokens: comments, blank lines, line breaks inside brackets and
    spacing don't count (``tokenize``, not ``ast.parse``: CPython 3.11.7's parser can raise
    ``SystemError: AST constructor recursion depth mismatch`` when called from deep stacks)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for tok in tokenize.tokenize(f.readline):
            if tok.type not in _LAYOUT_TOKENS:
                h.update(f"{tok.type}:{tok.string}\0".encode())
    return h.hexdigest()


def _source_file(producer) -> Path:
    """The source file of a module, a dotted module name, or a function, class or Warp kernel/func
    (the module it is defined in)."""
    if isinstance(producer, str):
        mod = sys.modules.get(producer)
        origin = getattr(mod, "__file__", None) if mod is not None else None
        if origin is None:
            spec = importlib.util.find_spec(producer)
            origin = spec.origin if spec is not None else None
    elif hasattr(producer, "__file__") and not callable(producer):  # a module
        origin = producer.__file__
    else:
        fn = getattr(producer, "func", producer)  # wp.Kernel / wp.Function wrap a Python function
        origin = getattr(sys.modules.get(getattr(fn, "__module__", None) or ""), "__file__", None)
    if not origin or not str(origin).endswith(".py"):
        raise ValueError(f"code_key: no Python source for {producer!r}")
    return Path(origin)


def code_key(*producers) -> str:
    """Hex hash of the code that produces a cache entry: the tokens of the source files of
    ``producers`` (modules, dotted module names, or functions / classes / Warp kernels, which stand
    for the module that defines them), in order.

    A producer passes ``code_key(__name__, helper, ...)`` as one of its :func:`content_key` parts:
    any change of that code (not of its comments or layout) changes the key, so the old entries
    miss and are rebuilt. The tokens are hashed once per file version (path, mtime, size)."""
    h = hashlib.sha256(b"warp-sg-code")
    for p in producers:
        path = _source_file(p)
        st = path.stat()
        h.update(_source_digest(str(path), st.st_mtime_ns, st.st_size).encode())
    return h.hexdigest()[:16]


def _raw_bytes(a: np.ndarray):
    """The bytes of the C-contiguous array ``a`` (``a.tobytes()``), without a copy where numpy's
    buffer allows one."""
    try:
        return memoryview(a.reshape(-1)).cast("B")
    except (TypeError, ValueError):  # (object arrays, non-native formats)
        return a.tobytes()


def _checksum(arrays: Mapping[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode() + b"\0")
        h.update(a.dtype.str.encode() + b"\0")
        h.update(json.dumps(list(a.shape)).encode())
        h.update(_raw_bytes(a))
    return h.hexdigest()


def entry_path(kind: str, key: str) -> Path:
    """Where ``load_or_build(kind, key, ...)`` stores its file."""
    if not kind or any(c in kind for c in "/\\") or kind.startswith("."):
        raise ValueError(f"cache kind must be a plain folder name, got {kind!r}")
    return cache_dir() / kind / f"{key}.npz"


def _read(path: Path, fingerprint: str | None = None) -> dict[str, np.ndarray]:
    """Read and verify an entry; :class:`CacheError` if it cannot be trusted (unreadable, not a
    file, checksum mismatch, or built for other inputs than ``fingerprint``)."""
    if not path.is_file():
        raise CacheError(f"{path}: not a cache entry (a folder or another non-file is in its place)")
    try:
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as e:  # noqa: BLE001 - OSError, BadZipFile, zlib and struct errors ... anything means corrupt
        raise CacheError(f"{path}: unreadable cache entry ({str(e) or 'truncated'})") from None
    stored = data.pop(_CHECKSUM, None)
    if stored is None:
        raise CacheError(f"{path}: cache entry has no checksum")
    if str(stored) != _checksum(data):
        raise CacheError(f"{path}: cache entry checksum mismatch")
    key = data.pop(_KEY, None)
    if fingerprint is not None and (key is None or str(key) != fingerprint):
        raise CacheError(f"{path}: the entry was built for other inputs ({str(key)[:60] if key is not None else 'none'}"
                         f"), not these")
    return data


def _write_atomic(path: Path, arrays: Mapping[str, np.ndarray], fingerprint: str | None = None) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {k: np.asarray(v) for k, v in arrays.items()}
    if fingerprint is not None:
        payload[_KEY] = np.asarray(fingerprint)
    payload[_CHECKSUM] = np.asarray(_checksum(payload))
    with atomic_output(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **payload)
        f.flush()
        os.fsync(f.fileno())


def _fingerprint(kind: str, key: str) -> str:
    return f"{kind}/{key}"


def _clear(path: Path) -> bool:
    """Remove an untrusted entry (a file, or a folder in its place); False when it stays."""
    import shutil

    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    except FileNotFoundError:
        pass
    except OSError:
        return False
    return True


def load(kind: str, key: str) -> dict[str, np.ndarray] | None:
    """The verified entry, or ``None`` when missing or untrusted (removed, with one warning)."""
    path = entry_path(kind, key)
    if not (path.exists() or path.is_symlink()):
        return None
    try:
        return _read(path, _fingerprint(kind, key))
    except CacheError as e:
        if _clear(path):
            warnings.warn(f"warp-sg cache: {e}; rebuilding", RuntimeWarning, stacklevel=3)
        else:
            _BLOCKED.add(path)
            warnings.warn(f"warp-sg cache: {e}, and it cannot be removed; rebuilding without caching it",
                          RuntimeWarning, stacklevel=3)
        return None


def load_or_build(
    kind: str,
    key: str,
    builder: Callable[[], Mapping[str, np.ndarray]],
    progress: bool = False,
) -> dict[str, np.ndarray]:
    """Return the cached ``dict[str, np.ndarray]`` for ``(kind, key)``, building it on a miss.

    ``builder()`` must return a mapping of names (not starting with ``__``) to arrays. The entry
    is stored atomically; if ``builder`` raises (or the process is interrupted) nothing is left
    in the cache. A corrupt/truncated entry is detected by its checksum, reported with a
    ``RuntimeWarning`` and rebuilt. ``progress`` prints a one-line note on a miss.
    """
    data = load(kind, key)
    if data is not None:
        note_hit(kind, key)
        return data
    if progress:
        print(f"warp-sg: building {kind} (cache miss {key[:12]})", flush=True)
    w0, c0 = time.perf_counter(), time.process_time()
    built = builder()
    note_build(kind, key, time.perf_counter() - w0, time.process_time() - c0)
    arrays = {}
    for k, v in dict(built).items():
        if k.startswith("__"):
            raise ValueError(f"cache entry names must not start with '__': {k!r}")
        arrays[k] = np.asarray(v)
    path = entry_path(kind, key)
    if path in _BLOCKED:  # (said when it was read)
        return arrays
    for folder in (path.parent.parent, path.parent):  # a file where the cache's folders go: not ours to keep
        if (folder.exists() or folder.is_symlink()) and not folder.is_dir() and _clear(folder):
            warnings.warn(f"warp-sg cache: {folder} was a file, not a cache folder; replaced by one",
                          RuntimeWarning, stacklevel=2)
    try:
        _write_atomic(path, arrays, _fingerprint(kind, key))
    except OSError as e:  # read-only cache folder etc.: still return the result
        warnings.warn(f"warp-sg cache: cannot write {path} ({e.strerror or e})", RuntimeWarning, stacklevel=2)
    return arrays


def cached_table(name: str, producers: tuple, build: Callable[[], np.ndarray], **params) -> np.ndarray:
    """The array ``build()`` returns, cached as entry ``tables/<key>`` with ``key`` the
    :func:`content_key` of ``name``, the :func:`code_key` of ``producers`` (the modules whose code
    computes it) and ``params``: for tables that depend on no input (every cold start of every
    scene would compute them again), e.g. :func:`warp_sg.sg.irradiance.irradiance_table`. A change
    of that code changes the key, so an old table is never served."""
    key = content_key("table", str(name), code_key(*producers), params)
    return load_or_build("tables", key, lambda: {"table": np.asarray(build())})["table"]


# --------------------------------------------------------------------------------------------
# build ledger
# --------------------------------------------------------------------------------------------
_LEDGERS: list = []


class BuildLedger:
    """Builds and hits of :func:`load_or_build` (and of callers that report their own, e.g. an
    in-memory memo: :meth:`built` / :meth:`hit` with their own ``kind``) while it is recording.

    ``fresh[(kind, key)] = (wall s, CPU s)`` of the entry's build (nested builds included);
    ``events``: ``(kind, key, built)`` in order. :meth:`mark` / :meth:`hit_cost` give what the
    hits since a mark would have cost to build (the entries must have been built while recording)."""

    def __init__(self):
        self.fresh: dict = {}
        self.events: list = []
        self._lock = threading.Lock()

    def built(self, kind: str, key: str, wall: float, cpu: float) -> None:
        with self._lock:
            self.fresh[(kind, key)] = (float(wall), float(cpu))
            self.events.append((kind, key, True))

    def hit(self, kind: str, key: str) -> None:
        with self._lock:
            self.events.append((kind, key, False))

    def mark(self) -> int:
        return len(self.events)

    def hit_cost(self, since: int = 0) -> tuple[float, float]:
        """(wall, CPU) seconds the entries hit since ``since`` (a :meth:`mark`) took to build."""
        w = c = 0.0
        with self._lock:
            for kind, key, built in self.events[since:]:
                if not built:
                    fw, fc = self.fresh.get((kind, key), (0.0, 0.0))
                    w += fw
                    c += fc
        return w, c


def note_build(kind: str, key: str, wall: float, cpu: float) -> None:
    """Enter a build (of the cache or of a caller's own memo) in every recording ledger."""
    for ledger in list(_LEDGERS):
        ledger.built(kind, key, wall, cpu)


def note_hit(kind: str, key: str) -> None:
    """Enter a reuse in every recording ledger."""
    for ledger in list(_LEDGERS):
        ledger.hit(kind, key)


@contextlib.contextmanager
def record_builds():
    """Record :func:`load_or_build`'s builds and hits in a :class:`BuildLedger` for the duration."""
    ledger = BuildLedger()
    _LEDGERS.append(ledger)
    try:
        yield ledger
    finally:
        _LEDGERS.remove(ledger)

"""warp_sg.cache (re-exported as precompute.cache): keys, hits/misses, corruption detection, atomic writes."""
from __future__ import annotations

import os

import numpy as np
import pytest

from warp_sg import cache


def _builder(counter, value=1.0):
    def build():
        counter.append(1)
        return {"a": np.full((3, 4), value, np.float32), "b": np.arange(5)}

    return build


def test_cache_dir_follows_environment(cache_dir):
    assert cache.cache_dir() == cache_dir


def test_cache_dir_defaults_to_home_cache(monkeypatch):
    monkeypatch.delenv("WARP_SG_CACHE_DIR", raising=False)
    assert str(cache.cache_dir()).endswith(os.path.join(".cache", "warp-sg"))


def test_content_key_is_stable_and_sensitive():
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    k = cache.content_key(a, {"r": 32, "n": 8})
    assert k == cache.content_key(a.copy(), {"n": 8, "r": 32})  # dict order does not matter
    assert k != cache.content_key(a.astype(np.float64), {"r": 32, "n": 8})  # dtype
    assert k != cache.content_key(a.reshape(4, 3), {"r": 32, "n": 8})  # shape
    b = a.copy()
    b[1, 2] += 1e-6
    assert k != cache.content_key(b, {"r": 32, "n": 8})  # bytes
    assert k != cache.content_key(a, {"r": 33, "n": 8})  # params


def test_miss_builds_then_hit_loads(cache_dir):
    calls = []
    d1 = cache.load_or_build("unit", "k1", _builder(calls))
    d2 = cache.load_or_build("unit", "k1", _builder(calls))
    assert len(calls) == 1
    np.testing.assert_array_equal(d1["a"], d2["a"])
    assert d2["a"].dtype == np.float32 and d2["b"].tolist() == [0, 1, 2, 3, 4]
    assert "__checksum__" not in d2


@pytest.mark.parametrize("damage", ["truncate", "garbage", "flip_byte"])
def test_corrupt_entry_is_rebuilt_not_trusted(cache_dir, damage):
    calls = []
    cache.load_or_build("unit", "k2", _builder(calls, 2.0))
    path = cache.entry_path("unit", "k2")
    raw = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(raw[: len(raw) // 2])
    elif damage == "garbage":
        path.write_bytes(b"\x00garbage" * 50)
    else:  # a flipped byte inside the stored array data (zip CRC or our checksum catches it)
        i = raw.find(np.full((3, 4), 2.0, np.float32).tobytes())
        assert i > 0
        raw = bytearray(raw)
        raw[i + 5] ^= 0xFF
        path.write_bytes(bytes(raw))
    with pytest.warns(RuntimeWarning, match="rebuilding"):
        d = cache.load_or_build("unit", "k2", _builder(calls, 2.0))
    assert len(calls) == 2
    np.testing.assert_array_equal(d["a"], np.full((3, 4), 2.0, np.float32))
    # the rebuilt file is sound again
    d = cache.load_or_build("unit", "k2", _builder(calls, 2.0))
    assert len(calls) == 2


def test_checksum_mismatch_is_detected(cache_dir):
    """A well-formed npz whose arrays do not match its stored checksum is not trusted."""
    cache.load_or_build("unit", "k3", _builder([], 3.0))
    path = cache.entry_path("unit", "k3")
    with np.load(path) as z:
        payload = {k: z[k] for k in z.files}
    payload["a"] = payload["a"] + 1
    with open(path, "wb") as f:
        np.savez(f, **payload)
    with pytest.warns(RuntimeWarning, match="checksum"):
        assert cache.load("unit", "k3") is None
    assert not path.exists()


def test_write_leaves_no_temporary_files(cache_dir):
    cache.load_or_build("unit", "k4", _builder([]))
    files = sorted(p.name for p in (cache_dir / "unit").iterdir())
    assert files == ["k4.npz"]


def test_interrupted_builder_leaves_nothing(cache_dir):
    def boom():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        cache.load_or_build("unit", "k5", boom)
    folder = cache_dir / "unit"
    assert not folder.exists() or list(folder.iterdir()) == []


def test_interrupted_write_leaves_nothing(cache_dir, monkeypatch):
    def failing_replace(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(cache.os, "replace", failing_replace)
    with pytest.raises(KeyboardInterrupt):
        cache.load_or_build("unit", "k6", _builder([]))
    assert list((cache_dir / "unit").iterdir()) == []

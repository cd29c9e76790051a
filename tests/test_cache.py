"""warp_sg.core.cache (re-exported as warp_sg.core.cache): keys, hits/misses, corruption detection, atomic writes."""
from __future__ import annotations

import os

import numpy as np
import pytest

from warp_sg.core import cache


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


def _write_module(folder, name, body):
    path = folder / f"{name}.py"
    path.write_text(body, encoding="utf-8")
    os.utime(path, ns=(os.stat(path).st_atime_ns, os.stat(path).st_mtime_ns + 1_000_000))  # a new file version
    return path


def test_code_key_changes_with_the_producing_code(tmp_path, monkeypatch):
    import importlib
    import sys

    monkeypatch.syspath_prepend(str(tmp_path))
    _write_module(tmp_path, "wsg_producer_probe", "def build(x):\n    return x * 2\n")
    mod = importlib.import_module("wsg_producer_probe")
    try:
        k0 = cache.code_key(mod)
        assert cache.code_key("wsg_producer_probe") == k0 == cache.code_key(mod.build)
        # comments and layout are not code: same key
        _write_module(tmp_path, "wsg_producer_probe", "# a note\ndef build(x):\n\n    return x  *  2  # twice\n")
        assert cache.code_key(mod) == k0
        # a changed algorithm is: a new key, and so a new content_key for the same inputs
        _write_module(tmp_path, "wsg_producer_probe", "def build(x):\n    return x * 3\n")
        k1 = cache.code_key(mod)
        assert k1 != k0
        assert cache.content_key(np.ones(3), {"v": k1}) != cache.content_key(np.ones(3), {"v": k0})
    finally:
        sys.modules.pop("wsg_producer_probe", None)


def test_code_key_covers_every_producer_in_order(tmp_path, monkeypatch):
    import importlib
    import sys

    monkeypatch.syspath_prepend(str(tmp_path))
    _write_module(tmp_path, "wsg_probe_a", "A = 1\n")
    _write_module(tmp_path, "wsg_probe_b", "B = 1\n")
    a, b = importlib.import_module("wsg_probe_a"), importlib.import_module("wsg_probe_b")
    try:
        kab = cache.code_key(a, b)
        assert kab != cache.code_key(a) and kab != cache.code_key(b, a)
        _write_module(tmp_path, "wsg_probe_b", "B = 2\n")  # a change in a helper module counts too
        assert cache.code_key(a, b) != kab
    finally:
        sys.modules.pop("wsg_probe_a", None)
        sys.modules.pop("wsg_probe_b", None)


def test_code_key_refuses_code_without_source():
    with pytest.raises(ValueError, match="no Python source"):
        cache.code_key(len)


def test_cached_producers_key_on_a_code_hash_not_a_version_number():
    """Every producer of a cache kind keys on :func:`cache.code_key` of its own module (a hand-kept
    version would be a small int or a literal string)."""
    import precompute.environment.irradiance as ei
    import precompute.environment.prefilter as pf
    import precompute.environment.sg_fit as es
    import precompute.visibility.refine as rf
    import precompute.visibility.ssdf as ss
    from warp_sg.brdf.fitting import measured_fit as mf

    keys = {pf: pf._VERSION, ei: ei._VERSION, es: es._VERSION, rf: rf._VERSION, ss: ss.SSDF_VERSION,
            mf: mf.FIT_VERSION}
    for mod, key in keys.items():
        assert isinstance(key, str) and len(key) == 16 and int(key, 16) >= 0, mod.__name__
    assert len(set(keys.values())) == len(keys)


# ------------------------------------------------------------------------------------------------
# entries that know what they hold (issue 51)
# ------------------------------------------------------------------------------------------------
def _warnings_of(fn):
    import warnings

    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        out = fn()
    return out, [str(w.message) for w in rec]


def test_a_valid_entry_of_other_inputs_under_this_key_is_rebuilt_with_one_warning(cache_dir):
    # before: another scene's entry copied under this key was used without a word (wrong shadows)
    cache.load_or_build("unit", "mine", _builder([], 1.0))
    cache.load_or_build("unit", "theirs", _builder([], 7.0))
    cache.entry_path("unit", "theirs").replace(cache.entry_path("unit", "mine"))
    calls = []
    d, msgs = _warnings_of(lambda: cache.load_or_build("unit", "mine", _builder(calls, 1.0)))
    assert len(calls) == 1 and (d["a"] == 1.0).all()
    assert len(msgs) == 1 and "built for other inputs" in msgs[0] and "unit/theirs" in msgs[0]
    again, msgs = _warnings_of(lambda: cache.load_or_build("unit", "mine", _builder(calls, 1.0)))
    assert len(calls) == 1 and msgs == [] and (again["a"] == 1.0).all()


def test_a_folder_in_place_of_an_entry_is_replaced_by_the_rebuilt_entry(cache_dir):
    # before: every later render of the scene failed (IsADirectoryError when removing it)
    path = cache.entry_path("unit", "dir")
    (path / "inside").mkdir(parents=True)
    calls = []
    d, msgs = _warnings_of(lambda: cache.load_or_build("unit", "dir", _builder(calls)))
    assert len(calls) == 1 and len(msgs) == 1 and "not a cache entry" in msgs[0]
    assert path.is_file()
    _, msgs = _warnings_of(lambda: cache.load_or_build("unit", "dir", _builder(calls)))
    assert len(calls) == 1 and msgs == []


def test_an_entry_that_cannot_be_cleared_is_built_with_one_warning(cache_dir, monkeypatch):
    path = cache.entry_path("unit", "stuck")
    path.mkdir(parents=True)
    monkeypatch.setattr(cache, "_clear", lambda p: False)  # (a folder the process may not remove)
    monkeypatch.setattr(cache, "_BLOCKED", set())
    calls = []
    d, msgs = _warnings_of(lambda: cache.load_or_build("unit", "stuck", _builder(calls)))
    assert len(calls) == 1 and (d["a"] == 1.0).all()
    assert len(msgs) == 1 and "cannot be removed" in msgs[0]


@pytest.mark.parametrize("damage", ["truncate", "empty"])
def test_a_damaged_entry_is_one_warning_and_no_open_file_left(cache_dir, damage):
    # before: a truncated entry left its file open (a ResourceWarning: a second warning line)
    import gc

    cache.load_or_build("unit", "t", _builder([]))
    path = cache.entry_path("unit", "t")
    path.write_bytes(path.read_bytes()[:40] if damage == "truncate" else b"")

    def run():
        out = cache.load_or_build("unit", "t", _builder([]))
        gc.collect()  # an unclosed file warns when it is collected
        return out

    _, msgs = _warnings_of(run)
    assert len(msgs) == 1 and "rebuilding" in msgs[0], msgs
    assert "Error" not in msgs[0]

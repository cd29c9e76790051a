"""Shared test fixtures.

Warp compiles each kernel module once per process (and caches the binaries on disk), so tests
share modules instead of defining kernels per test. Every device test runs on the CPU and, when
a CUDA device is present, on CUDA too (``device`` fixture).
"""
from __future__ import annotations

import os
import tempfile

import pytest

# Tests never touch the user's cache.
os.environ.setdefault("WARP_SG_CACHE_DIR", tempfile.mkdtemp(prefix="warp-sg-test-cache-"))
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

from warp_sg.device import cuda_available  # noqa: E402

DEVICES = ["cpu"] + (["cuda:0"] if cuda_available() else [])


@pytest.fixture(params=DEVICES)
def device(request):
    """Each device test runs on the CPU and, when present, on CUDA."""
    return request.param


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    """A fresh, private precompute cache folder."""
    d = tmp_path / "cache"
    monkeypatch.setenv("WARP_SG_CACHE_DIR", str(d))
    return d

"""Shared test fixtures.

Warp compiles each kernel module once per process (and caches the binaries on disk), so tests
share modules instead of defining kernels per test. Every device test runs on the CPU and, when
a CUDA device is present, on CUDA too (``device`` fixture).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest

# Tests never touch the user's cache.
os.environ.setdefault("WARP_SG_CACHE_DIR", tempfile.mkdtemp(prefix="warp-sg-test-cache-"))
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

from warp_sg.core.device import cuda_available

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


class Unprivileged:
    """Runs Python code where file permissions apply, also when the tests run as root (as CI does;
    root writes into read-only folders). ``dir``: a fresh folder every user can enter (``tmp_path``
    is private to the test user). ``run(setup, body)``: a fresh interpreter runs ``setup`` as the
    test user — imports: the interpreter and the packages may sit where an unprivileged user cannot
    read — then, when it is root, drops to the user 'nobody' and runs ``body``."""

    def __init__(self, folder: Path):
        self.dir = folder

    def run(self, setup: str, body: str, timeout: float = 300) -> subprocess.CompletedProcess:
        drop = ""
        if os.geteuid() == 0:
            import pwd

            try:
                pw = pwd.getpwnam("nobody")
            except KeyError:
                pytest.skip("running as root and there is no user 'nobody' to drop to")
            drop = textwrap.dedent(f"""
                try:
                    os.setgroups([])
                    os.setgid({pw.pw_gid})
                    os.setuid({pw.pw_uid})
                except PermissionError as e:
                    print("cannot drop privileges:", e, file=sys.stderr)
                    sys.exit(77)
                """)
        code = "\n".join(["import os, sys", textwrap.dedent(setup), drop,
                          "assert os.geteuid() != 0, 'still root'", textwrap.dedent(body)])
        r = subprocess.run([sys.executable, "-c", code], cwd=self.dir, capture_output=True, text=True,
                           timeout=timeout)
        if r.returncode == 77 and "cannot drop privileges" in r.stderr:
            pytest.skip(f"running as root without the right to change user ({r.stderr.strip()})")
        return r


@pytest.fixture
def unprivileged():
    """:class:`Unprivileged` with a fresh world-accessible folder (removed afterwards)."""
    if os.name != "posix":
        pytest.skip("POSIX permissions")
    d = Path(tempfile.mkdtemp(prefix="warp-sg-unprivileged-"))
    d.chmod(0o755)
    try:
        yield Unprivileged(d)
    finally:
        for sub in d.rglob("*"):
            if sub.is_dir():
                sub.chmod(0o755)
        shutil.rmtree(d, ignore_errors=True)

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


#: The scene file the scene-file tests start from (``tests/test_scene.py``, ``test_scene_schema.py``,
#: ``test_bad_input.py``, ``test_hostile_inputs.py``, ``test_input_properties.py``): a Cook–Torrance
#: copper ball on a Lambert floor under a point light, 16×12 pixels, no shadows. A test changes it with
#: :func:`replace_once` and writes it with :func:`write_scene`; the tests rely on its exact lines.
BALL_ON_FLOOR = """
[camera]
origin = [0.0, 1.0, 4.0]
target = [0.0, 0.5, 0.0]
fov = 40.0
width = 16
height = 12

[[objects]]
primitive = "sphere"
center = [0.0, 0.5, 0.0]
radius = 0.5
resolution = [8, 16]
material = "copper"

[[objects]]
primitive = "plane"
size = [4.0, 4.0]
resolution = [2, 2]
material = "floor"

[materials.copper]
model = "cook_torrance"
kd = [0.0, 0.0, 0.0]
ks = [1.0, 1.0, 1.0]
m = 0.2
fresnel = "copper"

[materials.floor]
model = "lambert"
kd = [0.8, 0.8, 0.8]

[[lights]]
type = "point"
position = [2.0, 3.0, 2.0]
radius = 0.1
intensity = [20.0, 20.0, 20.0]

[render]
shadows = false
"""


#: A Lambert sphere under a point light, 8×6 pixels, no shadows: the fewest kernel modules a frame
#: loads (``tests/test_quiet_cpu.py``, ``test_first_run.py``).
LIT_SPHERE = """
[camera]
origin = [0.0, 1.0, 3.0]
target = [0.0, 0.3, 0.0]
fov = 40.0
width = 8
height = 6

[[objects]]
primitive = "sphere"
center = [0.0, 0.4, 0.0]
radius = 0.4
material = "m"

[materials.m]
model = "lambert"
kd = [0.6, 0.6, 0.6]

[[lights]]
type = "point"
position = [1.0, 2.0, 1.0]
radius = 0.1
intensity = [5.0, 5.0, 5.0]

[render]
shadows = false
"""


def replace_once(old: str, new: str, text: str = BALL_ON_FLOOR) -> str:
    """``text`` (the shared scene by default) with its first ``old`` replaced by ``new`` (``old`` must be there)."""
    assert old in text, old
    return text.replace(old, new, 1)


def write_scene(folder: Path, text: str = BALL_ON_FLOOR, name: str = "scene.toml") -> Path:
    """``text`` written as ``folder/name``; its path."""
    p = Path(folder) / name
    p.write_text(text)
    return p


def run_cli(argv, capsys):
    """(exit status, stdout, stderr) of ``warp-sg argv`` run in this process."""
    from warp_sg.tools.cli import main

    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:  # argparse usage errors
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


def assert_clean_failure(rc, err, *needles):
    """A refusal: exit status 2, no traceback, a last stderr line under 400 characters, every needle
    (case-insensitive) in stderr. Returns that line."""
    assert rc == 2, f"exit status {rc}, stderr: {err!r}"
    assert "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert lines, "no message on stderr"
    msg = lines[-1]
    for n in needles:
        assert n.lower() in err.lower(), f"{n!r} not in {err!r}"
    assert len(msg) < 400
    return msg


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

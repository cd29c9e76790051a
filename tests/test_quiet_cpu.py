"""A successful CPU run prints nothing on stderr but progress bars and our own warnings: no line
from Warp's native library (its CUDA-driver warning on a machine without a GPU), whether the CPU
is asked for or chosen by ``auto``; a CUDA device asked for where there is none is one error line.

Each case is a fresh ``python -m warp_sg.tools.cli`` process (Warp initialises once per process,
and the warning is written by native code straight to file descriptor 2)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import LIT_SPHERE


def _cli(tmp_path, *argv):
    scene = tmp_path / "scene.toml"
    scene.write_text(LIT_SPHERE)
    return subprocess.run([sys.executable, "-m", "warp_sg.tools.cli", "render", str(scene), "-o",
                           str(tmp_path / "o.png"), "--no-progress", *argv],
                          capture_output=True, text=True, timeout=300)


def _has_cuda() -> bool:
    from warp_sg.core.device import cuda_available

    return cuda_available()


@pytest.mark.parametrize("device", ["cpu", "auto"])
def test_successful_cpu_render_leaves_stderr_empty(tmp_path, device):
    if device == "auto" and _has_cuda():
        pytest.skip("auto picks the GPU on this machine (the cpu case still runs)")
    r = _cli(tmp_path, "--device", device)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "o.png").is_file()
    assert r.stderr == "", r.stderr


def test_cuda_asked_for_without_a_gpu_is_one_error_line(tmp_path):
    if _has_cuda():
        pytest.skip("this machine has CUDA")
    r = _cli(tmp_path, "--device", "cuda")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warp-sg: error:") and "cuda" in lines[0].lower(), r.stderr
    assert not (tmp_path / "o.png").exists()


def test_an_unreadable_asset_is_one_error_line_and_leaves_no_half_built_module(tmp_path):
    """The CLI starts compiling the frames' modules while it reads an asset (kernel_preload): an
    asset that fails to load exits at once with one line, and the compiles under way finish first
    (no ``*_p<pid>_t<thread>`` build folder left in Warp's kernel cache, no line from Warp)."""
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"garbage")
    kernels = tmp_path / "kernels"
    env = {**os.environ, "WARP_CACHE_PATH": str(kernels), "WARP_SG_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "warp_sg.tools.cli", "render", str(bad), "-o", str(tmp_path / "o.png")],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warp-sg: error:") and "bad.glb" in lines[0], r.stderr
    left = [p.name for p in kernels.rglob("*_p*_t*")] if kernels.exists() else []
    assert not left, left

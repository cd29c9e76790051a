"""The linter is part of the suite: ``ruff check`` over the repository, with the rules of
``[tool.ruff]`` in pyproject.toml (pyflakes, pycodestyle, isort, bugbear, blind excepts, and
RUF100: a ``noqa`` comment that silences nothing), finds nothing.

ruff is in the ``[dev]`` extra, which the suite is run with, so a missing ruff fails the test
instead of skipping it."""
from __future__ import annotations

import subprocess
import sys
from importlib.util import find_spec
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_check_finds_nothing():
    assert find_spec("ruff") is not None, "ruff is not installed: it is in the [dev] extra (pip install -e '.[dev]')"
    r = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise", "."],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"ruff check found problems (fix them, or `ruff check --fix` for the safe ones):\n" \
                              f"{r.stdout[-6000:]}{r.stderr[-2000:]}"

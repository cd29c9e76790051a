"""What native libraries print on file descriptor 2 (C ``fprintf(stderr)``, which no Python hook
sees), captured so that the project can say it in its own words: Warp's line about a missing CUDA
driver (:mod:`warp_sg.core.device`), USD's ``Warning: in ... at line ... of ... -- message``
diagnostics (:mod:`warp_sg.scene.importers.usd`, one asset note)."""
from __future__ import annotations

import contextlib
import os
import sys
import tempfile


@contextlib.contextmanager
def native_stderr(lines: list):
    """Redirect file descriptor 2 to a temporary file meanwhile; its lines (stripped of the line
    break) are appended to ``lines`` on exit, whatever happened inside."""
    fd = 2  # (what native code writes to, whatever Python's sys.stderr is)
    try:
        sys.stderr.flush()
    except (AttributeError, OSError, ValueError):
        pass
    saved = os.dup(fd)
    with tempfile.TemporaryFile() as buf:
        os.dup2(buf.fileno(), fd)
        try:
            yield lines
        finally:
            os.dup2(saved, fd)
            os.close(saved)
            buf.seek(0)
            lines.extend(buf.read().decode("utf-8", "replace").splitlines())


__all__ = ["native_stderr"]

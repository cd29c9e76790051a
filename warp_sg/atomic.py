"""Atomic file output shared by images, MERL files and cache entries.

A file is written to a temporary name in the destination folder, then renamed over the target
with ``os.replace`` (atomic on POSIX): readers see the old file or the whole new one, never a
partial file, and on any error (including KeyboardInterrupt) the temporary file is removed.
The result gets the usual permissions of a new file (0666 less the umask), not mkstemp's 0600.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_output(path, suffix: str = ".tmp"):
    """Context manager yielding a temporary path (str) that replaces ``path`` on success.

    Creating the temporary file raises ``OSError`` before the body runs (e.g. read-only folder).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise

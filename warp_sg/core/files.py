"""Atomic file output shared by images, MERL files and cache entries.

A file is written to a temporary name in the destination folder, then renamed over the target
with ``os.replace`` (atomic on POSIX): readers see the old file or the whole new one, never a
partial file, and on any error (including KeyboardInterrupt) the temporary file is removed.
The result gets the usual permissions of a new file (0666 less the umask), not mkstemp's 0600.

:func:`check_output_path` checks an output path before any work (format, folder, writable) and
:func:`make_parents` creates its missing folders once the output exists, so a failed run leaves
nothing behind (the CLI commands and the reference use both).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from warp_sg.core.errors import InputError

#: Image formats ``save_image`` writes.
IMAGE_SUFFIXES = (".exr", ".png")


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


def check_output_path(path, suffixes=IMAGE_SUFFIXES, create_parents: bool = False) -> Path:
    """Fail early (before rendering) when ``path`` cannot be written as an image.

    ``create_parents``: missing folders are allowed (created by :func:`make_parents` once the image
    exists) as long as the nearest existing ancestor is a writable folder."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder, not a file", where=str(p))
    if p.suffix.lower() not in suffixes:
        raise InputError(f"unknown image format '{p.suffix}' (use {' or '.join(suffixes)})", where=str(p))
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        if not create_parents:
            raise InputError(f"folder '{parent}' does not exist", where=str(p))
        anc = parent
        while not anc.exists() and anc != anc.parent:
            anc = anc.parent
        if not anc.is_dir():
            raise InputError(f"'{anc}' is not a folder", where=str(p))
        parent = anc
    if not os.access(parent, os.W_OK):
        raise InputError(f"folder '{parent}' is not writable", where=str(p))
    return p


def output_folder(out_dir) -> Path:
    """``out_dir``, created if missing; one line when it cannot be created or written."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create the output folder ({e.strerror})", where=str(out)) from None
    if not os.access(out, os.W_OK):
        raise InputError("output folder is not writable", where=str(out))
    return out


def make_parents(path: Path) -> None:
    """Create the missing folders of ``path`` (after :func:`check_output_path` allowed them)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create folder '{path.parent}' ({e.strerror})", where=str(path)) from None

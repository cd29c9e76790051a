"""Did-you-mean: the closest of a few valid names to a misspelt one (difflib's ratio, Ratcliff and
Obershelp's matching: ``2·M/T`` with ``M`` matched characters of ``T`` in both strings), for the
one-line errors that name an unknown key, model, object or option."""
from __future__ import annotations

import difflib


def closest(name, options, cutoff: float = 0.5) -> str | None:
    """The option most like ``name`` with a ratio of at least ``cutoff`` (None when none is)."""
    m = difflib.get_close_matches(str(name), [str(o) for o in options], n=1, cutoff=cutoff)
    return m[0] if m else None


def did_you_mean(name, options) -> str:
    """``" — did you mean 'x'?"`` for the closest option ``x`` (ratio >= 0.5), else ``""``."""
    c = closest(name, options)
    return f" — did you mean '{c}'?" if c else ""


__all__ = ["closest", "did_you_mean"]

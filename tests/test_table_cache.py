"""Asset-independent tables on disk (warp_sg.core.cache.cached_table): the SG irradiance and fh tables
read back equal to a fresh computation, are read (not rebuilt) by the next cold start, and are
rebuilt when the code that computes them changes."""
from __future__ import annotations

import importlib
import sys

import numpy as np

from warp_sg.core import cache
from warp_sg.sg import fh, irradiance


def _builds(ledger, kind="tables"):
    return [k for k, _, built in ledger.events if built and k == kind]


def test_irradiance_and_fh_tables_are_read_back_equal_to_a_fresh_build(cache_dir):
    for table, build in ((irradiance.irradiance_table, irradiance.build_irradiance_table),
                         (fh.fh_table, fh.build_fh_table)):
        table.cache_clear()  # (the process's own memo: as a new process would)
        with cache.record_builds() as first:
            a = table()
        table.cache_clear()
        with cache.record_builds() as second:
            b = table()
        assert _builds(first) == ["tables"] and _builds(second) == []  # the second start reads the file
        assert ("tables", second.events[0][1], False) in second.events
        fresh = build()
        assert b.dtype == fresh.dtype and np.array_equal(b, fresh) and np.array_equal(a, fresh)
    assert len(list((cache_dir / "tables").glob("*.npz"))) == 2


def test_the_irradiance_table_read_back_matches_its_closed_forms(cache_dir):
    """Independent of the quadrature: e(1, λ) = coth λ − 1/λ for λ ≥ 24 (a lobe on the normal
    with no mass below the horizon: its mean cosine) and e(c, λ → 0) = 1/4 + λc/6 (irradiance.py,
    limits)."""
    irradiance.irradiance_table.cache_clear()
    irradiance.irradiance_table()
    irradiance.irradiance_table.cache_clear()
    tab = irradiance.irradiance_table().astype(np.float64)
    lam = 10.0 ** np.linspace(irradiance.IRR_LOG10_LAM_MIN, irradiance.IRR_LOG10_LAM_MAX, irradiance.IRR_N_LAM)
    sharp = lam >= 24.0
    np.testing.assert_allclose(np.exp(tab[sharp, -1]), 1.0 / np.tanh(lam[sharp]) - 1.0 / lam[sharp], rtol=2e-6)
    c = np.linspace(-1.0, 1.0, irradiance.IRR_N_C)
    np.testing.assert_allclose(np.exp(tab[0]), 0.25 + lam[0] * c / 6.0, atol=2e-5)


def test_a_table_is_rebuilt_when_its_code_changes(cache_dir, tmp_path, monkeypatch):
    src = tmp_path / "table_producer_mod.py"
    src.write_text("SCALE = 2.0\n\ndef build():\n    import numpy as np\n    return np.arange(4.0) * SCALE\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("table_producer_mod")
    try:
        with cache.record_builds() as ledger:
            a = cache.cached_table("unit", (mod,), mod.build)
            b = cache.cached_table("unit", (mod,), mod.build)
        assert _builds(ledger) == ["tables"] and np.array_equal(a, b) and np.array_equal(a, [0, 2, 4, 6])
        src.write_text("SCALE = 3.0\n\ndef build():\n    import numpy as np\n    return np.arange(4.0) * SCALE\n")
        mod = importlib.reload(mod)
        with cache.record_builds() as ledger:
            c = cache.cached_table("unit", (mod,), mod.build)
        assert _builds(ledger) == ["tables"] and np.array_equal(c, [0, 3, 6, 9])  # not the old entry
        # a comment or a blank line is no change of the code: the entry is reused
        src.write_text("# a comment\nSCALE = 3.0\n\n\ndef build():\n    import numpy as np\n"
                       "    return np.arange(4.0) * SCALE\n")
        mod = importlib.reload(mod)
        with cache.record_builds() as ledger:
            d = cache.cached_table("unit", (mod,), mod.build)
        assert _builds(ledger) == [] and np.array_equal(d, c)
    finally:
        sys.modules.pop("table_producer_mod", None)

"""Tools layer: the ways in — the ``warp-sg`` command line (``cli``), the error-vs-run-time report,
the benchmarks, the peer comparison and the interactive viewer. No library module imports them."""

"""Tools layer, Dask back end: cluster connection (``cluster``), SSDF chunks on workers
(``precompute``), frames and the reference across workers (``rendering``), batch jobs (``batch``).
Dask is imported only inside their functions."""

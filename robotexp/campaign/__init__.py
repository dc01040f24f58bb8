"""Campaigns: TOML sets of runs (spec), their jobs and runner (process pool, Dask
cluster, robots), reports, statistics, comparisons and the map benchmark.

Internal."""

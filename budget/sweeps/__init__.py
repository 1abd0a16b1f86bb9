"""The sweep engine for every study: sweep files, points through the runner, Zarr store, Sobol indices, plots."""

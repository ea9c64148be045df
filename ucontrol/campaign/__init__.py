"""Campaigns: sweeps and Monte Carlo over scenes on dask.distributed."""

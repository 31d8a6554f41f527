"""Many routes at once: sweeps, and the dask.distributed clusters they and ensembles run on."""

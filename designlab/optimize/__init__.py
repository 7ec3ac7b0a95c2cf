"""Design sweeps, executors (local, Dask), result store, optimizer, Pareto fronts."""

"""Monte Carlo sweeps: one scenario over axes, one result row per run, on dask.distributed.

ROS-free.  ``axes.py`` turns the axis options (``--seeds 1-100``, dates, presets,
trajectories, worlds) into run points (their Cartesian product); ``row.py`` runs
one point (a ``SimulationSetup`` built by the caller) and turns its
``SimulationResult`` or its error into one row; ``table.py`` is the rows' Parquet
schema and file; ``driver.py`` submits the runs to a local or an existing Dask
cluster, collects the rows as they finish (progress bar, the Parquet file
rewritten as it grows) and ``plot.py`` draws the summary of the percentiles.
"""

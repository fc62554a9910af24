"""The planner (``gnss-sim plan``): GNSS quality over an area and a time window from the scene's casts.

- area.py: the cells (a grid over the world's bounds or a polygon, or the points of a path) and their ground;
- sky.py: the satellites of every time step (positions, systems) from an ephemeris provider;
- ranging.py: the per-satellite ranging error budget (UERE) from a receiver profile;
- quality.py: per cell and time, one batched cast per chunk: line of sight, attenuated, reflected-only,
  blocked; DOPs (solver.dops_from_az_el); expected single-point horizontal accuracy; the RTK indicator;
- rtk_rule.py: the RTK availability proxy (a published rule, cited);
- windows.py: the best time windows (area share >= a threshold);
- geojson.py: the cells as WGS 84 lon/lat polygons (through the world's spherical_coordinates);
- outputs.py: the xarray Dataset (NetCDF), the Parquet table, the maps and the point time line.
"""

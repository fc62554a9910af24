"""What a plan writes: the xarray Dataset (NetCDF), the Parquet table (one row per cell and time), the maps
(share of time with RTK, mean HDOP), the time line of one point and the best-window summary."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..figures import pyplot, save_figure
from .quality import FIELDS
from .windows import Window, best_windows

#: descriptions and units of the dataset's variables
ATTRS = {"n_los": ("satellites in line of sight above the mask", "1"),
         "n_attenuated": ("satellites through foliage or a soft edge (attenuated)", "1"),
         "n_reflected": ("satellites received only by reflection (multipath on only)", "1"),
         "n_blocked": ("satellites above the mask blocked by the scene", "1"),
         "gdop": ("GDOP of the used satellites", "1"), "pdop": ("PDOP of the used satellites", "1"),
         "hdop": ("HDOP of the used satellites", "1"), "vdop": ("VDOP of the used satellites", "1"),
         "nlos_share": ("reflected-only share of the used satellites", "1"),
         "h_acc_m": ("expected single-point horizontal accuracy, HDOP x UERE (1 sigma)", "m"),
         "n_rtk": ("continuously visible dual-frequency satellites above the AR mask", "1"),
         "rtk": ("RTK availability indicator (proxy rule, rtk_rule.py)", "1"),
         "n_good": ("satellites with a predicted C/N0 >= the good threshold (predicted_cn0.py)", "1")}


def plan_dataset(area, ground_z_m, height_m, times_iso, t_s, fields: dict, attrs: dict):
    """xarray Dataset: variables (cell, time), coordinates x_m, y_m, ground_z_m per cell, time (ISO, GPS) and
    t_s (seconds from the first step); a grid also gets ix, iy per cell and its shape in the attributes."""
    import xarray as xr

    data = {k: (("cell", "time"), np.asarray(fields[k]).astype(np.int8 if k == "rtk" else FIELDS[k]),
                {"long_name": ATTRS[k][0], "units": ATTRS[k][1]}) for k in FIELDS}
    coords = {"x_m": ("cell", area.x_m), "y_m": ("cell", area.y_m), "ground_z_m": ("cell", ground_z_m),
              "antenna_z_m": ("cell", ground_z_m + height_m), "time": ("time", np.asarray(times_iso, dtype=str)),
              "t_s": ("time", np.asarray(t_s, float))}
    a = dict(attrs)
    if area.kind == "grid":
        iy, ix = np.nonzero(area.inside)
        coords["ix"], coords["iy"] = ("cell", ix), ("cell", iy)
        a.update(grid_step_m=area.step_m, grid_x0_m=area.x0_m, grid_y0_m=area.y0_m, grid_ny=area.shape[0],
                 grid_nx=area.shape[1])
    return xr.Dataset(data, coords=coords, attrs={k: (str(v) if not isinstance(v, (int, float)) else v)
                                                  for k, v in a.items()})


def write_netcdf(ds, path) -> str:
    """NetCDF with the netCDF4 engine where installed, else scipy (NetCDF 3); the engine used."""
    try:
        import netCDF4  # noqa: F401
        engine = "netcdf4"
    except ImportError:
        engine = "scipy"
    ds.to_netcdf(path, engine=engine)
    return engine


def write_parquet(ds, path) -> int:
    """One row per cell and time: cell, x_m, y_m, time, t_s and every field; the row count."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    c, t = ds.sizes["cell"], ds.sizes["time"]
    cols = {"cell": np.repeat(np.arange(c), t), "x_m": np.repeat(ds.x_m.values, t),
            "y_m": np.repeat(ds.y_m.values, t), "time": np.tile(ds.time.values.astype(str), c),
            "t_s": np.tile(ds.t_s.values, c)}
    for k in FIELDS:
        cols[k] = ds[k].values.reshape(-1).astype(bool) if k == "rtk" else ds[k].values.reshape(-1)
    pq.write_table(pa.table(cols), path)
    return c * t


def plot_maps(area, rtk_share, mean_hdop, path, title: str) -> None:
    """Two maps side by side: share of time with RTK available [%], mean HDOP (grid areas; a path: per point)."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2))
    for ax, val, name, cmap, vmax in ((axes[0], 100.0 * rtk_share, "time with RTK available [%]", "viridis", 100),
                                      (axes[1], mean_hdop, "mean HDOP", "magma_r", None)):
        if area.kind == "grid":
            ny, nx = area.shape
            ext = (area.x0_m, area.x0_m + nx * area.step_m, area.y0_m, area.y0_m + ny * area.step_m)
            im = ax.imshow(area.to_grid(val), origin="lower", extent=ext, cmap=cmap, vmin=0,
                           vmax=vmax if vmax is not None else np.nanpercentile(val, 98) if np.isfinite(val).any()
                           else 1)
        else:
            im = ax.scatter(area.x_m, area.y_m, c=val, cmap=cmap, s=12, vmin=0, vmax=vmax)
        ax.set_aspect("equal")
        ax.set_xlabel("world x [m]")
        ax.set_ylabel("world y [m]")
        ax.set_title(name)
        fig.colorbar(im, ax=ax, shrink=0.85)
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path)


def plot_timeline(t_h, fields_at: dict, path, title: str) -> None:
    """The time line of one cell: satellites by state, DOPs, expected accuracy, RTK indicator."""
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    ax = axes[0]
    for k, col in (("n_los", "tab:green"), ("n_attenuated", "tab:olive"), ("n_reflected", "tab:orange"),
                   ("n_blocked", "tab:grey"), ("n_rtk", "tab:blue")):
        ax.step(t_h, fields_at[k], where="post", color=col, label=k)
    ax.set_ylabel("satellites")
    ax.legend(fontsize=8, ncol=5)
    ax = axes[1]
    for k in ("hdop", "vdop", "pdop"):
        ax.step(t_h, fields_at[k], where="post", label=k)
    ax.set_ylabel("DOP")
    ax.set_ylim(0, min(20.0, np.nanmax(fields_at["pdop"]) * 1.1) if np.isfinite(fields_at["pdop"]).any() else 1)
    ax.legend(fontsize=8)
    ax = axes[2]
    ax.step(t_h, fields_at["h_acc_m"], where="post", color="k", label="HDOP x UERE [m]")
    rtk = np.asarray(fields_at["rtk"], bool)
    ax.fill_between(t_h, 0, 1, where=rtk, step="post", color="tab:blue", alpha=0.2,
                    transform=ax.get_xaxis_transform(), label="RTK indicator")
    ax.set_ylabel("horizontal accuracy [m]")
    ax.set_xlabel("hours from the start")
    ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path)


def window_lines(share, step_s: float, times_iso, threshold: float, what: str, limit: int = 3) -> list[str]:
    """Sentences of the best windows ("RTK available over 95 % of the area from 09:40 to 11:15 (GPS)")."""
    wins: list[Window] = best_windows(share, step_s, threshold, limit=limit)
    if not wins:
        best = float(np.nanmax(share)) if np.isfinite(share).any() else float("nan")
        return [f"{what} over {100 * threshold:.0f} % of the area at no time step (best {100 * best:.0f} %)"]
    out = []
    for w in wins:
        t_end = _plus(times_iso[0], w.end_s)
        out.append(f"{what} over {100 * threshold:.0f} % of the area from {_hm(_plus(times_iso[0], w.start_s))} to "
                   f"{_hm(t_end)} "
                   f"(GPS; {(w.end_s - w.start_s) / 3600:.2f} h, mean {100 * w.mean_share:.0f} %, lowest "
                   f"{100 * w.min_share:.0f} %)")
    return out


def _hm(iso: str) -> str:
    return iso[:10] + " " + iso[11:16]


def _plus(iso: str, s: float) -> str:
    from datetime import datetime, timedelta

    return (datetime.fromisoformat(iso[:19]) + timedelta(seconds=s)).isoformat()


def write_summary(path, lines: list[str]) -> None:
    Path(path).write_text("\n".join(lines) + "\n")

"""RINEX observation files -> :class:`~gnss_sim_ros2.core.rinex.obs_table.ObsTable` (numbers read by georinex)."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from .header import read_obs_header
from .obs_table import ObsTable

_OBS_RE = re.compile(r"^[CLDS][0-9][A-Z]$")


def load_rinex(path, tlim=None) -> ObsTable:
    """RINEX 3 observation file via georinex (its warnings silenced)."""
    import georinex as gr

    path = Path(path)
    hdr = read_obs_header(path)
    kw = {}
    if tlim is not None:
        kw["tlim"] = tuple(np.datetime_as_string(np.datetime64(t, "us")) for t in tlim)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = gr.load(path, **kw)
    except Exception as exc:  # noqa: BLE001  georinex raises many kinds
        raise ValueError(f"{path}: georinex could not read it: {exc}") from exc
    codes = [v for v in ds.data_vars if _OBS_RE.match(str(v))]
    if "time" not in ds.dims or "sv" not in ds.dims:
        times, svs = np.zeros(0, "datetime64[ns]"), np.zeros(0, "<U3")
        values = {}
    else:
        times = ds.time.values.astype("datetime64[ns]")
        svs = np.asarray(ds.sv.values).astype("<U3")
        values = {str(c): np.asarray(ds[c].values, dtype=float) for c in codes}
    return ObsTable(times, svs, values, str(path), "rinex", hdr["approx"], hdr["glo"])

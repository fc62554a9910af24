"""RINEX observation files -> :class:`~gnss_sim_ros2.core.rinex.obs_table.ObsTable` (numbers read by georinex)."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from .header import read_obs_header
from .obs_table import ObsTable

_OBS_RE = re.compile(r"^[CLDS][0-9][A-Z]$")
_OBS2_RE = re.compile(r"^[CLDSP][0-9]$")


def rinex2_code(code: str, system: str) -> str:
    """RINEX 3 code of a RINEX 2 observation code for ``system`` (RINEX 3.04 section 5.1; RTKLIB rinex.c
    convcode): P1/P2 are P(Y) (attribute W, GLONASS P); C1 and band-1 L/D/S are C/A (C) for GPS, GLONASS,
    QZSS, SBAS; C2 is L2C (GPS, QZSS) or GLONASS C/A (C); band-2 L/D/S are P(Y) (GPS W, GLONASS P); every
    other band and system: attribute X (the RINEX 2 files do not say which)."""
    kind, band = ("C" if code[0] in "CP" else code[0]), code[1]
    if code[0] == "P" and band in "12":
        attr = "W" if system == "G" else "P"
    elif code == "C2":
        attr = "C" if system in "GJR" else "X"
    elif band == "1":
        attr = "C" if system in "GRJS" else "X"
    elif band == "2":
        attr = "W" if system == "G" else ("P" if system == "R" else "X")
    else:
        attr = "X"
    return kind + band + attr


def _rinex2_values(ds, svs: np.ndarray) -> dict[str, np.ndarray]:
    """RINEX 2 variables (C1, P2, L1, ...) as RINEX 3 codes, each system's columns under its own code."""
    sys_of = np.array([s[0] for s in svs.tolist()])
    values: dict[str, np.ndarray] = {}
    for v in ds.data_vars:
        if not _OBS2_RE.match(str(v)):
            continue
        a = np.asarray(ds[v].values, dtype=float)
        for system in np.unique(sys_of).tolist():
            cols = sys_of == system
            if not np.isfinite(a[:, cols]).any():
                continue
            code = rinex2_code(str(v), system)
            dst = values.setdefault(code, np.full(a.shape, np.nan))
            fill = cols[None, :] & np.isfinite(a) & ~np.isfinite(dst)   # C1 and P1 of one band: the first read
            dst[fill] = a[fill]
    return values


def load_rinex(path, tlim=None) -> ObsTable:
    """RINEX 2, 3 or 4 observation file (plain, compressed or Hatanaka) via georinex (its warnings silenced);
    RINEX 2 codes become RINEX 3 codes (:func:`rinex2_code`)."""
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
        if hdr["version"] is not None and hdr["version"] < 3:
            values = _rinex2_values(ds, svs)
        else:
            values = {str(c): np.asarray(ds[c].values, dtype=float) for c in codes}
    return ObsTable(times, svs, values, str(path), "rinex", hdr["approx"], hdr["glo"])

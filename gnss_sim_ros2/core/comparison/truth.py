"""Ground truth of a comparison from a CSV file."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..frames import check_receiver_position, geodetic_to_ecef
from ..input_file import not_a_file, read_utf8
from ..rinex.obs_table import EPOCH_MATCH_NS, GPS_EPOCH_NP


def truth_from_csv(path, times: np.ndarray) -> np.ndarray:
    """Ground truth (E, 3) ECEF at ``times`` from a CSV with a ``time`` column (ISO 8601, GPS) and either
    ``x_m,y_m,z_m`` (ECEF) or ``lat_deg,lon_deg,h_m``; linear interpolation, NaN outside its span."""
    path = Path(path)
    if (why := not_a_file(path)) is not None:
        raise ValueError(f"--truth-csv {path}: {why}")
    t_ns, xyz, where = [], [], []
    rd = csv.DictReader(io.StringIO(read_utf8(path, f"--truth-csv {path}"), newline=""))
    cols = set(rd.fieldnames or [])
    ecef = {"x_m", "y_m", "z_m"} <= cols
    geo = {"lat_deg", "lon_deg", "h_m"} <= cols
    if "time" not in cols or not (ecef or geo):
        raise ValueError(f"{path}, line 1: need columns time and x_m,y_m,z_m or lat_deg,lon_deg,h_m; "
                         f"got {sorted(cols)}")
    for n, row in enumerate(rd, start=2):
        if None in row.values() or None in row:      # a short or long row: "float() argument must be ... 'NoneType'"
            raise ValueError(f"{path}, line {n}: {len(rd.fieldnames)} columns ({','.join(rd.fieldnames)}) expected, "
                             f"got {len([v for v in row.values() if v is not None]) + len(row.get(None) or [])}")
        try:
            t = np.datetime64(row["time"].strip().rstrip("Z"), "ns")
            if ecef:
                v = [float(row["x_m"]), float(row["y_m"]), float(row["z_m"])]
            else:
                if not row["lat_deg"].strip():
                    continue                    # fix.csv rows without a fix
                v = list(geodetic_to_ecef(float(row["lat_deg"]), float(row["lon_deg"]), float(row["h_m"])))
        except (ValueError, KeyError) as exc:
            raise ValueError(f"{path}, line {n}: {exc}") from None
        t_ns.append(int((t - GPS_EPOCH_NP) / np.timedelta64(1, "ns")))
        xyz.append(v)
        where.append(f", line {n}")
    if not t_ns:
        raise ValueError(f"{path}: no truth rows")
    check_receiver_position(np.asarray(xyz), "ecef", str(path), labels=where)     # names the first impossible row
    order = np.argsort(t_ns)
    ts = np.asarray(t_ns, dtype=float)[order]
    xyz = np.asarray(xyz)[order]
    q = ((times.astype("datetime64[ns]") - GPS_EPOCH_NP) / np.timedelta64(1, "ns")).astype(float)
    out = np.column_stack([np.interp(q, ts, xyz[:, i], left=np.nan, right=np.nan) for i in range(3)])
    if len(ts) == 1:
        out[np.abs(q - ts[0]) <= EPOCH_MATCH_NS] = xyz[0]
    return out

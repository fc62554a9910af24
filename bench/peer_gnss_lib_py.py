"""gnss_lib_py's ``simulate_measures`` on its own kind of scenario, for ``gnss-sim bench --speed``.

Run by the interpreter that has gnss_lib_py (its pins of pandas/xarray/georinex differ from
gnss_sim's, so it usually lives in a venv of its own)::

    PYTHON_WITH_GNSS_LIB_PY bench/peer_gnss_lib_py.py NAV.rnx START_GPS_MILLIS DURATION_S INTERVAL_S X,Y,Z

GPS only, a static receiver at ECEF X,Y,Z, one epoch every INTERVAL_S over DURATION_S from
START_GPS_MILLIS (milliseconds since the GPS epoch), broadcast ephemerides from the RINEX
navigation file NAV (parsed by gnss_lib_py's RinexNav).  Per epoch, as gnss_lib_py's tutorials
do: each satellite's record of the latest time at or before the epoch (its earliest when it has none
before: real files' satellites have their own times, not one grid), then
``simulate_measures(gps_millis, state, ephem=...)`` (visibility at 5 deg, expected pseudorange
and Doppler plus Gaussian noise).  Start-up (imports, parsing) is included in what the caller
times; prints one JSON line: epochs, measurements, and this process's own timings [s].
"""
from __future__ import annotations

import json
import sys
import time

T0 = time.perf_counter()

import numpy as np  # noqa: E402
from gnss_lib_py.navdata.navdata import NavData  # noqa: E402
from gnss_lib_py.parsers.rinex_nav import RinexNav  # noqa: E402
from gnss_lib_py.utils.gnss_models import simulate_measures  # noqa: E402


def main(argv) -> int:
    nav_path, start_ms, duration_s, interval_s, xyz = argv
    start_ms, duration_s, interval_s = float(start_ms), float(duration_s), float(interval_s)
    pos = np.array([float(v) for v in xyz.split(",")])
    t_import = time.perf_counter() - T0
    ephem = RinexNav(nav_path)
    ephem = ephem.where("gnss_id", "gps")
    t_parse = time.perf_counter() - T0 - t_import
    toe_ms = np.asarray(ephem["gps_millis"], dtype=float)
    sv_ids = np.asarray(ephem["sv_id"])
    # the selection changes only when an epoch passes a record time: memoised on how many it has passed
    times = np.unique(toe_ms)

    def records_at(t_ms):
        cols = []
        for sv in np.unique(sv_ids):
            mine = np.flatnonzero(sv_ids == sv)
            before = mine[toe_ms[mine] <= t_ms]
            cols.append(before[np.argmax(toe_ms[before])] if before.size else mine[np.argmin(toe_ms[mine])])
        return np.sort(np.array(cols))
    state = NavData()
    for name, v in zip(("x_rx_m", "y_rx_m", "z_rx_m"), pos):
        state[name] = np.array([v])
    for name in ("vx_rx_mps", "vy_rx_mps", "vz_rx_mps", "b_rx_m", "b_dot_rx_mps"):
        state[name] = np.array([0.0])
    rng = np.random.default_rng(1)
    n_epochs = int(np.floor(duration_s / interval_s + 1e-9)) + 1
    n_meas = 0
    cache: dict = {}
    t_loop0 = time.perf_counter()
    for k in range(n_epochs):
        t_ms = start_ms + 1000.0 * k * interval_s
        passed = int(np.searchsorted(times, t_ms, side="right"))
        eph = cache.get(passed)
        if eph is None:
            eph = cache[passed] = ephem.copy(cols=records_at(t_ms))
        meas, _ = simulate_measures(t_ms, state, ephem=eph, rng=rng)
        n_meas += len(meas)
    t_loop = time.perf_counter() - t_loop0
    print(json.dumps({"epochs": n_epochs, "measurements": n_meas, "import_s": t_import, "parse_s": t_parse,
                      "loop_s": t_loop, "total_s": time.perf_counter() - T0}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""Time to encode and write one RTCM3 epoch (RtcmWriter), MSM7 and MSM4.

The epochs of a simulated geodetic receiver (all six systems, the geodetic
profile's 20 signals, 2 minutes at 1 Hz, synthetic constellation) are
computed once; then each is encoded (MSM per system, cells split over 64,
station messages every 10 s, ephemerides every 60 s) into memory.  Prints
milliseconds per epoch and bytes per epoch.

    .venv/bin/python bench/bench_rtcm.py
"""
from __future__ import annotations

import io
import tempfile
import time
from pathlib import Path

import numpy as np

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.receiver.outputs import epoch_arrays, header, obs_types_for
from gnss_sim_ros2.core.rinex.nav import read_nav_file, records_as_dicts
from gnss_sim_ros2.core.rtcm.writer import RtcmWriter
from gnss_sim_ros2.core.simulation import chain_settings, run_simulation, setup_from_config
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.trajectory import Trajectory

POS = np.array([3149785.9652, 598260.8822, 5495348.4927])


def main(duration_s: float = 120.0) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        setup = setup_from_config(load_config(), Path(tmp), Trajectory.static(POS, "ecef"),
                                  start=GnssTime.from_iso("2022-01-01T01:00:00"), duration_s=duration_s,
                                  interval_s=1.0).with_params(systems="GRECJI")
        epochs = []
        setup.observer = lambda t, ecef, obs, sol: epochs.append((t, obs))
        res = run_simulation(setup)
        obs_types = obs_types_for(chain_settings(setup).receiver.profile, setup.systems)
        nav = records_as_dicts(read_nav_file(res.nav_path))
        st = [(t, epoch_arrays(o, obs_types)) for t, o in epochs]
        glo = {sv: 1 for _, o in epochs for sv in o.sv.tolist() if sv[0] == "R"}
        hdr = header(obs_types, "BNCH", POS, 1.0, glo)
    cells = np.mean([np.isfinite(a.value).sum() / 4 for _, a in st])
    print(f"{len(st)} epochs, {cells:.0f} signals per epoch on average")
    for msm in (7, 4):
        sink = io.BytesIO()
        w = RtcmWriter(sink, hdr, msm=msm, navigation=nav)
        t0 = time.perf_counter()
        for t, a in st:
            w.write_epoch(t, a)
        dt = time.perf_counter() - t0
        print(f"MSM{msm}: {1e3 * dt / len(st):.2f} ms per epoch, {len(sink.getvalue()) / len(st):.0f} bytes per epoch "
              f"(with station and ephemeris messages)")


if __name__ == "__main__":
    main()

"""Time to format and write one RINEX 3.04 observation epoch.

40 satellites (10 per system G/R/E/C), 3 signals each with code, phase,
Doppler and C/N0 (12 values per satellite, 480 per epoch), LLI and SSI set.
Prints microseconds per epoch for the dict and the array input forms.

    .venv/bin/python bench/bench_rinex_obs.py
"""
from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from gnss_sim_ros2.core.rinex.obs_write import EpochArrays, RinexObsHeader, RinexObsWriter, ssi_from_cn0
from gnss_sim_ros2.core.time import GnssTime

SIGNALS = {"G": ("1C", "2W", "5X"), "R": ("1C", "2C", "3X"), "E": ("1X", "5X", "7X"), "C": ("2I", "7I", "6I")}


def main(n_epochs: int = 2000) -> None:
    obs_types = {s: [f"{k}{sig}" for sig in sigs for k in "CLDS"] for s, sigs in SIGNALS.items()}
    svs = [f"{s}{i:02d}" for s in SIGNALS for i in range(1, 11)]
    rng = np.random.default_rng(1)
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")

    def make(k):
        val = np.empty((len(svs), 12))
        val[:, 0::4] = 2.0e7 + rng.uniform(0, 5e6, (len(svs), 1)) + k  # code [m]
        val[:, 1::4] = val[:, 0::4] / 0.19                              # phase [cycles]
        val[:, 2::4] = rng.uniform(-4000, 4000, (len(svs), 3))          # Doppler [Hz]
        val[:, 3::4] = rng.uniform(25, 52, (len(svs), 3))               # C/N0 [dB-Hz]
        ssi = np.repeat(ssi_from_cn0(val[:, 3::4]), 4, axis=1)
        lli = np.zeros_like(ssi)
        return val, lli, ssi

    epochs = [make(k) for k in range(20)]
    dict_epochs = []
    for val, lli, ssi in epochs:
        d = {}
        for r, sv in enumerate(svs):
            sys_codes = obs_types[sv[0]]
            d[sv] = {sys_codes[j]: (val[r, j], int(lli[r, j]), int(ssi[r, j])) for j in range(12)}
        dict_epochs.append(d)

    with tempfile.TemporaryDirectory() as tmp:
        for form in ("dict", "arrays"):
            path = os.path.join(tmp, f"bench_{form}.rnx")
            hdr = RinexObsHeader(obs_types=obs_types, interval_s=1.0)
            with RinexObsWriter(path, hdr) as w:
                w.write_epoch(t0, dict_epochs[0])
                start = time.perf_counter()
                for k in range(1, n_epochs):
                    if form == "dict":
                        w.write_epoch(t0 + k, dict_epochs[k % 20])
                    else:
                        val, lli, ssi = epochs[k % 20]
                        w.write_epoch(t0 + k, EpochArrays(svs, obs_types, val, lli, ssi))
                elapsed = time.perf_counter() - start
            per = elapsed / (n_epochs - 1) * 1e6
            print(f"{form:6s}: {per:7.1f} us per epoch (40 satellites x 12 values, formatted + written), "
                  f"{os.path.getsize(path) / n_epochs / 1024:.1f} KiB per epoch")


if __name__ == "__main__":
    main()

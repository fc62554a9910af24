"""Measure a real receiver's code biases against the simulator (the defaults of core/receiver/hardware_bias.py).

Simulates the station noise-free at its header position with the default models, then prints, per bias
group (system; BeiDou-2/-3) and signal pair, the median over satellites of each satellite's mean of
real minus simulated pseudorange, after one receiver clock per epoch (median over GPS satellites of the
first GPS code).  Figures are relative to that GPS code.

    python bench/measure_code_bias.py [--data ../shared/data/opec-2022-001]
"""
from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np

from gnss_sim_ros2.cli import main as cli_main
from gnss_sim_ros2.core.receiver.hardware_bias import group_of

#: real code -> simulated code of the same signal (OPEC's NETR9 against the geodetic profile)
PAIRS = {"G": [("C1C", "C1C"), ("C2W", "C2W"), ("C5X", "C5Q")],
         "E": [("C1X", "C1C"), ("C5X", "C5Q"), ("C7X", "C7Q"), ("C8X", "C8Q")],
         "C": [("C2X", "C2I"), ("C7X", "C7I"), ("C6X", "C6I")]}
OPEC = "OPEC00NOR_S_20220010000"


def header_position(path: Path) -> str:
    for line in path.read_text().splitlines():
        if "APPROX POSITION XYZ" in line:
            return ",".join(line.split()[:3])
    raise ValueError(f"{path}: no APPROX POSITION XYZ line")


def main(argv=None) -> int:
    import georinex as gr

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" /
                                          "opec-2022-001"))
    args = ap.parse_args(argv)
    data = Path(args.data)
    real_path = data / f"{OPEC}_0340_30S_MO.rnx"
    with tempfile.TemporaryDirectory() as tmp:
        rc = cli_main(["simulate", "--nav", *(str(data / f"{OPEC}_01D_{s}N.rnx") for s in "GEC"),
                       "--position-ecef", header_position(real_path), "--start", "2022-01-01T00:00:00",
                       "--duration", "13170", "--interval", "30", "--systems", "GEC", "--mask-deg", "10",
                       "--noise-free", "--quiet", "--out", tmp])
        if rc:
            return rc
        (sim_path,) = Path(tmp).glob("*_MO.rnx")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            real = gr.load(real_path, use=set(PAIRS), meas=sorted({a for v in PAIRS.values() for a, _ in v}))
            sim = gr.load(sim_path, use=set(PAIRS), meas=sorted({b for v in PAIRS.values() for _, b in v}))

    def table(ds, code, system):
        return ds[code].sel(sv=[v for v in ds.sv.values if v[0] == system])

    g_real, g_sim = table(real, "C1C", "G"), table(sim, "C1C", "G")
    common = sorted(set(g_real.sv.values) & set(g_sim.sv.values))
    clock_m = np.nanmedian(g_real.sel(sv=common).values - g_sim.sel(sv=common).values, axis=1)
    print(f"{'group':6s} {'real':5s} {'sim':5s} {'sats':>4s} {'bias_m':>7s} {'sd_sat_m':>8s}")
    for system, pairs in PAIRS.items():
        for real_code, sim_code in pairs:
            r, m = table(real, real_code, system), table(sim, sim_code, system)
            svs = sorted(set(r.sv.values) & set(m.sv.values))
            d = r.sel(sv=svs).values - m.sel(sv=svs).values - clock_m[:, None]
            d[np.abs(d - np.nanmedian(d)) > 30.0] = np.nan      # gross errors of the real receiver
            for group in sorted({group_of(sv) for sv in svs}):
                cols = [j for j, sv in enumerate(svs)
                        if group_of(sv) == group and np.isfinite(d[:, j]).sum() > 10]
                if not cols:
                    continue
                means = np.array([np.nanmean(d[:, j]) for j in cols])
                print(f"{group:6s} {real_code:5s} {sim_code:5s} {len(cols):4d} {np.median(means):+7.2f} "
                      f"{means.std():8.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

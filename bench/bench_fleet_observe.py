"""The observables of a fleet's epoch: one ReceiverChain.observe per robot against one
core/receiver/batch_observe.observe_receivers pass over every robot (issue 31), for several robot counts.

The inputs are the fleet receiver node's (bench_chain_step's: the demo path in the demo courtyard, the visibility
cast of each epoch, the node's chain: no ephemeris provider, default parameters at 10 Hz, the benchmark's fleet
configuration: reflections and the LMS layer off); robot k stands k metres east of robot 0 with robot 0's
visibility (the observables' cost, not the cast's, is measured) and the seed + k.  Two sets of chains with the
same seeds step the same epochs, the per-robot loop and the batch alternated epoch by epoch (which goes first
alternating too), so a load on the machine weighs on both; every robot's observations are checked equal.

Printed per robot count: the CPU time of the observables per robot-epoch (median over epochs, thread time) of
each way, their ratio, and the load average.

    python bench/bench_fleet_observe.py [--epochs 200] [--robots 1,4,32]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def _chains(rcv: dict, robots: int):
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

    return [ReceiverChain(ChainSettings.from_params({**rcv, "seed": rcv["seed"] + k, "output_dir": ""}), None)
            for k in range(robots)]


def run(epochs, rcv: dict, robots: int) -> dict:
    from gnss_sim_ros2.core.receiver.batch_observe import ReceiverEpoch, observe_receivers

    loop, batch = _chains(rcv, robots), _chains(rcv, robots)
    east = None
    t_loop, t_batch = [], []
    for i, (t, ecef, st, vis, att, _) in enumerate(epochs):
        if east is None:
            from gnss_sim_ros2.core.frames import ecef_to_geodetic, enu_rotation

            lat, lon, _h = ecef_to_geodetic(*ecef)
            east = enu_rotation(lat, lon)[0]
        inputs = [ReceiverEpoch(t, ecef + k * east, st, vis, att) for k in range(robots)]

        def one_by_one(inputs=inputs):
            return [c.observe(e.t, e.antenna_ecef_m, e.states, e.vis_state, e.attenuation_db)
                    for c, e in zip(loop, inputs)]

        def together(inputs=inputs):
            return observe_receivers(batch, inputs)

        got = {}
        for name, fn in ((("loop", one_by_one), ("batch", together)) if i % 2 == 0 else
                         (("batch", together), ("loop", one_by_one))):
            c0 = time.thread_time()
            got[name] = fn()
            (t_loop if name == "loop" else t_batch).append((time.thread_time() - c0) / robots)
        for a, b in zip(got["loop"], got["batch"]):
            if a.pseudorange_m.tobytes() != b.pseudorange_m.tobytes() or a.cn0_dbhz.tobytes() != b.cn0_dbhz.tobytes():
                raise SystemExit(f"epoch {i}: a robot's observations differ between the loop and the batch")
    warm = min(20, len(epochs) // 10)
    lo, ba = 1e3 * np.median(t_loop[warm:]), 1e3 * np.median(t_batch[warm:])
    return {"robots": robots, "loop_ms": lo, "batch_ms": ba, "ratio": lo / ba}


def main() -> int:
    from bench_chain_step import _inputs

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=200)
    ap.add_argument("--robots", default="1,4,32", help="robot counts, comma-separated")
    a = ap.parse_args()
    if a.epochs < 20:
        raise SystemExit("--epochs must be >= 20")
    counts = [int(x) for x in a.robots.split(",")]
    rcv, epochs, _, _ = _inputs(a.epochs, 10.0, "off")
    rcv = {**rcv, "lms_environment": "off"}
    print(f"observables per robot-epoch, {a.epochs} epochs at 10 Hz, CPU thread time, median after warm-up; "
          f"load average before {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'robots':>6} {'loop ms':>9} {'batch ms':>9} {'loop/batch':>10}")
    for n in counts:
        r = run(epochs, rcv, n)
        print(f"{r['robots']:>6} {r['loop_ms']:>9.3f} {r['batch_ms']:>9.3f} {r['ratio']:>10.2f}")
    print(f"load average after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Cost of a threat scenario (core/threats) in the offline chain (printed figures, not a timed test).

The demo (courtyard world, every system, geodetic profile) simulated for ``--duration`` seconds, ``--repeat``
times each, in one process, the scene and the ephemeris loaded once (SimulationSetup.scene / .ephemeris):
  * no scenario (parameter scenario empty: ReceiverChain.threats is None);
  * a scenario whose events are never active during the run (a jammer and every fault kind, all after the
    run's end): what "a scenario with no event active" costs (spoofers are not simulated yet);
  * the same jammer active the whole run (C/N0 of every signal row through jamming.py, a segment cast per epoch).
Times: the epoch loop's wall clock (SimulationResult.wall_s), median and best, with the load average beside them
(a shared machine: the best moves least).

    .venv/bin/python bench/bench_threats.py [--duration 600] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gnss_sim_ros2.config_file import load_config  # noqa: E402
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config, visibility_options  # noqa: E402
from gnss_sim_ros2.core.visibility import load_scene  # noqa: E402

JAMMER = """  - type: jammer
    name: ppd
    position: [20.0, 0.0, 1.0]
    eirp_dbw: -50.0
    center_hz: 1575.42e6
    bandwidth_hz: 2.0e6
    start_s: {start}
    end_s: {end}
"""
IDLE_REST = """  - {{type: fault, kind: off, start_s: {start}, end_s: {end}}}
  - {{type: fault, kind: stuck, start_s: {start}, end_s: {end}}}
  - {{type: fault, kind: position_offset, offset_enu_m: [1, 0, 0], start_s: {start}, end_s: {end}}}
  - {{type: fault, kind: clock_jump_s, jump_s: 1.0e-3, start_s: {start}, end_s: {end}}}
  - {{type: fault, kind: satellite_clock_step_m, satellite: G05, step_m: 10, start_s: {start}, end_s: {end}}}
  - {{type: fault, kind: satellite_ramp_mps, satellite: G05, ramp_mps: 1, start_s: {start}, end_s: {end}}}
  - {{type: fault, kind: bad_ephemeris, satellite: G05, error_m: 10, start_s: {start}, end_s: {end}}}
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_threats_"))
    late = {"start": a.duration + 1000.0, "end": a.duration + 2000.0}
    (tmp / "idle.yaml").write_text("version: 1\nevents:\n" + JAMMER.format(**late) + IDLE_REST.format(**late))
    (tmp / "jam.yaml").write_text("version: 1\nevents:\n" + JAMMER.format(start=0.0, end=".inf"))
    cases = {"no scenario": "", "scenario, no event active": str(tmp / "idle.yaml"),
             "jammer active every epoch": str(tmp / "jam.yaml")}
    base = setup_from_config(load_config(), tmp / "warm", duration_s=a.duration)
    scene = load_scene(*base.scene_files(), visibility_options(base))
    ephemeris = {}
    print(f"demo, {a.duration:.0f} s at 1 Hz, {a.repeat} runs each; load average {os.getloadavg()[0]:.2f}")
    print(f"{'case':30s} {'median s':>9s} {'best s':>8s} {'x real time':>12s} {'fixes':>6s}")
    for name, scenario in cases.items():
        walls, fixes = [], 0
        for r in range(a.repeat):
            cfg = load_config(overrides={"receiver": {"scenario": scenario}})
            setup = setup_from_config(cfg, tmp / f"{len(walls)}_{r}", duration_s=a.duration, scene=scene,
                                      ephemeris=ephemeris)
            res = run_simulation(setup)
            walls.append(res.wall_s)
            fixes = res.fixes
        med, best = statistics.median(walls), min(walls)
        print(f"{name:30s} {med:9.3f} {best:8.3f} {a.duration / med:12.0f} {fixes:6d}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

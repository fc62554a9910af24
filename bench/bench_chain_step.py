"""The one-epoch path of the receiver node: ``ReceiverChain.step`` per epoch, stage by stage (issue 18).

The inputs are those the receiver node gets, built from the core only (no ROS): the satellite states of
every system at the epoch (what the ephemeris node publishes), the antenna on the demo path in the demo
courtyard, and the visibility cast of that epoch (what the visibility node publishes: satellites below
the horizon BLOCKED, attenuation 0).  The chain is the node's: no ephemeris provider (the second-order
transmit-time expansion), NMEA every epoch, the RINEX observation file, ``fix.csv`` and, with ``--rtcm``,
RTCM3 bytes; default parameters otherwise (preset ``balanced``, every system GRECJI, 10 Hz).

Printed: the step's wall and CPU time per epoch (median, p90, p99, without instrumentation), then the CPU
time per stage (exclusive: a stage's own time without the stages it calls; timers around the chain's calls,
so the sum is a little above the plain step), the visibility cast and the states outside the step, and
optionally the cProfile top entries.

    python bench/bench_chain_step.py [--epochs 600] [--rate 10] [--rtcm] [--multipath off|nlos|full]
                                     [--profile] [--robots 4]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def _inputs(n_epochs: int, rate_hz: float, multipath: str):
    """(chain settings params, epochs [(t, ecef, states, vis_state, att, paths)], cast ms/epoch,
    states ms/epoch)."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.simulation import AntennaPath, setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene
    from gnss_sim_ros2.core.vocabulary import VisibilityState

    cfg = load_config(overrides={"/**": {"rate_hz": rate_hz}})
    setup = setup_from_config(cfg, Path(tempfile.mkdtemp(prefix="gnss_sim_step_")))
    vis_p = {**cfg.node("visibility"), "multipath": multipath}
    opt = VisibilityOptions.from_params(vis_p)
    scene = load_scene(*setup.scene_files(), opt)
    path = AntennaPath(setup.trajectory, scene)
    rcv = cfg.node("receiver")
    start = GnssTime.from_iso(rcv["start_time"])
    dur = n_epochs / rate_hz + 60.0
    with tempfile.TemporaryDirectory() as tmp:
        provider, _ = open_ephemeris("synthetic", start, dur, rcv["systems"], workdir=tmp)
    blocked = int(VisibilityState.BLOCKED)
    epochs, t_cast, t_states = [], 0.0, 0.0
    for i in range(n_epochs):
        t_rel = i / rate_hz
        t = start + t_rel
        w0 = time.perf_counter()
        st = provider.states(t, systems=rcv["systems"])
        w1 = time.perf_counter()
        ecef, world = path.at(t_rel)
        state, att, v = opt.cast(scene, world, st.pos_ecef_m)
        t_cast += time.perf_counter() - w1
        t_states += w1 - w0
        above = v.el_deg >= 0.0          # the visibility message lists the satellites above the horizon
        vis_state = np.where(above, state, blocked).astype(np.int64)
        att = np.where(above, att, 0.0)
        paths = getattr(v, "paths", None)
        epochs.append((t, np.asarray(ecef, dtype=float), st, vis_state, att, paths))
    return rcv, epochs, 1e3 * t_cast / n_epochs, 1e3 * t_states / n_epochs


def _chain(rcv: dict, out_dir: Path, rtcm: bool, marker: str = "GSIM"):
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

    settings = ChainSettings.from_params({**rcv, "output_dir": str(out_dir), "marker_name": marker})
    return ReceiverChain(settings, None, nmea=True, comment="bench_chain_step", rtcm=True if rtcm else None)


#: (stage, owner, attribute): the calls timed; owner a module or class, looked up at run time
def _stages():
    from gnss_sim_ros2.core import nmea, solver
    from gnss_sim_ros2.core.receiver import chain, code_multipath, engine, noise, tracking
    from gnss_sim_ros2.core.receiver import clock as clock_mod
    from gnss_sim_ros2.core.receiver import cn0 as cn0_mod
    from gnss_sim_ros2.core.rinex import obs_write
    from gnss_sim_ros2.core.rtcm import writer as rtcm_writer

    return [
        ("step (chain's own)", chain.ReceiverChain, "step"),
        ("observables (Receiver.epochs' own)", engine.Receiver, "epochs"),
        ("geometry / light time", engine.Receiver, "_light_time"),
        ("az/el of the states", engine, "az_el_at"),
        ("ionosphere (Klobuchar)", engine.prop, "klobuchar_l1_delay_s"),
        ("troposphere", engine.prop, "tropo_slant_delay_m"),
        ("C/N0", cn0_mod, "cn0_dbhz_from_params"),
        ("receiver clock", clock_mod.ReceiverClock, "step"),
        ("noise sigmas (DLL/PLL/FLL)", noise, "dll_sigma_m"),
        ("noise sigmas (DLL/PLL/FLL)", noise, "pll_sigma_m"),
        ("noise sigmas (DLL/PLL/FLL)", noise, "doppler_sigma_hz"),
        ("multipath state", code_multipath.CodeMultipath, "state"),
        ("tracking", tracking.Tracker, "update_many"),
        ("carrier smoothing", chain.ReceiverChain, "_smoothed_many"),
        ("solver (position + velocity)", chain, "solve_pvt_many"),
        ("RINEX cells (epoch_arrays)", chain, "epoch_arrays"),
        ("RINEX text (write_epochs)", obs_write.RinexObsWriter, "write_epochs"),
        ("NMEA", nmea, "sentences_from_solution"),
        ("NMEA", nmea, "join_sentences"),
        ("RTCM3", rtcm_writer.RtcmWriter, "write_epoch"),
        ("fix.csv + files (_write's own)", chain.ReceiverChain, "_write"),
        ("products (_products' own)", chain.ReceiverChain, "_products"),
        ("solver inputs (fix_inputs)", sys.modules["gnss_sim_ros2.core.receiver.outputs"], "fix_inputs"),
        ("solver: PvtSolution objects", solver, "_make_solution"),
        ("solver: velocity", solver, "_solve_velocities"),
    ]


class _Timers:
    """Exclusive wall time per stage: wrappers around the stages' calls, a stack subtracting callees."""

    def __init__(self):
        self.total: dict[str, float] = {}
        self._stack: list = []
        self._saved: list = []

    def install(self, stages):
        for name, owner, attr in stages:
            fn = getattr(owner, attr)
            self._saved.append((owner, attr, fn))
            setattr(owner, attr, self._wrap(name, fn, isinstance(owner, type)))

    def uninstall(self):
        for owner, attr, fn in reversed(self._saved):
            setattr(owner, attr, fn)
        self._saved.clear()

    def _wrap(self, name, fn, method):
        timers = self

        def timed(*a, **kw):
            stack = timers._stack
            stack.append(0.0)
            t0 = time.thread_time()
            try:
                return fn(*a, **kw)
            finally:
                dt = time.thread_time() - t0
                child = stack.pop()
                timers.total[name] = timers.total.get(name, 0.0) + dt - child
                if stack:
                    stack[-1] += dt
        return timed


def run(n_epochs: int, rate_hz: float, rtcm: bool, multipath: str, profile: bool, robots: int) -> dict:
    rcv, epochs, cast_ms, states_ms = _inputs(n_epochs, rate_hz, multipath)
    warm = min(20, n_epochs // 10)
    with tempfile.TemporaryDirectory() as tmp:
        # 1. plain: the step's wall time per epoch (every robot's chain steps the same inputs)
        chains = [_chain(rcv, Path(tmp) / f"plain{r}", rtcm, f"R{r:03d}") for r in range(robots)]
        times, cpu = [], []
        n_sig = []
        for t, ecef, st, vis, att, paths in epochs:
            w0, c0 = time.perf_counter(), time.thread_time()
            for c in chains:
                ep = c.step(t, ecef, st, vis, att, multipath=paths)
            cpu.append((time.thread_time() - c0) / robots)
            times.append((time.perf_counter() - w0) / robots)
            n_sig.append(len(ep.obs.sv))
        for c in chains:
            c.close()
        fixes = chains[0].fixes
        # 2. per stage
        timers = _Timers()
        timers.install(_stages())
        chain = _chain(rcv, Path(tmp) / "stages", rtcm)
        try:
            for j, (t, ecef, st, vis, att, paths) in enumerate(epochs):
                if j == warm:
                    timers.total.clear()
                chain.step(t, ecef, st, vis, att, multipath=paths)
        finally:
            timers.uninstall()
            chain.close()
        stage_ms = {k: 1e3 * v / (n_epochs - warm) for k, v in timers.total.items()}
        prof = None
        if profile:
            import cProfile
            import io
            import pstats

            chain = _chain(rcv, Path(tmp) / "prof", rtcm)
            for t, ecef, st, vis, att, paths in epochs[:warm]:
                chain.step(t, ecef, st, vis, att, multipath=paths)
            pr = cProfile.Profile()
            pr.enable()
            for t, ecef, st, vis, att, paths in epochs[warm:]:
                chain.step(t, ecef, st, vis, att, multipath=paths)
            pr.disable()
            chain.close()
            s = io.StringIO()
            ps = pstats.Stats(pr, stream=s)
            ps.sort_stats("tottime").print_stats(30)
            prof = (s.getvalue(), ps.total_calls / (n_epochs - warm))
    v = 1e3 * np.array(times[warm:])
    c = 1e3 * np.array(cpu[warm:])
    return {"epochs": n_epochs, "rate_hz": rate_hz, "robots": robots, "signals": float(np.median(n_sig)),
            "sats": float(np.median([len(e[2]) for e in epochs])), "fixes": fixes,
            "median_ms": float(np.median(v)), "p90_ms": float(np.percentile(v, 90)),
            "p99_ms": float(np.percentile(v, 99)), "mean_ms": float(v.mean()), "cpu_median_ms": float(np.median(c)),
            "cpu_p99_ms": float(np.percentile(c, 99)), "cpu_mean_ms": float(c.mean()), "stage_ms": stage_ms,
            "cast_ms": cast_ms, "states_ms": states_ms, "profile": prof}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=600)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--rtcm", action="store_true", help="RTCM3 bytes every epoch (the node's rtcm parameter)")
    ap.add_argument("--multipath", default="off", choices=("off", "nlos", "full"))
    ap.add_argument("--robots", type=int, default=1, help="chains stepped per epoch in this process")
    ap.add_argument("--profile", action="store_true", help="cProfile top 30 (own time)")
    a = ap.parse_args()
    if a.epochs < 20 or a.robots < 1:
        raise SystemExit("--epochs must be >= 20 and --robots >= 1")
    r = run(a.epochs, a.rate, a.rtcm, a.multipath, a.profile, a.robots)
    print(f"ReceiverChain.step, demo (courtyard, demo path, GRECJI, balanced), {r['epochs']} epochs at "
          f"{r['rate_hz']:g} Hz, multipath {a.multipath}, RTCM {'on' if a.rtcm else 'off'}, {r['robots']} chain(s); "
          f"median {r['sats']:.0f} satellites in the states, {r['signals']:.0f} tracked signals; "
          f"{r['fixes']} fixes")
    print(f"  step per epoch and chain: median {r['median_ms']:.3f} ms, p90 {r['p90_ms']:.3f} ms, "
          f"p99 {r['p99_ms']:.3f} ms, mean {r['mean_ms']:.3f} ms wall; CPU median {r['cpu_median_ms']:.3f} ms, "
          f"p99 {r['cpu_p99_ms']:.3f} ms, mean {r['cpu_mean_ms']:.3f} ms")
    print("  per stage (exclusive, thread CPU time, instrumented), ms/epoch:")
    total = 0.0
    for name, ms in sorted(r["stage_ms"].items(), key=lambda kv: -kv[1]):
        print(f"    {name:40s} {ms:7.3f}")
        total += ms
    print(f"    {'sum':40s} {total:7.3f}")
    print(f"  outside the step: visibility cast {r['cast_ms']:.3f} ms/epoch, states at the epoch "
          f"{r['states_ms']:.3f} ms/epoch")
    if r["profile"]:
        text, calls = r["profile"]
        print(f"  cProfile: {calls:.0f} function calls per epoch")
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

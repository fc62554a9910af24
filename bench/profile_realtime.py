"""Where an epoch of the composed ROS graph goes: per-epoch CPU time of each stage (printed figures).

Runs `gnss-sim run --realtime` (every node in one process) at RATE Hz for DURATION s of simulated
time with every system, each stage's entry point wrapped to add up the CPU time of the main thread
(time.thread_time: the executor runs every node there; DDS threads are not counted). A few dozen
wrapped calls per epoch cost nothing measurable, and CPU time changes little with other work on the
machine, unlike the wall-clock latency of bench_realtime.py (the machine's load still slows the
caches down a little). Times are inclusive (a stage contains the indented ones below it). With
``--cprofile N`` the N functions of most own time follow (cProfile, wall clock, its overhead
included).

    python bench/profile_realtime.py [--rate 10] [--duration 30] [--cprofile 25]
"""
from __future__ import annotations

import argparse
import functools
import json
import sys
import tempfile
import time
from pathlib import Path

from gnss_sim_ros2.benchmarks.timing import wrap_attribute

#: (label, module, attribute path): the entry points timed; a missing one is skipped (old or new code); an empty
#: label adds to the stage above
STAGES = [
    ("ephemeris node: one epoch published", "gnss_sim_ros2.nodes.ephemeris_node", "EphemerisNode.publish_epoch"),
    ("  provider.states (core)", "gnss_sim_ros2.core.ephemeris.broadcast", "BroadcastEphemeris.states"),
    ("  states -> message", "gnss_sim_ros2.nodes.ephemeris_node", "states_to_msg"),
    ("  states -> CDR bytes (codec)", "gnss_sim_ros2.nodes.ephemeris_node", "encode_states"),
    ("visibility node: one epoch", "gnss_sim_ros2.nodes.visibility_node", "VisibilityNode.process"),
    ("  message -> states (visibility)", "gnss_sim_ros2.nodes.visibility_node", "states_from_msg"),
    ("  CDR bytes -> states (codec, visibility)", "gnss_sim_ros2.nodes.visibility_node", "states_from_cdr"),
    ("  cast (core VisibilityOptions.cast)", "gnss_sim_ros2.core.visibility.options", "VisibilityOptions.cast"),
    ("  visibility -> CDR bytes (codec)", "gnss_sim_ros2.nodes.visibility_node", "encode_visibility"),
    ("receiver node: one epoch", "gnss_sim_ros2.nodes.receiver_session", "ReceiverSession.process"),
    ("  message -> states (receiver)", "gnss_sim_ros2.nodes.receiver_node", "states_from_msg"),
    ("  CDR bytes -> states (codec, receiver)", "gnss_sim_ros2.nodes.receiver_session", "states_from_cdr"),
    ("  message -> reflected paths", "gnss_sim_ros2.nodes.receiver_node", "paths_from_msg"),
    ("  CDR bytes -> visibility (codec)", "gnss_sim_ros2.nodes.receiver_session", "visibility_from_cdr"),
    ("  visibility columns -> chain inputs", "gnss_sim_ros2.nodes.receiver_session", "chain_inputs_from_visibility"),
    ("  chain: observables (core ReceiverChain.observe)", "gnss_sim_ros2.core.receiver.chain", "ReceiverChain.observe"),
    ("  chain: fix, NMEA, files (core ReceiverChain.finish)", "gnss_sim_ros2.core.receiver.chain",
     "ReceiverChain.finish"),
    ("  observations message", "gnss_sim_ros2.nodes.receiver_node", "ReceiverNode._observations_msg"),
    ("  fix, vel, status messages", "gnss_sim_ros2.nodes.receiver_session", "fix_to_msg"),
    ("", "gnss_sim_ros2.nodes.receiver_session", "vel_to_msg"),
    ("", "gnss_sim_ros2.nodes.receiver_session", "status_to_msg"),
    ("  observations -> CDR bytes (codec)", "gnss_sim_ros2.nodes.receiver_session", "encode_observations"),
    ("rclpy Publisher.publish (all, serialisation included)", "rclpy.publisher", "Publisher.publish"),
    ("rclpy take (SingleThreadedExecutor: deserialisation)", "rclpy.executors", "Executor._take_subscription"),
    ("recorder: bag writes (rosbags Writer.write)", "rosbags.rosbag2", "Writer.write"),
    ("trajectory player tick", "gnss_sim_ros2.nodes.trajectory_player", "TrajectoryPlayer._tick"),
    ("run driver: /clock messages", "gnss_sim_ros2.commands.run.clock", "ClockDriver.set_clock"),
    ("executor spin_once (everything dispatched)", "rclpy.executors", "SingleThreadedExecutor.spin_once"),
]


class StageClock:
    def __init__(self):
        self.cpu: dict[str, float] = {}
        self.calls: dict[str, int] = {}

    def timed(self, label: str, inner):
        """``inner`` adding its main-thread CPU time to ``label``."""
        self.cpu.setdefault(label, 0.0)
        self.calls.setdefault(label, 0)

        @functools.wraps(inner)      # the same signature: executors look at it (a timer's TimerInfo)
        def timed(*args, **kwargs):
            t0 = time.thread_time()
            try:
                return inner(*args, **kwargs)
            finally:
                self.cpu[label] += time.thread_time() - t0
                self.calls[label] += 1

        return timed

    def wrap(self, label: str, module: str, path: str) -> bool:
        return wrap_attribute(module, path, lambda inner: self.timed(label, inner))

    def wrap_executor(self, label: str):
        """spin_once of whichever executor the run makes (a C++ EventsExecutor cannot be patched: wrapped at
        the call site through the clock driver's attribute)."""
        from gnss_sim_ros2.commands.run.runner import Runner

        start = Runner.start
        clock = self

        def start_timed(runner):
            start(runner)
            ex = runner.clock.executor
            spin_once = clock.timed(label, ex.spin_once)

            class Timed:
                def __getattr__(self, a):
                    return getattr(ex, a)

                def spin_once(self, *a, **k):
                    return spin_once(*a, **k)

            runner.clock.executor = Timed()

        self.cpu.setdefault(label, 0.0)
        self.calls.setdefault(label, 0)
        Runner.start = start_timed


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--cprofile", type=int, default=0, metavar="N", help="also the N functions of most own time")
    a = ap.parse_args()
    from gnss_sim_ros2 import cli

    clock = StageClock()
    shown = []
    previous = ""
    for label, module, path in STAGES:
        label = previous = label or previous       # "": more entry points of the stage above
        if "spin_once" in path:
            clock.wrap_executor(label)
        elif not clock.wrap(label, module, path):
            continue
        if label not in shown:
            shown.append(label)
    out = Path(tempfile.mkdtemp(prefix="gnss_sim_prof_"))
    argv = ["run", "--realtime", "--rate", str(a.rate), "--duration", str(a.duration), "--systems", "GRECJI",
            "--out", str(out), "--quiet"]
    prof = None
    if a.cprofile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    cpu0 = time.process_time()
    code = cli.main(argv)
    cpu_process = time.process_time() - cpu0
    if prof is not None:
        prof.disable()
    if code != 0:
        print(f"gnss-sim run exited {code}", file=sys.stderr)
        return code
    s = json.loads((out / "summary.json").read_text())
    n = s["epochs"]
    print(f"\n{a.rate:g} Hz for {a.duration:g} s at real-time pace, composed: {n} epochs, "
          f"{s['epochs_without_output']} without output, latency median {s['latency_ms_median']} ms, "
          f"p99 {s['latency_ms_p99']} ms{' (under cProfile)' if prof else ''}")
    print(f"{'stage (CPU of the main thread)':56s} {'ms/epoch':>9s} {'calls/epoch':>12s}")
    for label in shown:
        print(f"{label:56s} {1e3 * clock.cpu[label] / n:9.3f} {clock.calls[label] / n:12.1f}")
    print(f"{'whole process, every thread (start-up, summary included)':56s} {1e3 * cpu_process / n:9.3f}")
    if prof is not None:
        import pstats

        print()
        pstats.Stats(prof).sort_stats("tottime").print_stats(a.cprofile)
    return 0


if __name__ == "__main__":
    sys.exit(main())

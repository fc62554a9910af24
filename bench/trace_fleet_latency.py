"""Where the ms of the fleet layout's latency go: states published -> each robot's observations published.

Runs `gnss-sim run --realtime --layout fleet --robots N` in this process with every node callback timed
(GnssSimNode.speaking wraps them all; TF's subscriptions, rclpy's /clock callbacks and the run driver's clock are
wrapped too) on one clock (time.perf_counter), and for every epoch the span from the ephemeris node's states
published to the worst robot's observations published split into: the callbacks that ran inside the span (by
node and callback, e.g. the TF messages of N trajectory players, the cast, each robot's receiver step) and the
time nothing of ours ran (the executor's and the middleware's own: delivery, dispatch). Inside the visibility
epoch and the receiver epoch the named steps (states decode, cast, visibility encode, visibility decode,
observables, observations encode) are split out too. Wall times, so run it on a quiet machine or read ratios.

    python bench/trace_fleet_latency.py [--robots 4] [--rate 10] [--duration 20] [--config FILE]
"""
from __future__ import annotations

import argparse
import collections
import functools
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gnss_sim_ros2.benchmarks.timing import wrap_attribute

EVENTS: list = []          # (t0, t1, label)
MARKS: dict = {}           # ("states", stamp) -> t; ("obs", robot label, stamp) -> t
STEPS = [
    ("visibility: states decode", "gnss_sim_ros2.nodes.fleet_visibility_node", "states_from_cdr"),
    ("visibility: cast", "gnss_sim_ros2.core.visibility.options", "VisibilityOptions.cast"),
    ("visibility: encode", "gnss_sim_ros2.nodes.fleet_visibility_node", "encode_visibility"),
    ("visibility: TF lookup", "gnss_sim_ros2.nodes.tf_source", "TfSource.lookup"),
    ("receiver: visibility decode", "gnss_sim_ros2.nodes.receiver_session", "visibility_from_cdr"),
    ("receiver: chain inputs", "gnss_sim_ros2.nodes.receiver_session", "chain_inputs_from_visibility"),
    ("receiver: observables", "gnss_sim_ros2.core.receiver.chain", "ReceiverChain.observe"),
    ("receiver: observables, every robot (batch)", "gnss_sim_ros2.nodes.fleet_receiver_node", "observe_receivers"),
    ("receiver: visibility decode", "gnss_sim_ros2.nodes.fleet_receiver_node", "visibility_from_cdr"),
    ("receiver: states decode", "gnss_sim_ros2.nodes.fleet_receiver_node", "states_from_cdr"),
    ("receiver: fix half (ReceiverChain.finish)", "gnss_sim_ros2.core.receiver.chain", "ReceiverChain.finish"),
    ("receiver: fix half (ReceiverSession.finish)", "gnss_sim_ros2.nodes.receiver_session", "ReceiverSession.finish"),
    ("rclpy Publisher.publish", "rclpy.publisher", "Publisher.publish"),
    ("receiver: fixes (finish_robots)", "gnss_sim_ros2.nodes.fleet_receiver_node", "FleetReceiverNode.finish_robots"),
]


def timed(label, inner, on_end=None):
    @functools.wraps(inner)
    def run(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            t1 = time.perf_counter()
            EVENTS.append((t0, t1, label))
            if on_end is not None:
                on_end(t1, args)
    return run


def wrap(label, module, path, on_end=None):
    # an entry point this version of the code lacks: not timed
    wrap_attribute(module, path, lambda inner: timed(label, inner, on_end))


def install():
    from gnss_sim_ros2.messages.conversions import stamp_of
    from gnss_sim_ros2.nodes import common

    speaking = common.GnssSimNode.speaking

    def speaking_timed(self, callback):
        name = getattr(callback, "__name__", "callback")
        return timed(f"cb {self.get_name()}.{name}", speaking(self, callback))

    common.GnssSimNode.speaking = speaking_timed
    for label, module, path in STEPS:
        wrap("step " + label, module, path)
    wrap("cb TF /tf message (TfSource._feed)", "gnss_sim_ros2.nodes.tf_source", "TfSource._feed")
    wrap("cb rclpy /clock (TimeSource.clock_callback)", "rclpy.time_source", "TimeSource.clock_callback")
    wrap("run driver: /clock published", "gnss_sim_ros2.commands.run.clock", "ClockDriver.set_clock")

    last_states = {}

    from gnss_sim_ros2.nodes import ephemeris_node
    encode = ephemeris_node.encode_states

    def encode_marked(*a, **k):
        data = encode(*a, **k)
        last_states["stamp"] = stamp_of(data)
        # the span starts here, the states about to be published: since the states are handed in-process the
        # whole epoch runs inside publish_epoch, so its end is the epoch's end
        MARKS[("states", last_states["stamp"])] = time.perf_counter()
        return data
    ephemeris_node.encode_states = encode_marked

    from gnss_sim_ros2.nodes import receiver_session
    encode_obs = receiver_session.encode_observations
    robots_done = collections.Counter()

    def encode_obs_marked(*a, **k):       # each robot's observations: encoded, then published at once
        t0 = time.perf_counter()
        data = encode_obs(*a, **k)
        t1 = time.perf_counter()
        EVENTS.append((t0, t1, "step receiver: observations encode"))
        stamp = stamp_of(data)
        robots_done[stamp] += 1
        MARKS[("obs", robots_done[stamp], stamp)] = t1
        return data
    receiver_session.encode_observations = encode_obs_marked

    wrap("step ephemeris: epoch published (and, handed in-process, every node's epoch)",
         "gnss_sim_ros2.nodes.ephemeris_node", "EphemerisNode.publish_epoch")
    wrap("step receiver: one robot's epoch (process)", "gnss_sim_ros2.nodes.receiver_session",
         "ReceiverSession.process")


def breakdown(skip_s: float = 2.0):
    """Per epoch (after the first ``skip_s`` of marks): latency to the worst robot, and the time inside it of
    each callback / step label (clipped to the span); 'nothing of ours' = span minus the union of callbacks."""
    states = {k[1]: t for k, t in MARKS.items() if k[0] == "states"}
    obs = collections.defaultdict(dict)
    for k, t in MARKS.items():
        if k[0] == "obs":
            obs[k[2]][k[1]] = t
    robots = max((len(v) for v in obs.values()), default=0)
    ev = sorted(EVENTS)
    starts = np.array([e[0] for e in ev])
    t_first = min(states.values())
    per_label = collections.defaultdict(list)
    lat_worst, lat_first, idle = [], [], []
    for stamp, t0 in sorted(states.items()):
        got = obs.get(stamp, {})
        if len(got) < robots or t0 - t_first < skip_s:
            continue
        t1 = max(got.values())
        lat_worst.append(1e3 * (t1 - t0))
        lat_first.append(1e3 * (min(got.values()) - t0))
        sums = collections.defaultdict(float)
        covered = []
        lo = np.searchsorted(starts, t0 - 1.0)
        for a, b, label in ev[lo:]:
            if a >= t1:
                break
            a2, b2 = max(a, t0), min(b, t1)
            if b2 <= a2:
                continue
            sums[label] += b2 - a2
            if label.startswith("cb ") or label.startswith("run driver"):
                covered.append((a2, b2))
        busy, end = 0.0, t0
        for a, b in sorted(covered):
            if b > end:
                busy += b - max(a, end)
                end = b
        idle.append(1e3 * (t1 - t0 - busy))
        for label in {e[2] for e in ev}:
            per_label[label].append(1e3 * sums.get(label, 0.0))
    return robots, lat_worst, lat_first, idle, per_label


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", type=int, default=1)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--config", default=None)
    a = ap.parse_args()
    install()
    from gnss_sim_ros2 import cli

    out = Path(tempfile.mkdtemp(prefix="gnss_sim_trace_")) / "run"
    argv = ["run", "--realtime", "--rate", str(a.rate), "--duration", str(a.duration), "--systems", "GRECJI",
            "--out", str(out), "--quiet", "--no-record", "--robots", str(a.robots), "--layout", "fleet"]
    if a.config:
        argv += ["--config", str(Path(a.config).resolve())]
    cpu0 = time.process_time()
    code = cli.main(argv)
    cpu = time.process_time() - cpu0
    if code != 0:
        return code
    s = json.loads((out / "summary.json").read_text())
    robots, worst, first, idle, per_label = breakdown()
    n = len(worst)
    print(f"\n{a.robots} robot(s), fleet layout, {a.rate:g} Hz, {a.duration:g} s: {n} epochs traced "
          f"(probe: p50 {s.get('latency_ms_median')} p99 {s.get('latency_ms_p99')} ms, robot 0); process CPU "
          f"{1e3 * cpu / max(s['epochs'], 1):.1f} ms/epoch")
    print(f"states published -> worst robot's observations published: p50 {np.median(worst):.2f} ms, p99 "
          f"{np.percentile(worst, 99):.2f} ms; first robot's p50 {np.median(first):.2f} ms")
    print(f"{'inside the span (mean ms per epoch)':60s} {'mean':>7s} {'p50':>7s}")
    rows = sorted(per_label.items(), key=lambda kv: -np.mean(kv[1]))
    for label, v in rows:
        if np.mean(v) >= 0.01:
            print(f"{label:60s} {np.mean(v):7.2f} {np.median(v):7.2f}")
    print(f"{'nothing of ours running (delivery, executor dispatch)':60s} {np.mean(idle):7.2f} {np.median(idle):7.2f}")
    total = collections.defaultdict(float)
    for t0, t1, label in EVENTS:
        total[label] += t1 - t0
    print(f"\n{'whole run, wall ms per epoch inside each (callbacks: cb, their steps: step)':76s}")
    for label, v in sorted(total.items(), key=lambda kv: -kv[1]):
        if 1e3 * v / s["epochs"] >= 0.05:
            print(f"{label:76s} {1e3 * v / s['epochs']:7.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

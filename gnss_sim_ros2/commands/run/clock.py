"""The simulated clock of ``gnss-sim run``: /clock published epoch by epoch, each epoch held until every robot's
receiver answered it (its status came), as fast as the chain answers or, with --realtime, at wall-clock pace; a
robot whose antenna frame is missing from TF stops the run (tf_tree.FrameWait); with --rtk an epoch also waits for
rtkrcv's solution, so the next one does not overtake it."""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np

from gnss_sim_ros2 import graph

#: with --realtime, /clock between two epochs steps onto the trajectory player's ticks (multiples of
#: 1 / publish_rate_hz: what a node needs between epochs is the player's TF samples) and at every epoch exactly,
#: never more often than this [s]: every message wakes every node of every process (each node's clock
#: subscription and clock-jump callbacks), 0.5 ms of CPU a message in a one-process run (bench/profile_realtime.py)
REALTIME_CLOCK_PERIOD_S = 0.01


def realtime_clock_steps_s(t_from_s: float, t_to_s: float, tick_s: float) -> list[float]:
    """The /clock values published between the epochs at ``t_from_s`` and ``t_to_s`` [s] with --realtime: the
    multiples of ``tick_s`` strictly between them (the trajectory player's ticks: each sample published when the
    clock reaches its stamp), thinned to at most one per REALTIME_CLOCK_PERIOD_S, then the epoch itself."""
    step_s = tick_s * max(1, int(np.ceil(REALTIME_CLOCK_PERIOD_S / tick_s - 1e-9)))
    first = int(np.floor(t_from_s / step_s + 1e-9)) + 1
    last = int(np.ceil(t_to_s / step_s - 1e-9)) - 1
    return [k * step_s for k in range(first, last + 1)] + [t_to_s]
#: wall seconds an epoch waits for rtkrcv's solution (gnss-sim run --rtk) before the next one starts: at least,
#: at most (the first epochs: at most), and the multiple of the median latency so far in between
RTK_WAIT_S = (0.05, 0.5)
RTK_WAIT_FACTOR = 4.0
#: wall seconds between two checks of the robots' antenna TF while an epoch waits (tf_timeout_s is seconds)
TF_CHECK_PERIOD_S = 0.005


@dataclass
class EpochsDriven:
    """What the loop did: ``code`` 0, or 1 when an antenna frame was missing from TF; ``epochs`` done,
    ``dropped`` (epochs some robot gave no output for), ``start_perf_s`` (time.perf_counter() at its start)."""
    code: int
    epochs: int
    dropped: int
    start_perf_s: float


class ClockDriver:
    """/clock of the run, published by the run's node ``driver``, and the executor spun in between."""

    def __init__(self, driver, executor):
        from rosgraph_msgs.msg import Clock

        self.driver, self.executor = driver, executor
        self.pub = driver.create_publisher(Clock, "/clock", 10)
        self.epochs_done = 0

    def set_clock(self, t_s: float):
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock

        ns = int(round(t_s * 1e9))
        self.pub.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))

    def spin(self, seconds: float):
        self.spin_until(time.perf_counter() + seconds)

    def spin_until(self, end_perf_s: float):
        """Dispatch callbacks until time.perf_counter() reaches ``end_perf_s`` (not beyond it by more than the
        executor's wake-up)."""
        while (left := end_perf_s - time.perf_counter()) > 0:
            self.executor.spin_once(timeout_sec=min(left, 0.005))

    def wait_rtk(self, outputs, t_s: float, period: float, stop) -> None:
        """Until rtkrcv's solution of the epoch at t_s is back (outputs.rtk_fix); an epoch rtkrcv does not solve
        gives none, so the wait ends after RTK_WAIT_FACTOR times the median latency so far (from the rover's
        status to its RTK solution, outputs.rtk_latency_s), within RTK_WAIT_S."""
        t0 = time.monotonic()
        lat = outputs.rtk_latency_s
        limit = RTK_WAIT_S[1] if len(lat) < 5 else min(max(RTK_WAIT_FACTOR * float(np.median(lat)), RTK_WAIT_S[0]),
                                                        RTK_WAIT_S[1])
        while time.monotonic() - t0 < limit and not stop["flag"]:
            if any(abs(s - t_s) < 0.5 * period for s in list(outputs.rtk_fix)[-3:]):
                lat.append(time.monotonic() - t0)
                return
            self.executor.spin_once(timeout_sec=0.001)

    def drive(self, cfg, args, outputs, n_epochs: int, period: float, stop, log) -> EpochsDriven:
        """The epochs 0 .. n_epochs - 1 at ``period`` [s] (or until ``stop["flag"]``); progress on stderr unless
        args.quiet; ``epochs_done`` follows the loop."""
        tf_timeout_s = cfg.node("visibility")["tf_timeout_s"]
        tick_s = 1.0 / cfg.node("trajectory")["publish_rate_hz"]
        wall0 = time.perf_counter()
        dropped = 0
        k_done = 0
        robots = outputs.robots
        antenna_frames = {r.k: (graph.node_parameters(cfg, r.spec("visibility"), args.robots) if r.k >= 0
                                else cfg.node("visibility"))["antenna_frame"] for r in robots}
        for k in range(n_epochs):
            if stop["flag"]:
                log(f"stopped after {k_done} epochs")
                break
            t_s = k * period
            if args.realtime:
                # the ticks between the epochs as wall time reaches them (one already passed: only the latest)
                steps = realtime_clock_steps_s((k - 1) * period, t_s, tick_s) if k else [t_s]
                for i, step_s in enumerate(steps[:-1]):
                    if time.perf_counter() - wall0 < steps[i + 1]:
                        self.spin_until(wall0 + step_s)
                        self.set_clock(step_s)
                self.spin_until(wall0 + t_s)
            self.set_clock(t_s)
            t_wait = time.monotonic()
            deadline = t_wait + max(10.0, tf_timeout_s + 2.0)
            next_tf_check = t_wait
            while (not all(r.answered(t_s) for r in robots) and time.monotonic() < deadline
                   and not stop["flag"]):
                self.executor.spin_once(timeout_sec=0.001)
                if time.monotonic() < next_tf_check:
                    continue
                # the missing-TF rule every TF_CHECK_PERIOD_S, not after each callback (N robots' callbacks
                # per epoch times N robots checked otherwise)
                next_tf_check = time.monotonic() + TF_CHECK_PERIOD_S
                waiting = [r for r in robots if not r.cast(t_s)]
                # one graph query per pass, not one per robot (a 16-robot run spent 40 ms per epoch in them)
                tf_publishers = self.driver.count_publishers("/tf") if waiting else 0
                late = [r for r in waiting if outputs.tf_wait.missing(
                    antenna_frames[r.k], t_s, t_wait, time.monotonic(), tf_publishers)]
                if late:
                    vis = graph.node_parameters(cfg, late[0].spec("visibility"), args.robots) \
                        if late[0].k >= 0 else cfg.node("visibility")
                    print(f"\ngnss-sim run: error: no transform from '{vis['world_frame']}' to "
                          f"'{vis['antenna_frame']}' in TF within tf_timeout_s = {tf_timeout_s:g} s at "
                          f"epoch {k} (t = {t_s:g} s): nothing publishes the robot's TF (the trajectory player, "
                          f"or Gazebo through ros_gz_bridge) or the frames are misnamed (parameters world_frame, "
                          f"antenna_frame)", file=sys.stderr)
                    self.epochs_done = k_done
                    return EpochsDriven(1, k_done, dropped, wall0)
            answered = [r.answered(t_s, every=True) for r in robots]
            if stop["flag"] and not all(answered):
                log(f"stopped after {k_done} epochs")
                break
            if not all(answered):
                dropped += 1
            if args.rtk:
                self.wait_rtk(outputs, t_s, period, stop)
            k_done = k + 1
            self.epochs_done = k_done
            if not args.quiet and (k % max(1, n_epochs // 20) == 0 or k == n_epochs - 1):
                st = outputs.status.get(t_s)
                el = time.perf_counter() - wall0
                print(f"\r[gnss-sim run] epoch {k + 1}/{n_epochs}  tracked {st.satellites_tracked if st else '-'}"
                      f"  {'fix' if st and st.solution_type else 'no fix'}  {t_s / max(el, 1e-9):.1f}x real time ",
                      end="", file=sys.stderr, flush=True)
        if not args.quiet:
            print(file=sys.stderr)
        return EpochsDriven(0, k_done, dropped, wall0)

"""``gnss-sim run``: the running system, what ``ros2 launch gnss_sim sim.launch.py`` starts.

Builds the node graph of gnss_sim_ros2/graph.py (trajectory player, ephemeris,
visibility, receiver) with the parameters of one file, in this process
(composed), one process per robot (its player, visibility and receiver; the
ephemeris node here) or one process per node, brings every node through configure and
activate, drives the simulated clock (/clock) epoch by epoch as fast as the
chain answers (or at real-time pace), records a rosbag2 (MCAP) bag, and
writes into the output folder: RINEX observation and navigation files, the
bag, a sky plot PNG and a summary.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from gnss_sim_ros2.graph import LAYOUTS

#: summary.json "mode" of each layout ("processes": one per node, as before --layout)
LAYOUT_MODES = {"composed": "composed", "robot": "robot_processes", "node": "processes"}
#: with --realtime, /clock between two epochs is published at most this often [s of wall time] (and at every
#: epoch exactly): every message wakes every node of every process (each node's clock subscription, the
#: trajectory player's timer), so a finer clock costs CPU where the epochs need it (bench/profile_realtime.py)
REALTIME_CLOCK_PERIOD_S = 0.01
LAYOUT_WORDS = {"composed": "all nodes in one process", "robot": "one process per robot",
                "node": "one process per node"}


def layout_of(args) -> str:
    """The process layout of --layout and --processes (an alias of --layout node); ValueError naming both."""
    if args.processes and args.layout not in (None, "node"):
        raise ValueError(f"options --processes (one process per node) and --layout {args.layout} do not go "
                         f"together: give one of them")
    return "node" if args.processes else (args.layout or "composed")


def add_arguments(p):
    p.add_argument("--config", help="gnss_sim parameter file (the one the launch file takes)")
    sc = p.add_mutually_exclusive_group()
    sc.add_argument("--world", metavar="SDF", help="Gazebo world (default: worlds/courtyard.sdf)")
    sc.add_argument("--mesh", metavar="FILE", help="mesh exported by export-world")
    from gnss_sim_ros2.core.scene.scene_report import ALLOW_PARTIAL_HELP
    p.add_argument("--allow-partial", action="store_true", help=ALLOW_PARTIAL_HELP)
    p.add_argument("--out", default="gnss_sim_run", metavar="DIR",
                   help="output folder [gnss_sim_run]: new, empty or one of an earlier run (only its files are "
                        "replaced); a folder holding other files is refused")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="simulated seconds [from config]")
    p.add_argument("--rate", type=float, default=None, metavar="HZ", help="epoch rate [from config]")
    p.add_argument("--systems", default=None, help="GNSS systems, letters of GRECJI")
    p.add_argument("--layout", choices=LAYOUTS, default=None,
                   help="processes: composed (every node in this one), robot (one process per robot: its player, "
                        "visibility and receiver; the ephemeris node and the recorder in this one), node (one "
                        "process per node) [composed]")
    p.add_argument("--processes", action="store_true", help="one process per node: --layout node")
    p.add_argument("--realtime", action="store_true", help="simulated time at wall-clock pace")
    p.add_argument("--no-record", action="store_true", help="do not record a bag")
    p.add_argument("--no-autostart", action="store_true",
                   help="do not configure/activate the nodes (leave them to another lifecycle manager)")
    p.add_argument("--antenna-frame", default=None, help="TF frame of the antenna [from config]")
    p.add_argument("--no-trajectory-player", action="store_true",
                   help="do not move the robot here: its TF comes from elsewhere (Gazebo + ros_gz_bridge)")
    p.add_argument("--domain-id", type=int, default=None, metavar="N",
                   help="ROS_DOMAIN_ID of the run's graph (default: a free one of its own, printed at the start)")
    p.add_argument("--rtk", action="store_true",
                   help="RTK: a base station at base_position and the rtk node (RTKLIB rtkrcv) on the rover's and "
                        "the base's RTCM3; /gnss/rtk/fix recorded, RTK figures in the summary")
    p.add_argument("--robots", type=int, default=1, metavar="N",
                   help="N robots in one graph (1..16): each its own TF frames (robot<k>/...), path (a convoy "
                        "convoy_spacing_s apart along the path, or robot_trajectory_files), visibility and receiver "
                        "node in namespace robot<k> (/robot<k>/gnss/fix, RINEX in OUT/robot<k>), one ephemeris node "
                        "and one scene for all [1]")
    p.add_argument("--quiet", action="store_true")


#: parameter -> command-line option (load_config's ``options``: errors name the option the user typed)
PARAM_OPTIONS = {"systems": "--systems", "rate_hz": "--rate", "antenna_frame": "--antenna-frame",
                 "duration_s": "--duration", "world_file": "--world", "mesh_file": "--mesh",
                 "strict_world": "--allow-partial"}


def _overrides(args) -> dict:
    shared = {}
    if args.systems is not None:
        shared["systems"] = args.systems
    if args.rate is not None:
        shared["rate_hz"] = args.rate
    if args.antenna_frame is not None:
        shared["antenna_frame"] = args.antenna_frame
    out = {"/**": shared}
    if args.world:
        out["visibility"] = {"world_file": str(Path(args.world).resolve()), "mesh_file": ""}
    if args.mesh:
        out["visibility"] = {"mesh_file": str(Path(args.mesh).resolve()), "world_file": ""}
    if getattr(args, "allow_partial", False):
        out.setdefault("visibility", {})["strict_world"] = False
    if args.duration is not None:
        out["ephemeris"] = {"duration_s": args.duration}
    if getattr(args, "rtk", False):
        out["receiver"] = {"rtcm": True}      # the rover's RTCM3 for the rtk node
    return out


def run(args) -> int:
    from gnss_sim_ros2 import graph
    from gnss_sim_ros2.parameters import check_robot_config, check_robots, load_config
    from gnss_sim_ros2.run_isolation import OutputBusy, OutputFolder, OutputNotOurs, choose_domain_id

    folder = OutputFolder(Path(args.out), command="gnss-sim run", inputs=(args.config, args.world, args.mesh))
    try:
        folder.check()           # a folder with files the run did not write: refused before anything starts
        args.robots = check_robots(args.robots, "option --robots")
        args.layout = layout_of(args)
        args.processes = args.layout == "node"
        if args.rtk and args.robots > 1:
            raise ValueError(f"options --rtk and --robots {args.robots} do not go together: an RTK run has one "
                             f"rover (and its base station); run RTK with --robots 1")
        ov = _overrides(args)
        ov["/**"]["output_dir"] = str(folder.staging)
        cfg = load_config(args.config, ov, PARAM_OPTIONS)
        check_robot_config(cfg, args.robots, "option --robots")
        robot_sections = graph.robot_parameter_sections(cfg, args.robots)   # a robot's bad path file stops here
        # the base station's (and moving baseline's) sections: a bad base_position stops here, before any start
        rtk_sections = graph.rtk_parameter_sections(cfg) if args.rtk else {}
        if args.domain_id is not None and not 0 <= args.domain_id <= 232:
            raise ValueError(f"option --domain-id is {args.domain_id}; a ROS domain id is 0..232")
    except ValueError as exc:
        print(f"gnss-sim run: error: {exc}", file=sys.stderr)
        return 2
    try:
        staging = folder.acquire()
        if args.domain_id is None:
            user = os.environ.get("ROS_DOMAIN_ID", "")
            domain, _domain_lock = choose_domain_id(avoid={int(user)} if user.isdigit() else set())
        else:
            domain = args.domain_id
    except OutputBusy as exc:
        print(f"gnss-sim run: error: {exc}", file=sys.stderr)
        return 1
    except OutputNotOurs as exc:
        print(f"gnss-sim run: error: {exc}", file=sys.stderr)
        return 2
    os.environ["ROS_DOMAIN_ID"] = str(domain)   # this process and its node processes
    import yaml

    params_file = staging / "params.yaml"
    params_file.write_text(yaml.safe_dump({**cfg.ros_parameter_file_dict(), **rtk_sections, **robot_sections},
                                          sort_keys=False))
    runner = Runner(cfg, staging, params_file, args)
    runner.domain_id = domain
    for old in folder.stale:
        runner.warn(f"note: {old} holds the outputs of a run that was killed; left as it is")
    stop = {"flag": False, "signal": 0}

    def on_signal(signum, _frame):
        stop["flag"] = True
        stop["signal"] = signum

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    code = 1
    try:
        code = runner.run(stop)
    finally:
        runner.close()
        if runner.epochs_done > 0:
            try:
                folder.commit()
                runner.log(f"outputs in {folder.final}")
            except OutputNotOurs as exc:    # a foreign file appeared under one of the run's names meanwhile
                runner.warn(f"gnss-sim run: error: {exc}")
                code = code or 1
        else:
            folder.abandon()
            if folder.final.exists():
                runner.log(f"nothing produced: the previous results in {folder.final} are left untouched")
    if stop["signal"] and code == 0:
        return 128 + stop["signal"]       # the convention: 130 after SIGINT, 143 after SIGTERM
    return code


class Runner:
    def __init__(self, cfg, out: Path, params_file: Path, args):
        self.cfg, self.out, self.params_file, self.args = cfg, out, params_file, args
        self.procs: list[subprocess.Popen] = []
        self.local = []
        self.executor = None
        self.recorder = None
        self.manager = None
        self.started = False
        self.epochs_done = 0
        self.domain_id = None
        self.foreign: dict = {}
        self.configure_wall_s = self.peak_rss_mb = None
        self.robots: list[RobotOutputs] = []
        self.proc_names: list[str] = []     # of self.procs: the node's path, or robot<k> (--layout robot)
        self.cpu0: dict = {}

    def log(self, text: str):
        if not self.args.quiet:
            print(f"[gnss-sim run] {text}", file=sys.stderr, flush=True)

    @staticmethod
    def warn(text: str):
        """Printed even with --quiet."""
        print(f"[gnss-sim run] {text}", file=sys.stderr, flush=True)

    # ------------------------------------------------------------------ graph
    def start(self):
        import rclpy
        from rosgraph_msgs.msg import Clock

        from gnss_sim_ros2 import graph
        from gnss_sim_ros2.nodes.manager import LocalNodes, OrderedNodes, RemoteNodes

        # our own SIGINT/SIGTERM handlers end the loop (summary, sky plot, files closed); rclpy's would shut
        # the context down under the running executor
        rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.rclpy = rclpy
        from gnss_sim_ros2.nodes.common import executor_name, make_executor

        self.executor = make_executor()      # every composed node's callbacks: the EventsExecutor where rclpy has it
        self.executor_name = executor_name(self.executor)
        self.driver = rclpy.create_node("gnss_sim_run")
        self.executor.add_node(self.driver)
        self.clock_pub = self.driver.create_publisher(Clock, "/clock", 10)
        self._subscribe_outputs()
        self.set_clock(0.0)
        if not self.args.no_record:
            from gnss_sim_ros2.recorder import BagRecorder

            self.recorder = BagRecorder(self.driver, self.out / "bag", graph.recorded(self.args.robots)
                                        + (graph.RECORDED_RTK if self.args.rtk else ()))
        specs = self.specs()
        layout = self.args.layout
        elsewhere = {"composed": [], "node": specs,
                     "robot": [s for s in specs if graph.robot_of(s) is not None]}[layout]
        if elsewhere:
            from gnss_sim_ros2.run_isolation import die_with_parent

            params = str(self.params_file)
            if layout == "node":
                cmds = {s.path: [sys.executable, "-m", s.module] + graph.ros_args(s, params, True) for s in specs}
            else:       # one process per robot: its nodes in one executor (nodes/group.py)
                cmds = {}
                for k, group in graph.robot_groups(specs).items():
                    cmds[robot_process_name(k, self.args.robots)] = [
                        sys.executable, "-m", "gnss_sim_ros2.nodes.group",
                        *(a for s in group
                          for a in ["--node", f"{s.module}:{s.cls}", *graph.ros_args(s, params, True)])]
            env = dict(os.environ)
            for name, cmd in cmds.items():
                self.procs.append(subprocess.Popen(cmd, env=env, preexec_fn=die_with_parent))
                self.proc_names.append(name)
        import importlib

        from rclpy.parameter import Parameter

        for spec in specs:
            if spec in elsewhere:
                continue
            cls = getattr(importlib.import_module(spec.module), spec.cls)
            overrides = [Parameter("use_sim_time", value=True)] + [
                Parameter(k, value=v) for k, v in graph.node_parameters(self.cfg, spec, self.args.robots).items()
                if not (isinstance(v, list) and not v)]
            node = cls(parameter_overrides=overrides, cli_args=graph.ros_args(spec, None, True)[:-2])
            self.local.append(node)
            self.executor.add_node(node)
        if layout == "composed":
            self.manager = LocalNodes(self.local)
        else:           # in the graph's order, wherever each node is
            local = iter(self.local)
            parts = [RemoteNodes(self.driver, [s.path], self.executor) if s in elsewhere else LocalNodes([next(local)])
                     for s in specs]
            for part in parts:
                if isinstance(part, RemoteNodes):
                    part.wait_for_services()
            self.manager = OrderedNodes(parts)
        self.started = True

    def _subscribe_outputs(self):
        from gnss_sim_msgs.msg import Observations, SatelliteStates
        from sensor_msgs.msg import NavSatFix

        from gnss_sim_ros2.nodes.latency_probe import LatencyProbe

        self._subs = []
        n = self.args.robots
        self.robots = [RobotOutputs(self.driver, k if n > 1 else -1) for k in range(n)]
        # how far TF has come: the missing-frame rule of the wait for an epoch's visibility (tf_tree.FrameWait; a
        # second later than the visibility node's own, whose error comes first)
        from tf2_msgs.msg import TFMessage

        from gnss_sim_ros2.tf_tree import FrameWait

        self.tf_wait = FrameWait(self.cfg.node("visibility")["tf_timeout_s"] + 1.0)
        self._subs.append(self.driver.create_subscription(
            TFMessage, "/tf", lambda m: self.tf_wait.seen_transforms(m.transforms, time.monotonic()), 100))
        r0 = self.robots[0]              # one robot: the run's outputs (the RTK figures use its truth)
        self.status, self.fix, self.truth = r0.status, r0.fix, r0.truth
        # latency: the states published -> each robot's observations published (the middleware's publication
        # times, read by a node of its own)
        self.probe = LatencyProbe(self.driver.context, ("/gnss/satellite_states", SatelliteStates),
                                  [(r.topic(name), msg_type) for r in self.robots
                                   for name, msg_type in (("observations", Observations), ("fix", NavSatFix))])
        if self.args.rtk:
            self._subscribe_rtk()

    @property
    def last_vis(self):
        """Robot 0's last gnss_sim_msgs/Visibility (kept serialised during the run)."""
        return self.robots[0].last_vis_msg()

    def specs(self):
        """The nodes of this run (graph.nodes, and the RTK ones with --rtk)."""
        from gnss_sim_ros2 import graph

        return (graph.nodes(not self.args.no_trajectory_player, self.args.robots)
                + (graph.rtk_nodes(self.cfg) if self.args.rtk else []))

    def _subscribe_rtk(self):
        from diagnostic_msgs.msg import DiagnosticStatus
        from sensor_msgs.msg import NavSatFix

        self.rtk_fix, self.rtk_quality = {}, {}
        self.rtk_latency_s: list[float] = []       # wall time from the rover's status to its RTK solution

        def on_fix(m):
            self.rtk_fix[m.header.stamp.sec + m.header.stamp.nanosec * 1e-9] = m

        def on_status(m):
            v = {kv.key: kv.value for kv in m.values}
            if v.get("stamp"):
                self.rtk_quality[round(float(v["stamp"]) * 1e6)] = v["quality"]   # [us]: the fix's stamp

        self._subs += [self.driver.create_subscription(NavSatFix, "/gnss/rtk/fix", on_fix, 1000),
                       self.driver.create_subscription(DiagnosticStatus, "/gnss/rtk/status", on_status, 1000)]
        if self.cfg.node("receiver")["antenna2_frame"]:
            self._subscribe_heading()

    def _subscribe_heading(self):
        """The moving baseline: rtkrcv's headings, their quality, and the second antenna's true position."""
        from diagnostic_msgs.msg import DiagnosticStatus
        from gnss_sim_msgs.msg import Visibility
        from sensor_msgs.msg import Imu

        self.heading, self.heading_quality, self.truth2 = {}, {}, {}

        def stamp(m):
            return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9

        def on_heading(m):
            self.heading[stamp(m)] = m

        def on_status(m):
            v = {kv.key: kv.value for kv in m.values}
            if v.get("stamp"):
                self.heading_quality[round(float(v["stamp"]) * 1e6)] = v["quality"]

        def on_vis(m):
            self.truth2[stamp(m)] = np.array([m.antenna_ecef_m.x, m.antenna_ecef_m.y, m.antenna_ecef_m.z])

        d = self.driver
        self._subs += [d.create_subscription(Imu, "/gnss/rtk/heading", on_heading, 1000),
                       d.create_subscription(DiagnosticStatus, "/gnss/heading/status", on_status, 1000),
                       d.create_subscription(Visibility, "/gnss/antenna2/visibility", on_vis, 1000)]

    def wait_rtk(self, t_s: float, period: float, stop) -> None:
        """With --rtk: until rtkrcv's solution of the epoch at t_s is back, so the next epoch does not overtake
        it; an epoch rtkrcv does not solve gives none, so the wait ends after RTK_WAIT_FACTOR times the median
        latency so far (from the rover's status to its RTK solution), within RTK_WAIT_S."""
        if not self.args.rtk:
            return
        t0 = time.monotonic()
        lat = self.rtk_latency_s
        limit = RTK_WAIT_S[1] if len(lat) < 5 else min(max(RTK_WAIT_FACTOR * float(np.median(lat)), RTK_WAIT_S[0]),
                                                        RTK_WAIT_S[1])
        while time.monotonic() - t0 < limit and not stop["flag"]:
            if any(abs(s - t_s) < 0.5 * period for s in list(self.rtk_fix)[-3:]):
                lat.append(time.monotonic() - t0)
                return
            self.executor.spin_once(timeout_sec=0.001)

    def set_clock(self, t_s: float):
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock

        ns = int(round(t_s * 1e9))
        self.clock_pub.publish(Clock(clock=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))

    def spin(self, seconds: float):
        self.spin_until(time.perf_counter() + seconds)

    def spin_until(self, end_perf_s: float):
        """Dispatch callbacks until time.perf_counter() reaches ``end_perf_s`` (not beyond it by more than the
        executor's wake-up)."""
        while (left := end_perf_s - time.perf_counter()) > 0:
            self.executor.spin_once(timeout_sec=min(left, 0.005))

    # ------------------------------------------------------------------ run
    def run(self, stop) -> int:
        from gnss_sim_ros2 import graph
        from gnss_sim_ros2.nodes.manager import TransitionFailed

        eph = self.cfg.node("ephemeris")
        duration = eph["duration_s"]
        period = 1.0 / eph["rate_hz"]
        n_epochs = int(np.floor(duration / period + 1e-9)) + 1
        tf_timeout_s = self.cfg.node("visibility")["tf_timeout_s"]
        self.log(f"starting {LAYOUT_WORDS[self.args.layout]}; "
                 f"{n_epochs} epochs of {period:g} s; ROS_DOMAIN_ID={self.domain_id}; output {self.out}")
        try:
            self.start()
            if self.args.no_autostart:
                self.log("--no-autostart: waiting for another lifecycle manager (Ctrl-C to stop)")
                while not stop["flag"]:
                    self.spin(0.1)
                return 0
            t_configure = time.perf_counter()
            self.manager.transition("configure")
            self.configure_wall_s = time.perf_counter() - t_configure
            self.peak_rss_mb = _proc_peak_rss_mb(os.getpid())   # every node when composed
            self.log(f"{self.args.robots} robot(s) configured in {self.configure_wall_s:.2f} s (scene, ephemeris, "
                     f"receivers), peak memory of this process "
                     f"{'unknown' if self.peak_rss_mb is None else f'{self.peak_rss_mb:.0f} MB'}")
            self.manager.transition("activate")
        except TransitionFailed as exc:
            print(f"gnss-sim run: error: {exc}", file=sys.stderr)
            return 3
        self.spin(0.3)  # let the recorder find the topics and TF static latch
        self.foreign = self.foreign_publishers()
        self.states_publishers = sorted(
            f"{i.node_namespace.rstrip('/')}/{i.node_name}"
            for i in self.driver.get_publishers_info_by_topic(f"{graph.TOPIC_NAMESPACE}/satellite_states"))
        for topic, nodes in self.foreign.items():
            self.warn(f"warning: {topic} has publishers outside this run's graph: {', '.join(nodes)}")
        wall0 = time.perf_counter()
        self.cpu0 = self.cpu_s()
        dropped = 0
        k_done = 0
        antenna_frames = {r.k: (graph.node_parameters(self.cfg, r.spec("visibility"), self.args.robots) if r.k >= 0
                                else self.cfg.node("visibility"))["antenna_frame"] for r in self.robots}
        for k in range(n_epochs):
            if stop["flag"]:
                self.log(f"stopped after {k_done} epochs")
                break
            t_s = k * period
            if self.args.realtime:
                while (now_s := time.perf_counter() - wall0) < t_s:
                    self.set_clock(now_s)
                    self.spin_until(wall0 + min(t_s, now_s + REALTIME_CLOCK_PERIOD_S))
            self.set_clock(t_s)
            t_wait = time.monotonic()
            deadline = t_wait + max(10.0, tf_timeout_s + 2.0)
            while (not all(r.answered(t_s) for r in self.robots) and time.monotonic() < deadline
                   and not stop["flag"]):
                self.executor.spin_once(timeout_sec=0.001)
                late = [r for r in self.robots if not r.cast(t_s) and self.tf_wait.missing(
                    antenna_frames[r.k], t_s, t_wait, time.monotonic(), self.driver.count_publishers("/tf"))]
                if late:
                    vis = graph.node_parameters(self.cfg, late[0].spec("visibility"), self.args.robots) \
                        if late[0].k >= 0 else self.cfg.node("visibility")
                    print(f"\ngnss-sim run: error: no transform from '{vis['world_frame']}' to "
                          f"'{vis['antenna_frame']}' in TF within tf_timeout_s = {tf_timeout_s:g} s at "
                          f"epoch {k} (t = {t_s:g} s): nothing publishes the robot's TF (the trajectory player, "
                          f"or Gazebo through ros_gz_bridge) or the frames are misnamed (parameters world_frame, "
                          f"antenna_frame)", file=sys.stderr)
                    self.epochs_done = k_done
                    return 1
            answered = [r.answered(t_s, every=True) for r in self.robots]
            if stop["flag"] and not all(answered):
                self.log(f"stopped after {k_done} epochs")
                break
            if not all(answered):
                dropped += 1
            self.wait_rtk(t_s, period, stop)
            k_done = k + 1
            self.epochs_done = k_done
            if not self.args.quiet and (k % max(1, n_epochs // 20) == 0 or k == n_epochs - 1):
                st = self.status.get(t_s)
                el = time.perf_counter() - wall0
                print(f"\r[gnss-sim run] epoch {k + 1}/{n_epochs}  tracked {st.satellites_tracked if st else '-'}"
                      f"  {'fix' if st and st.solution_type else 'no fix'}  {t_s / max(el, 1e-9):.1f}x real time ",
                      end="", file=sys.stderr, flush=True)
        if not self.args.quiet:
            print(file=sys.stderr)
        self.spin(0.3)
        wall = time.perf_counter() - wall0
        self.process_figures = self._process_figures(k_done)
        self.finish(k_done, dropped, wall, period)
        return 0

    def cpu_s(self) -> dict:
        """CPU time [s] (user + system) so far of this process and of each node process (None: unknown)."""
        out = {"gnss_sim_run": time.process_time()}
        for name, p in zip(self.proc_names, self.procs):
            out[name] = _proc_cpu_s(p.pid)
        return out

    def _process_figures(self, n_epochs: int) -> dict:
        """{process: CPU time per epoch [ms] over the epochs, peak memory [MB]} of this process and its node
        processes (before they stop)."""
        cpu1 = self.cpu_s()
        pids = {"gnss_sim_run": os.getpid(), **{n: p.pid for n, p in zip(self.proc_names, self.procs)}}
        out = {}
        for name, pid in pids.items():
            a, b = self.cpu0.get(name), cpu1.get(name)
            out[name] = {"cpu_ms_per_epoch": round(1e3 * (b - a) / n_epochs, 2) if None not in (a, b) and n_epochs
                         else None, "peak_rss_mb": _proc_peak_rss_mb(pid)}
        return out

    def foreign_publishers(self) -> dict[str, list[str]]:
        """{topic: nodes} of publishers on the run's topics that are not nodes of its graph."""
        from gnss_sim_ros2 import graph

        ours = {s.name for s in graph.nodes() + graph.rtk_nodes(self.cfg)} | {"gnss_sim_run"}
        out = {}
        for topic in dict.fromkeys(t for topics in graph.robot_topics(self.args.robots) for t in topics):
            others = sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}"
                             for i in self.driver.get_publishers_info_by_topic(topic) if i.node_name not in ours})
            if others:
                out[topic] = others
        return out

    def finish(self, n_epochs: int, dropped: int, wall_s: float, period: float):
        """Close the files (nodes cleaned up), then summary, sky plot and bag counts."""
        sky = self._local_sky()    # before cleanup frees the visibility node's scene
        self.shutdown_nodes()
        if self.recorder is not None:
            self.recorder.close()
        summary = self.summary(n_epochs, dropped, wall_s, period)
        (self.out / "summary.json").write_text(json.dumps(summary, indent=2))
        (self.out / "summary.md").write_text(_summary_markdown(summary))
        self.sky_plot(sky)
        print(_summary_markdown(summary))

    def _antenna_world_m(self):
        m = self.last_vis
        return None if m is None else np.array([m.antenna_world_m.x, m.antenna_world_m.y, m.antenna_world_m.z])

    def _local_sky(self):
        """The skyline at the last antenna position from the visibility node of this process (composed
        mode); None when the nodes run in other processes."""
        at = self._antenna_world_m()
        scenes = [node.scene for node in self.local if getattr(node, "scene", None) is not None]
        return scenes[0].sky_grid(at) if at is not None and scenes else None

    def summary(self, n_epochs, dropped, wall_s, period) -> dict:
        per_robot = [r.samples(self.probe) for r in self.robots]
        pooled = {key: [x for one in per_robot for x in one[key]] for key in per_robot[0]}
        n = len(self.robots)
        figures = _figures(pooled, n_epochs * n)
        rinex = sorted(str(p.relative_to(self.out)) for p in self.out.glob("*.rnx"))
        if n > 1:
            rinex += sorted(str(p.relative_to(self.out)) for p in self.out.glob("robot*/*.rnx"))
        out = {
            "epochs": n_epochs, "epochs_without_output": dropped, "wall_s": round(wall_s, 3),
            "realtime_factor": round(n_epochs * period / wall_s, 2) if wall_s > 0 else None,
            **figures,
            "mode": LAYOUT_MODES[self.args.layout],
            "executor": self.executor_name,
            "processes": getattr(self, "process_figures", {}),
            "ros_domain_id": self.domain_id,
            "foreign_publishers": self.foreign,
            "satellite_states_publishers": getattr(self, "states_publishers", None),
            "pace": "realtime" if self.args.realtime else "as fast as the chain answers",
            "rinex_files": rinex,
            "configure_wall_s": round(self.configure_wall_s, 3) if self.configure_wall_s is not None else None,
            "peak_rss_mb": round(self.peak_rss_mb, 1) if self.peak_rss_mb is not None else None,
        }
        if n > 1:
            from gnss_sim_ros2.core.simulation import SCENE_LOADS

            out["robots"] = n
            out["scene_loads"] = dict(SCENE_LOADS)     # this process's: one world for every composed robot
            out["per_robot"] = {r.name: {"epochs_without_output": n_epochs - r.epochs_answered(n_epochs, period),
                                         **_figures(one, n_epochs)}
                                for r, one in zip(self.robots, per_robot)}
            out["worst_robot"] = _worst(out["per_robot"])
        if self.args.rtk:
            out.update(self.rtk_summary(n_epochs, period))
        if self.recorder is not None:
            from gnss_sim_ros2.recorder import count_messages

            out["bag"] = "bag"      # relative: the folder is moved into place at the end
            out["bag_messages"] = count_messages(self.out / "bag")
        return out

    def rtk_summary(self, n_epochs: int, period: float) -> dict:
        """RTK figures: epochs with a /gnss/rtk/fix, fixed / float / single shares, horizontal error against the
        true antenna path (fixed solutions; every solution), and the time line (rtk_timeline.csv)."""
        from gnss_sim_ros2.core.rtk.summary import rtk_figures

        truth = {int(round(t / period)): x for t, x in self.truth.items()}
        rows = []
        for t, f in sorted(self.rtk_fix.items()):
            k = int(round(t / period))
            if not 0 <= k < n_epochs or k not in truth:
                continue
            quality = self.rtk_quality.get(round(t * 1e6), "unknown")
            rows.append((k * period, quality, f.latitude, f.longitude, f.altitude, truth[k]))
        figures, timeline = rtk_figures(rows, n_epochs, period)
        lat = self.rtk_latency_s
        figures["rtk_latency_ms_median"] = round(1e3 * float(np.median(lat)), 2) if lat else None
        figures["rtk_latency_ms_p95"] = round(1e3 * float(np.percentile(lat, 95)), 2) if lat else None
        (self.out / "rtk_timeline.csv").write_text(timeline)
        if self.cfg.node("receiver")["antenna2_frame"]:
            figures.update(self.heading_summary(n_epochs, period, truth))
        return figures

    def heading_summary(self, n_epochs: int, period: float, truth: dict) -> dict:
        """Moving baseline: headings against the true baseline first -> second antenna."""
        from gnss_sim_ros2.core.rtk.summary import heading_figures

        truth2 = {int(round(t / period)): x for t, x in self.truth2.items()}
        rows = []
        for t, m in sorted(self.heading.items()):
            k = int(round(t / period))
            if not 0 <= k < n_epochs or k not in truth or k not in truth2:
                continue
            yaw_enu_deg = float(np.degrees(2.0 * np.arctan2(m.orientation.z, m.orientation.w)))
            sd_deg = float(np.degrees(np.sqrt(max(m.orientation_covariance[8], 0.0))))
            rows.append((k * period, self.heading_quality.get(round(t * 1e6), "unknown"), 90.0 - yaw_enu_deg,
                         sd_deg, truth[k], truth2[k]))
        return heading_figures(rows, n_epochs)

    def sky_plot(self, sky=None):
        """skyplot.png of the last epoch; ``sky``: what the casts find (Scene.sky_grid) if known, else the scene
        is loaded here
        (nodes in other processes)."""
        m = self.last_vis
        if m is None:
            return
        from gnss_sim_ros2.core.skyplot import plot_skyplot

        at = self._antenna_world_m()
        if sky is None:
            from gnss_sim_ros2.core.scene.demo_world import demo_world_path
            from gnss_sim_ros2.core.simulation import load_scene

            vis = self.cfg.node("visibility")
            world = vis["world_file"] if vis["world_file"] or vis["mesh_file"] else str(demo_world_path())
            from gnss_sim_ros2.core.receiver.chain import VisibilityOptions

            sky = load_scene(world, vis["mesh_file"], vis["materials_file"],
                                 VisibilityOptions.from_params(vis)).sky_grid(at)
        sats = m.satellites
        plot_skyplot(self.out / "skyplot.png", [s.sv for s in sats], np.array([s.azimuth_deg for s in sats]),
                     np.array([s.elevation_deg for s in sats]), np.array([s.state for s in sats]),
                     sky=sky, mask_deg=self.cfg.node("receiver")["elevation_mask_deg"],
                     title=f"last epoch, antenna at E {at[0]:.1f} N {at[1]:.1f} U {at[2]:.1f} m")

    def shutdown_nodes(self):
        if self.manager is None:
            return
        from gnss_sim_ros2.nodes.manager import TransitionFailed

        try:
            self.manager.transition("deactivate")
            self.manager.transition("cleanup")
        except TransitionFailed as exc:
            self.log(f"shutdown: {exc}")
        self.manager = None

    def close(self):
        if not self.started:
            return
        try:
            self.shutdown_nodes()
        except Exception as exc:  # noqa: BLE001 - still close the bag and stop the processes
            self.log(f"shutdown: {exc}")
        if self.recorder is not None:
            self.recorder.close()
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        for n in self.local:
            self.executor.remove_node(n)
            n.destroy_node()
        self.probe.close()
        self.driver.destroy_node()
        self.rclpy.try_shutdown()
        self.started = False


#: wall seconds an epoch waits for rtkrcv's solution (gnss-sim run --rtk) before the next one starts: at least,
#: at most (the first epochs: at most), and the multiple of the median latency so far in between
RTK_WAIT_S = (0.05, 0.5)
RTK_WAIT_FACTOR = 4.0


def _summary_markdown(s: dict) -> str:
    lines = ["# gnss_sim run summary", "", "| figure | value |", "|---|---|"]
    for k, v in s.items():
        if k == "bag_messages":
            v = ", ".join(f"{t}: {n}" for t, n in sorted(v.items()))
        if k == "per_robot":
            continue
        lines.append(f"| {k} | {v} |")
    if "per_robot" in s:
        cols = list(next(iter(s["per_robot"].values())))
        lines += ["", "| robot | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
        lines += [f"| {name} | " + " | ".join(str(f[c]) for c in cols) + " |" for name, f in s["per_robot"].items()]
    return "\n".join(lines) + "\n"


def _stamp_s(m) -> float:
    return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9


class RobotOutputs:
    """What the run reads of one robot's receiver chain: status, fix and the visibility's true antenna
    position (the latency: the run's LatencyProbe), on the robot's topics (graph.robot_topic: /robot<k>/gnss/...;
    ``k`` = -1: the one robot of a run, /gnss/...)."""

    def __init__(self, driver, k: int):
        from gnss_sim_msgs.msg import ReceiverStatus, Visibility
        from sensor_msgs.msg import NavSatFix

        from gnss_sim_ros2.parameters import robot_namespace

        self.k = k
        self.name = robot_namespace(max(k, 0))
        from gnss_sim_ros2.conversions import stamp_of, visibility_antenna

        self.status, self.fix, self.truth = {}, {}, {}
        self.last_vis = None

        def on_status(m):
            self.status[_stamp_s(m)] = m

        def on_fix(m):
            self.fix[_stamp_s(m)] = m

        def on_vis(data):
            # raw: no message object per satellite in the chain's executor (the last one is read at the end)
            sec, nanosec = stamp_of(data)
            self.truth[sec + nanosec * 1e-9] = visibility_antenna(data)[1]
            self.last_vis = data

        topic = self.topic
        self.subs = [driver.create_subscription(ReceiverStatus, topic("status"), on_status, 100),
                     driver.create_subscription(NavSatFix, topic("fix"), on_fix, 100),
                     driver.create_subscription(Visibility, topic("visibility"), on_vis, 100, raw=True)]

    def topic(self, name: str) -> str:
        """This robot's topic ``name`` (/robot<k>/gnss/<name>, or /gnss/<name> for the one robot of a run)."""
        from gnss_sim_ros2 import graph

        return graph.robot_topic(self.k, f"{graph.TOPIC_NAMESPACE}/{name}")

    def last_vis_msg(self):
        """The last gnss_sim_msgs/Visibility (kept serialised during the run); None before the first."""
        if isinstance(self.last_vis, bytes):
            from gnss_sim_msgs.msg import Visibility
            from rclpy.serialization import deserialize_message

            self.last_vis = deserialize_message(self.last_vis, Visibility)
        return self.last_vis

    def spec(self, key: str):
        """This robot's node of ``key`` (graph.ROBOT_KEYS)."""
        from gnss_sim_ros2 import graph

        return graph.robot_spec(next(n for n in graph.NODES if n.key == key), self.k)

    def answered(self, t_s: float, every: bool = False) -> bool:
        """The receiver's status of the epoch at t_s came (``every``: searched among all, else the last 3)."""
        stamps = self.status if every else list(self.status)[-3:]
        return any(abs(s - t_s) < 1e-6 for s in stamps)

    def cast(self, t_s: float) -> bool:
        """The visibility of the epoch at t_s came (the antenna's TF was there)."""
        return any(abs(s - t_s) < 1e-6 for s in list(self.truth)[-3:])

    def epochs_answered(self, n_epochs: int, period: float) -> int:
        return len({int(round(t / period)) for t in self.status} & set(range(n_epochs)))

    def samples(self, probe) -> dict:
        """Per-epoch samples: satellites tracked, fixes, horizontal errors against the true antenna [m],
        latency states -> observations [ms]."""
        from gnss_sim_ros2.core.frames import ecef_to_enu, ecef_to_geodetic, geodetic_to_ecef

        err = []
        for t, f in self.fix.items():
            if f.status.status < 0 or t not in self.truth:
                continue
            est = np.array(geodetic_to_ecef(f.latitude, f.longitude, f.altitude))
            lat, lon, h = ecef_to_geodetic(*self.truth[t])
            d = ecef_to_enu(est, lat, lon, h)
            err.append(float(np.hypot(d[0], d[1])))
        return {"tracked": [m.satellites_tracked for m in self.status.values()],
                "fixes": [1 for m in self.fix.values() if m.status.status >= 0], "err": err,
                "lat_ms": probe.latencies_ms(self.topic("observations")),
                "fix_lat_ms": probe.latencies_ms(self.topic("fix"))}


def _figures(x: dict, n_epochs: int) -> dict:
    """The run's figures from RobotOutputs.samples (of one robot, or pooled over several)."""
    tracked, err, lat_ms = x["tracked"], x["err"], x["lat_ms"]

    def r(v, nd=3):
        return round(float(v), nd)

    return {
        "satellites_tracked_mean": r(np.mean(tracked), 2) if tracked else 0,
        "satellites_tracked_min": int(min(tracked)) if tracked else 0,
        "satellites_tracked_max": int(max(tracked)) if tracked else 0,
        "fix_availability": round(len(x["fixes"]) / max(n_epochs, 1), 4),
        "horizontal_error_rms_m": r(np.sqrt(np.mean(np.square(err)))) if err else None,
        "horizontal_error_p95_m": r(np.percentile(err, 95)) if err else None,
        "latency_ms_median": r(np.median(lat_ms)) if lat_ms else None,
        "latency_ms_p95": r(np.percentile(lat_ms, 95)) if lat_ms else None,
        "latency_ms_p99": r(np.percentile(lat_ms, 99)) if lat_ms else None,
        # states published -> NavSatFix published (the fix follows the observations: ReceiverChain.finish)
        "fix_latency_ms_median": r(np.median(x["fix_lat_ms"])) if x["fix_lat_ms"] else None,
        "fix_latency_ms_p99": r(np.percentile(x["fix_lat_ms"], 99)) if x["fix_lat_ms"] else None,
    }


#: figures of the worst robot: the lowest (min) or highest (max) value among the robots
WORST_BY = {"fix_availability": min, "horizontal_error_rms_m": max, "latency_ms_median": max,
            "latency_ms_p95": max, "latency_ms_p99": max, "epochs_without_output": max}


def _worst(per_robot: dict) -> dict:
    """{figure: {"robot": name, "value": v}} of the worst robot per figure (WORST_BY)."""
    out = {}
    for key, pick in WORST_BY.items():
        have = {name: f[key] for name, f in per_robot.items() if f.get(key) is not None}
        if have:
            name = pick(have, key=have.get)
            out[key] = {"robot": name, "value": have[name]}
    return out


def robot_process_name(k: int, robots: int) -> str:
    """The name of robot k's process in the summary (--layout robot)."""
    from gnss_sim_ros2.parameters import robot_namespace

    return robot_namespace(k) if robots > 1 else "robot"


def _proc_cpu_s(pid: int) -> float | None:
    """CPU time [s] (user + system) of a process so far (Linux /proc/<pid>/stat: fields 14, 15 in clock ticks)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _proc_peak_rss_mb(pid: int) -> float | None:
    """Peak resident memory of a process [MB] (Linux /proc/<pid>/status VmHWM, kB)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return round(int(line.split()[1]) / 1024.0, 1)
    except OSError:
        pass
    return None

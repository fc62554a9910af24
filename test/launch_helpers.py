"""What the launch tests share: a probe node in the test process (a simulated /clock, the
fixes, lifecycle and composition service calls), the ``ros2`` command line, RINEX epochs, the launch of
sim.launch.py with a configuration file of the test's own, the checks of the robot launch tests."""
from __future__ import annotations

import os
import subprocess
import threading
import time
from pathlib import Path

import launch
import launch_testing.actions
import launch_testing.asserts
import numpy as np
import rclpy
import yaml
from ament_index_python.packages import get_package_share_directory
from builtin_interfaces.msg import Time
from launch.launch_description_sources import PythonLaunchDescriptionSource
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import NavSatFix, NavSatStatus

from gnss_sim_ros2 import graph

#: the graph's lifecycle nodes, upstream first
NODES = tuple(s.name for s in graph.NODES)
TRANSITION_IDS = {
    "configure": Transition.TRANSITION_CONFIGURE, "activate": Transition.TRANSITION_ACTIVATE,
    "deactivate": Transition.TRANSITION_DEACTIVATE, "cleanup": Transition.TRANSITION_CLEANUP,
    "shutdown": Transition.TRANSITION_ACTIVE_SHUTDOWN,
}


def stamp_s(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


class Probe:
    """One node of the test process, spun in a background thread; publishes /clock at ``speed``x."""

    def __init__(self, speed: float):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("gnss_sim_launch_probe", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.lock = threading.Lock()
        self.fixes: list[NavSatFix] = []
        self.node.create_subscription(NavSatFix, "/gnss/fix", self._on_fix, 100)
        self.speed = speed
        self.clock_ns = None  # None: no /clock yet
        self._clock_pub = self.node.create_publisher(Clock, "/clock", 10)
        self._wall0 = None
        self.node.create_timer(0.01, self._tick_clock)  # wall (steady) clock: the probe is not on sim time
        self._clients: dict = {}
        self._stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def _on_fix(self, msg):
        with self.lock:
            self.fixes.append(msg)

    def _tick_clock(self):
        if self._wall0 is None:
            return
        ns = int((time.monotonic() - self._wall0) * self.speed * 1e9)
        self.clock_ns = ns
        self._clock_pub.publish(Clock(clock=Time(sec=ns // 10**9, nanosec=ns % 10**9)))

    def start_clock(self):
        self._wall0 = time.monotonic()

    def fixes_copy(self) -> list[NavSatFix]:
        with self.lock:
            return list(self.fixes)

    def wait_for(self, predicate, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return True
            time.sleep(0.1)
        return predicate()

    # ----------------------------------------------------------------- services
    def call(self, srv_type, name: str, request, timeout_s: float = 30.0):
        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = self.node.create_client(srv_type, name)
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise AssertionError(f"service {name} did not appear within {timeout_s} s")
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(timeout_s):
            raise AssertionError(f"service {name}: no answer within {timeout_s} s")
        return future.result()

    def state(self, node: str) -> str:
        return self.call(GetState, f"/{node}/get_state", GetState.Request()).current_state.label

    def state_or_none(self, node: str):
        """The node's lifecycle state, None while it does not answer."""
        try:
            return self.state(node)
        except AssertionError:
            return None

    def transition(self, node: str, name: str) -> bool:
        req = ChangeState.Request()
        req.transition.id = TRANSITION_IDS[name]
        return self.call(ChangeState, f"/{node}/change_state", req, timeout_s=120.0).success

    def publishers_of(self, node: str) -> set[str]:
        return {t for t, _ in self.node.get_publisher_names_and_types_by_node(node, "/")}

    def close(self):
        self._stop = True
        self.thread.join(timeout=5)
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)


class RobotFixes:
    """Each robot's fixes (/robot<k>/gnss/fix), gathered on the probe's node."""

    def __init__(self, probe: Probe, robots: int):
        self.lock = threading.Lock()
        self.fixes: dict[int, list[NavSatFix]] = {k: [] for k in range(robots)}
        for k in range(robots):
            probe.node.create_subscription(NavSatFix, f"/robot{k}/gnss/fix", lambda m, k=k: self._on_fix(k, m), 100)

    def _on_fix(self, k: int, m: NavSatFix):
        with self.lock:
            self.fixes[k].append(m)

    def copy(self) -> dict[int, list[NavSatFix]]:
        with self.lock:
            return {k: list(v) for k, v in self.fixes.items()}

    def all_reached(self, t_s: float) -> bool:
        """Every robot has a fix stamped t_s or later."""
        return all(f and stamp_s(f[-1].header.stamp) >= t_s for f in self.copy().values())


def sim_launch_description(out: Path, params: dict[str, dict], arguments: dict[str, str]) -> launch.LaunchDescription:
    """`ros2 launch gnss_sim sim.launch.py` with ``arguments``, ``config:=`` out/config.yaml (written from
    ``params``: node name -> its ros__parameters) and ``output_dir:=`` out/out; then ReadyToTest."""
    cfg = out / "config.yaml"
    cfg.write_text(yaml.safe_dump({node: {"ros__parameters": p} for node, p in params.items()}))
    sim = launch.actions.IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(get_package_share_directory("gnss_sim"), "launch",
                                                   "sim.launch.py")),
        launch_arguments={**arguments, "config": str(cfg), "output_dir": str(out / "out")}.items())
    return launch.LaunchDescription([sim, launch_testing.actions.ReadyToTest()])


class RobotLaunchCase:
    """The running part of a robot launch test (mixed into its ``unittest.TestCase``, whose class sets SPEED
    and ROBOTS): the probe publishing /clock at SPEED x, each robot's fixes, and the checks they share."""

    SPEED: float
    ROBOTS: int

    @classmethod
    def setUpClass(cls):
        cls.probe = Probe(cls.SPEED)
        cls.robot_fixes = RobotFixes(cls.probe, cls.ROBOTS)

    @classmethod
    def tearDownClass(cls):
        cls.probe.close()

    def assert_all_active(self, node_paths, timeout_s: float = 180.0):
        """Every node in node_paths answers and is active within timeout_s."""
        probe = self.probe
        ok = probe.wait_for(lambda: all(probe.state_or_none(n) == "active" for n in node_paths), timeout_s)
        self.assertTrue(ok, {n: probe.state_or_none(n) for n in node_paths})

    def robot_fixes_until(self, run_s: float, timeout_s: float) -> dict[int, list[NavSatFix]]:
        """Each robot's fixes once every robot has one stamped run_s or later (within timeout_s), none on
        /gnss/fix, each robot's 1 s apart."""
        got = self.probe.wait_for(lambda: self.robot_fixes.all_reached(run_s), timeout_s)
        fixes = self.robot_fixes.copy()
        self.assertTrue(got, {k: len(f) for k, f in fixes.items()})
        self.assertEqual(self.probe.fixes_copy(), [], "fixes on /gnss/fix: the robots' topics are their own")
        for k in range(self.ROBOTS):
            t = np.array([stamp_s(f.header.stamp) for f in fixes[k]])
            self.assertTrue(np.allclose(np.diff(t), 1.0, atol=1e-6), f"robot{k}: fix intervals {np.diff(t)}")
        return fixes

    def valid_fixes(self, fixes: list[NavSatFix], k: int) -> list[NavSatFix]:
        """Robot k's fixes with a position (status not NO_FIX), checked to be more than 80 % of them."""
        valid = [f for f in fixes if f.status.status != NavSatStatus.STATUS_NO_FIX]
        self.assertGreater(len(valid), 0.8 * len(fixes), f"robot{k}")
        return valid


def check_robot_rinex(case, out: Path, robots: int, marker: str, min_epochs: int):
    """After the launch: one observation file per robot in out/robot<k> under the marker, none outside."""
    for k in range(robots):
        files = sorted((out / f"robot{k}").glob(f"{marker}*_MO.rnx"))
        case.assertEqual(len(files), 1, sorted(p.name for p in out.rglob("*")))
        header, epochs = rinex_obs_epochs(files[0])
        case.assertEqual(header["MARKER NAME"].strip(), marker)
        case.assertGreaterEqual(len(epochs), min_epochs)
    case.assertFalse(list(out.glob("*_MO.rnx")), "no observation file outside the robots' folders")


def ros2(*args: str, timeout_s: float = 60.0) -> str:
    """Run the ``ros2`` command line of this environment; its stdout (fails on a non-zero exit)."""
    proc = subprocess.run(["ros2", *args], capture_output=True, text=True, timeout=timeout_s, env=os.environ.copy())
    if proc.returncode != 0:
        raise AssertionError(f"ros2 {' '.join(args)}: exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}")
    return proc.stdout


def rinex_obs_epochs(path: Path) -> tuple[dict, list[float]]:
    """Header fields (label -> text) and epoch times [s of day] of a RINEX 3/4 observation file."""
    header, epochs, in_header = {}, [], True
    for line in path.read_text().splitlines():
        if in_header:
            header.setdefault(line[60:].strip(), line[:60])
            if line[60:].strip() == "END OF HEADER":
                in_header = False
        elif line.startswith(">"):
            f = line[1:].split()
            epochs.append(int(f[3]) * 3600 + int(f[4]) * 60 + float(f[5]))
    return header, epochs


class ExitsCleanly:
    """Post-shutdown checks of a launch test (mixed into its ``@launch_testing.post_shutdown_test()`` class):
    after SIGINT every process exits 0 and none printed a traceback."""

    def test_exit_codes_zero(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info)

    def test_no_traceback(self, proc_output):
        for info in proc_output:
            self.assertNotIn("Traceback", info.text.decode(errors="replace"), info.process_name)

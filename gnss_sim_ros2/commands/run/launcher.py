"""Where the nodes of ``gnss-sim run`` live (``--layout``): all in this process (composed), one process per robot
(its player, visibility and receiver: nodes/group.py; the shared nodes here) or one process per node; the ROS
context, the executor and the run's own node (``gnss_sim_run``), the lifecycle of every node in the graph's order
(nodes/manager.py), and their end."""
from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys

from gnss_sim_ros2 import graph
from gnss_sim_ros2.commands.run.isolation import die_with_parent
from gnss_sim_ros2.graph_params import robot_namespace

#: summary.json "mode" of each layout ("processes": one per node, as before --layout)
LAYOUT_MODES = {"composed": "composed", "robot": "robot_processes", "node": "processes", "fleet": "fleet"}
LAYOUT_WORDS = {"composed": "all nodes in one process", "robot": "one process per robot",
                "node": "one process per node",
                "fleet": "all nodes in one process, one visibility and one receiver node for every robot"}


def robot_process_name(k: int, robots: int) -> str:
    """The name of robot k's process in the summary (--layout robot)."""
    return robot_namespace(k) if robots > 1 else "robot"


class Launcher:
    """The run's ROS side: ``init_ros`` (context, executor, the ``gnss_sim_run`` node), ``start_nodes`` (node
    processes and local nodes of the layout, ``manager`` driving them all), ``shutdown_nodes``, ``close``."""

    def __init__(self, cfg, args, params_file):
        self.cfg, self.args, self.params_file = cfg, args, params_file
        self.procs: list[subprocess.Popen] = []
        self.proc_names: list[str] = []     # of self.procs: the node's path, or robot<k> (--layout robot)
        self.local = []
        self.executor = self.driver = self.manager = self.rclpy = None
        self.executor_name = None

    def init_ros(self):
        import rclpy

        from gnss_sim_ros2.nodes.common import executor_name, make_executor

        # our own SIGINT/SIGTERM handlers end the loop (summary, sky plot, files closed); rclpy's would shut
        # the context down under the running executor
        rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.rclpy = rclpy
        self.executor = make_executor()      # every composed node's callbacks: the EventsExecutor where rclpy has it
        self.executor_name = executor_name(self.executor)
        self.driver = rclpy.create_node("gnss_sim_run")
        self.executor.add_node(self.driver)

    def start_nodes(self, specs):
        """The node processes of the layout, then the local nodes; ``manager`` drives them in the graph's order."""
        from rclpy.parameter import Parameter

        from gnss_sim_ros2.nodes.manager import LocalNodes, OrderedNodes, RemoteNodes

        layout = self.args.layout
        elsewhere = {"composed": [], "fleet": [], "node": specs,
                     "robot": [s for s in specs if graph.robot_of(s) is not None]}[layout]
        if elsewhere:
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
        if layout in ("composed", "fleet"):
            self.manager = LocalNodes(self.local)
        else:           # in the graph's order, wherever each node is
            local = iter(self.local)
            parts = [RemoteNodes(self.driver, [s.path], self.executor) if s in elsewhere else LocalNodes([next(local)])
                     for s in specs]
            for part in parts:
                if isinstance(part, RemoteNodes):
                    part.wait_for_services()
            self.manager = OrderedNodes(parts)

    def process_pids(self) -> dict[str, int]:
        """{name: pid} of the node processes (the node's path, or robot<k>)."""
        return {n: p.pid for n, p in zip(self.proc_names, self.procs)}

    def foreign_publishers(self) -> dict[str, list[str]]:
        """{topic: nodes} of publishers on the run's topics that are not nodes of its graph."""
        ours = {s.name for s in graph.nodes() + graph.rtk_nodes(self.cfg) + list(graph.FLEET_NODES)} | {"gnss_sim_run"}
        out = {}
        for topic in dict.fromkeys(t for topics in graph.robot_topics(self.args.robots) for t in topics):
            others = sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}"
                             for i in self.driver.get_publishers_info_by_topic(topic) if i.node_name not in ours})
            if others:
                out[topic] = others
        return out

    def states_publishers(self) -> list[str]:
        """The nodes publishing /gnss/satellite_states."""
        return sorted(f"{i.node_namespace.rstrip('/')}/{i.node_name}"
                      for i in self.driver.get_publishers_info_by_topic(f"{graph.TOPIC_NAMESPACE}/satellite_states"))

    def shutdown_nodes(self, log):
        """Deactivate and clean up every node (files closed); ``log`` gets a failed transition."""
        if self.manager is None:
            return
        from gnss_sim_ros2.nodes.manager import TransitionFailed

        try:
            self.manager.transition("deactivate")
            self.manager.transition("cleanup")
        except TransitionFailed as exc:
            log(f"shutdown: {exc}")
        self.manager = None

    def stop_processes(self):
        """SIGINT to every node process, SIGKILL to one not gone within 10 s."""
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()

    def destroy_local_nodes(self):
        for n in self.local:
            self.executor.remove_node(n)
            n.destroy_node()

    def close_ros(self):
        """The run's node and the ROS context (after destroy_local_nodes and the outputs' own nodes)."""
        self.driver.destroy_node()
        self.rclpy.try_shutdown()

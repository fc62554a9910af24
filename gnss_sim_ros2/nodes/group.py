"""One process, several nodes in one executor: ``gnss-sim run --layout robot`` runs one per robot.

    python -m gnss_sim_ros2.nodes.group --node MODULE:CLASS [--ros-args ...] [--node MODULE:CLASS ...]

Each ``--node`` builds the class with the ``--ros-args`` that follow it as the node's own arguments
(its name, namespace, remappings, parameter file: graph.ros_args), never the process's, so one node's
``__node`` remap does not rename another. The process needs no composition_interfaces (the launch file's
``composed:=robot`` uses gnss_sim's component container instead, one per robot); the nodes stay
unconfigured until a lifecycle manager drives them through ``<node>/change_state``. Ctrl-C / SIGTERM:
every node's resources freed (files closed), exit 0.
"""
from __future__ import annotations

import importlib
import sys


def parse(argv: list[str]) -> list[tuple[str, str, list[str]]]:
    """[(module, class, node arguments)] of the command line; ValueError naming the bad part."""
    if not argv or argv[0] != "--node":
        raise ValueError("give the nodes as --node MODULE:CLASS [--ros-args ...] ...")
    out = []
    for i, token in enumerate(argv):
        if token == "--node":
            target = argv[i + 1] if i + 1 < len(argv) else ""
            if ":" not in target:
                raise ValueError(f"--node {target!r}: give MODULE:CLASS")
            module, cls = target.split(":", 1)
            out.append((module, cls, []))
        elif i == 0 or argv[i - 1] != "--node":
            out[-1][2].append(token)
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        specs = parse(argv)
    except ValueError as exc:
        print(f"gnss_sim group: error: {exc}", file=sys.stderr)
        return 2
    from gnss_sim_ros2.nodes.common import close_ros, init_ros, make_executor, spin_until_stopped

    stop = init_ros([sys.argv[0]])          # no process-wide ROS arguments: each node has its own
    executor = make_executor()              # as every gnss_sim process: the EventsExecutor where rclpy has it
    nodes = []
    try:
        for module, cls, args in specs:
            node = getattr(importlib.import_module(module), cls)(cli_args=args, use_global_arguments=False)
            nodes.append(node)
            executor.add_node(node)
        spin_until_stopped(executor, stop)
    finally:
        for node in reversed(nodes):
            node.release()
        close_ros(executor, *nodes)
    return 0


if __name__ == "__main__":
    sys.exit(main())

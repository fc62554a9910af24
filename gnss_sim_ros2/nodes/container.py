"""A component container for Python nodes (rclpy has none: ros2/rclpy#575).

``ros2 run gnss_sim container`` (or launch_ros ``ComposableNodeContainer(package='gnss_sim',
executable='container', ...)``) serves the composition_interfaces services of
rclcpp_components' container on ``<container>/_container/{load_node,unload_node,list_nodes}``:

* ``load_node`` finds ``plugin_name`` among the components ``package_name``
  registers in the ament index (nodes/components.py) and builds the class with
  the request's node name, namespace, parameters and remap rules, as rclcpp
  does: the node takes no process-wide (``--ros-args`` of the container)
  arguments unless ``forward_global_arguments`` is true, so the launch's
  ``__node`` remap of the container never renames a loaded node;
* ``unload_node`` frees a node (``release()``: files closed) and destroys it;
* ``list_nodes`` gives the full names and ids.

Extra arguments: ``use_intra_process_comms`` (bool; rclpy has no intra-process
transport, so true only logs that the middleware carries the messages; the fleet visibility and receiver nodes
hand their robots' visibility over in-process whenever they share the container: nodes/in_process.py),
``forward_global_arguments`` (bool), ``enable_rosout`` (bool); any other is refused.
Every loaded node spins in the one executor of the process (rclpy's
EventsExecutor, or its SingleThreadedExecutor: nodes/common.py make_executor).  Lifecycle nodes
stay unconfigured until a lifecycle manager (or ``ros2 lifecycle set``) drives them.
"""
from __future__ import annotations

import sys
import threading

import rclpy
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter

from gnss_sim_ros2.nodes.common import close_ros, executor_name, init_ros, make_executor, spin_until_stopped
from gnss_sim_ros2.nodes.components import ComponentError, load_class

EXTRA_BOOL_ARGUMENTS = ("use_intra_process_comms", "forward_global_arguments", "enable_rosout")


def _srv():
    try:
        from composition_interfaces import srv
    except ImportError:
        raise ComponentError(
            "the container needs the composition_interfaces package (LoadNode, UnloadNode, ListNodes), which is "
            "not importable: on a ROS 2 install it comes with ros-<distro>-composition-interfaces; with the "
            "PyPI wheels, install ../shared/ros2-tools (docs/ROS.md: 'install-into') and use its venv") from None
    return srv


def _extra_arguments(msgs) -> dict:
    out = {}
    for msg in msgs:
        if msg.name not in EXTRA_BOOL_ARGUMENTS:
            raise ComponentError(f"extra argument '{msg.name}' is not supported (supported: "
                                 f"{', '.join(EXTRA_BOOL_ARGUMENTS)})")
        if msg.value.type != ParameterType.PARAMETER_BOOL:
            raise ComponentError(f"extra argument '{msg.name}' must be a boolean")
        out[msg.name] = msg.value.bool_value
    return out


class ComponentManager:
    """The composition services on ``node``; loaded nodes go into ``executor``."""

    def __init__(self, node, executor):
        srv = _srv()
        self.node = node
        self.executor = executor
        self.loaded: dict[int, object] = {}  # unique id -> node
        self.next_id = 1
        self.lock = threading.Lock()
        node.create_service(srv.LoadNode, "~/_container/load_node", self._on_load)
        node.create_service(srv.UnloadNode, "~/_container/unload_node", self._on_unload)
        node.create_service(srv.ListNodes, "~/_container/list_nodes", self._on_list)

    # ----------------------------------------------------------------- services
    def _on_load(self, request, response):
        try:
            uid, loaded = self.load(request)
        except Exception as exc:  # noqa: BLE001 - any failure goes back to the caller, the container lives on
            msg = str(exc) if isinstance(exc, ComponentError) else f"{type(exc).__name__}: {exc}"
            self.node.get_logger().error(f"load of '{request.plugin_name}' failed: {msg}")
            response.success = False
            response.error_message = msg
            return response
        response.success = True
        response.full_node_name = loaded.get_fully_qualified_name()
        response.unique_id = uid
        self.node.get_logger().info(f"loaded {request.plugin_name} as {response.full_node_name} (id {uid})")
        return response

    def _on_unload(self, request, response):
        with self.lock:
            loaded = self.loaded.pop(request.unique_id, None)
        if loaded is None:
            response.success = False
            response.error_message = f"No node found with unique_id: {request.unique_id}"
            return response
        name = loaded.get_fully_qualified_name()
        self._free(loaded)
        self.node.get_logger().info(f"unloaded {name} (id {request.unique_id})")
        response.success = True
        return response

    def _on_list(self, request, response):
        with self.lock:
            items = sorted(self.loaded.items())
        response.unique_ids = [uid for uid, _ in items]
        response.full_node_names = [n.get_fully_qualified_name() for _, n in items]
        return response

    # ----------------------------------------------------------------- work
    def load(self, request):
        cls = load_class(request.package_name, request.plugin_name)
        extra = _extra_arguments(request.extra_arguments)
        if extra.get("use_intra_process_comms"):
            self.node.get_logger().warning(
                f"{request.plugin_name}: use_intra_process_comms: rclpy has no intra-process transport; "
                "messages go through the middleware")
        cli_args = ["--ros-args"]
        for rule in request.remap_rules:
            cli_args += ["-r", rule]
        kwargs = {
            "context": self.node.context,
            "cli_args": cli_args,
            "use_global_arguments": extra.get("forward_global_arguments", False),
            "enable_rosout": extra.get("enable_rosout", True),
            "parameter_overrides": [Parameter.from_parameter_msg(p) for p in request.parameters],
        }
        if request.node_name:
            kwargs["node_name"] = request.node_name
        if request.node_namespace:
            kwargs["namespace"] = request.node_namespace
        loaded = cls(**kwargs)
        full = loaded.get_fully_qualified_name()
        with self.lock:
            clash = [uid for uid, n in self.loaded.items() if n.get_fully_qualified_name() == full]
            if not clash:
                uid = self.next_id
                self.next_id += 1
                self.loaded[uid] = loaded
        if clash:
            loaded.destroy_node()
            raise ComponentError(f"a node named {full} is already loaded in this container (id {clash[0]})")
        if request.log_level:
            loaded.get_logger().set_level(request.log_level)
        self.executor.add_node(loaded)
        return uid, loaded

    def _free(self, loaded):
        self.executor.remove_node(loaded)
        release = getattr(loaded, "release", None)
        if release is not None:
            release()  # gnss_sim nodes: files closed, entities destroyed, whatever the lifecycle state
        loaded.destroy_node()
        # rclpy's LifecycleNode.destroy_node leaves its state machine, which holds the rcl node: the node
        # would stay in the graph (`ros2 node list`) until garbage collection; free it now
        state_machine = getattr(loaded, "_state_machine", None)
        if state_machine is not None:
            state_machine.destroy_when_not_in_use()

    def unload_all(self):
        with self.lock:
            items = sorted(self.loaded.items(), reverse=True)  # last loaded first
            self.loaded.clear()
        for _, loaded in items:
            self._free(loaded)


def main(args=None) -> int:
    try:
        _srv()
    except ComponentError as exc:
        print(f"container: error: {exc}", file=sys.stderr)
        return 2
    stop = init_ros(args)
    node = rclpy.create_node("gnss_sim_container")
    # one thread: a lifecycle transition (service callback) destroying publishers never races another thread
    # building the wait set from them (rclpy InvalidHandle "destruction was requested"); the EventsExecutor
    # (or the SingleThreadedExecutor, common.make_executor) runs every callback in this thread
    executor = make_executor()
    node.get_logger().info(f"executor: {executor_name(executor)}")
    manager = ComponentManager(node, executor)
    executor.add_node(node)
    try:
        spin_until_stopped(executor, stop)
    finally:
        manager.unload_all()
        close_ros(executor, node)
    return 0


if __name__ == "__main__":
    sys.exit(main())

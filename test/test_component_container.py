"""gnss_sim's component container (nodes/container.py) in this process: load, list, unload
through the composition_interfaces services, and the refusals with their reasons.

Needs composition_interfaces (not on PyPI): `make test` runs this file in .venv-launch
(../shared/ros2-tools); the main suite skips it. The ament index must list gnss_sim's components
(AMENT_PREFIX_PATH; scripts/launch_tests.sh registers them)."""
from __future__ import annotations

import threading

import pytest

srv = pytest.importorskip("composition_interfaces.srv", reason="composition_interfaces is not installed here: "
                          "make test runs this file in .venv-launch (../shared/ros2-tools)")
from rcl_interfaces.msg import Parameter as ParameterMsg  # noqa: E402
from rcl_interfaces.msg import ParameterType, ParameterValue  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from ros_helpers import rclpy  # noqa: E402  (private domain, rclpy or skip)

from gnss_sim_ros2.nodes.container import ComponentManager  # noqa: E402


@pytest.fixture
def container():
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("test_container", context=ctx)
    client_node = rclpy.create_node("test_container_client", context=ctx)
    ex = MultiThreadedExecutor(num_threads=2, context=ctx)
    manager = ComponentManager(node, ex)
    ex.add_node(node)
    ex.add_node(client_node)
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            ex.spin_once(timeout_sec=0.05)

    th = threading.Thread(target=spin)
    th.start()

    def call(kind, request):
        cli = client_node.create_client(getattr(srv, kind), f"/test_container/_container/{kind_to_srv[kind]}")
        assert cli.wait_for_service(timeout_sec=10.0)
        done = threading.Event()
        fut = cli.call_async(request)
        fut.add_done_callback(lambda _f: done.set())
        assert done.wait(30.0)
        return fut.result()

    call.graph = client_node
    yield manager, call
    stop.set()
    th.join()
    manager.unload_all()
    for n in (node, client_node):
        ex.remove_node(n)
        n.destroy_node()
    ex.shutdown()
    rclpy.shutdown(context=ctx)


kind_to_srv = {"LoadNode": "load_node", "UnloadNode": "unload_node", "ListNodes": "list_nodes"}


def _param(name, value: str):
    return ParameterMsg(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value))


def _bool(name, value: bool):
    return ParameterMsg(name=name, value=ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value))


def _load(**kw):
    req = srv.LoadNode.Request(package_name="gnss_sim", plugin_name="gnss_sim::ReceiverNode")
    for k, v in kw.items():
        setattr(req, k, v)
    return req


def test_load_honours_name_namespace_parameters_remaps_then_unload(container):
    manager, call = container
    res = call("LoadNode", _load(node_name="rx_a", node_namespace="/robot1", remap_rules=["fix:=/elsewhere/fix"],
                                 parameters=[_param("marker_name", "ABCD")]))
    assert res.success, res.error_message
    assert res.full_node_name == "/robot1/rx_a"
    node = manager.loaded[res.unique_id]
    assert node.get_parameter("marker_name").value == "ABCD"
    assert node.get_parameter("rate_hz").value == 1.0  # not given: the table's default
    assert node.resolve_topic_name("fix") == "/elsewhere/fix"
    assert node.resolve_topic_name("vel") == "/robot1/vel"
    res2 = call("LoadNode", _load(node_name="rx_b"))
    assert res2.success and res2.unique_id == res.unique_id + 1 and res2.full_node_name == "/rx_b"
    listed = call("ListNodes", srv.ListNodes.Request())
    assert list(listed.full_node_names) == ["/robot1/rx_a", "/rx_b"]
    assert list(listed.unique_ids) == [res.unique_id, res2.unique_id]
    assert call("UnloadNode", srv.UnloadNode.Request(unique_id=res.unique_id)).success
    assert list(call("ListNodes", srv.ListNodes.Request()).full_node_names) == ["/rx_b"]
    again = call("UnloadNode", srv.UnloadNode.Request(unique_id=res.unique_id))
    assert not again.success and f"unique_id: {res.unique_id}" in again.error_message


def test_default_name_comes_from_the_class(container):
    _, call = container
    res = call("LoadNode", _load(plugin_name="gnss_sim::EphemerisNode"))
    assert res.success, res.error_message
    assert res.full_node_name == "/gnss_sim_ephemeris"


@pytest.mark.parametrize("request_kw, message", [
    ({"package_name": "no_such_pkg"}, "package 'no_such_pkg' registers no components"),
    ({"plugin_name": "gnss_sim::Nope"}, "has no component 'gnss_sim::Nope' (registered: gnss_sim::EphemerisNode"),
    ({"extra_arguments": [_bool("wat", True)]}, "extra argument 'wat' is not supported"),
    ({"extra_arguments": [_param("forward_global_arguments", "yes")]}, "must be a boolean"),
])
def test_refusals_name_the_reason(container, request_kw, message):
    manager, call = container
    res = call("LoadNode", _load(**request_kw))
    assert not res.success
    assert message in res.error_message
    assert manager.loaded == {}


def test_a_second_node_of_the_same_name_is_refused(container):
    _, call = container
    assert call("LoadNode", _load(node_name="twin")).success
    res = call("LoadNode", _load(node_name="twin"))
    assert not res.success and "a node named /twin is already loaded" in res.error_message


def test_unload_frees_an_active_node(container):
    import time

    manager, call = container
    res = call("LoadNode", _load(node_name="rx_lc", parameters=[_param("output_dir", "")]))
    node = manager.loaded[res.unique_id]
    from rclpy.lifecycle import TransitionCallbackReturn

    assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
    assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS

    def fix_publishers():
        return [t for t, _ in call.graph.get_publisher_names_and_types_by_node("rx_lc", "/") if t == "/fix"]

    deadline = time.monotonic() + 10
    while not fix_publishers() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert fix_publishers()
    assert call("UnloadNode", srv.UnloadNode.Request(unique_id=res.unique_id)).success
    deadline = time.monotonic() + 10
    while "rx_lc" in call.graph.get_node_names() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert "rx_lc" not in call.graph.get_node_names()
    assert res.unique_id not in manager.loaded

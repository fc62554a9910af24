"""The ament index entries of gnss_sim (scripts/ament_register.py, resource/) and the component
lookup (nodes/components.py) that the container uses; no ROS tools needed."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from gnss_sim_ros2 import graph
from gnss_sim_ros2.nodes import components

REPO = Path(__file__).resolve().parents[1]


def _register_module():
    spec = importlib.util.spec_from_file_location("ament_register", REPO / "scripts" / "ament_register.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_resource_file_lists_every_node_of_the_graph():
    text = (REPO / "resource" / "rclcpp_components" / "gnss_sim").read_text()
    assert text == components.index_lines(graph.COMPONENT_NODES)  # regenerate with index_lines() when they change
    parsed = components.parse_index(text, "resource")
    assert parsed["gnss_sim::ReceiverNode"] == "python:gnss_sim_ros2.nodes.receiver_node:ReceiverNode"


def test_register_copies_the_share_folder_as_real_files(tmp_path):
    written = _register_module().register(tmp_path, executables=True)
    share = tmp_path / "share" / "gnss_sim"
    assert (tmp_path / "share/ament_index/resource_index/packages/gnss_sim").is_file()
    for rel in ("package.xml", "launch/sim.launch.py", "config/gnss_sim.yaml", "worlds/courtyard.sdf"):
        f = share / rel
        assert f.is_file() and not f.is_symlink(), rel
        assert f.read_bytes() == (REPO / rel).read_bytes(), rel
    exe = tmp_path / "lib" / "gnss_sim" / "container"
    assert exe.stat().st_mode & 0o111 and "from gnss_sim_ros2.nodes.container import main" in exe.read_text()
    assert len(written) >= 8


def test_register_again_removes_stale_share_files(tmp_path):
    mod = _register_module()
    mod.register(tmp_path, executables=False)
    stale = tmp_path / "share" / "gnss_sim" / "launch" / "removed.launch.py"
    stale.write_text("old")
    mod.register(tmp_path, executables=False)
    assert not stale.exists()
    assert not (tmp_path / "lib" / "gnss_sim").exists()


@pytest.fixture
def index(tmp_path, monkeypatch):
    _register_module().register(tmp_path, executables=False)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path))
    return tmp_path


def test_components_resolve_through_the_index(index):
    assert set(components.registered("gnss_sim")) == {s.plugin for s in graph.COMPONENT_NODES}
    cls = components.load_class("gnss_sim", "gnss_sim::VisibilityNode")
    assert cls.__name__ == "VisibilityNode" and cls.__module__ == "gnss_sim_ros2.nodes.visibility_node"


@pytest.mark.parametrize("package, plugin, content, message", [
    ("other_pkg", "x::Y", None, "package 'other_pkg' registers no components"),
    ("gnss_sim", "gnss_sim::Nope", None, "has no component 'gnss_sim::Nope'"),
    ("cpp_pkg", "cpp_pkg::Talker", "cpp_pkg::Talker;lib/libtalker.so\n", "is a C++ library (lib/libtalker.so)"),
    ("py_pkg", "py_pkg::Gone", "py_pkg::Gone;python:py_pkg_missing.mod:Gone\n", "cannot import py_pkg_missing.mod"),
    ("bad_pkg", "bad_pkg::A", "bad_pkg::A\n", "line 1: expected 'plugin_name;library_or_python_target'"),
])
def test_component_errors_say_why(index, package, plugin, content, message):
    if content is not None:
        (index / "share/ament_index/resource_index/rclcpp_components" / package).write_text(content)
    with pytest.raises(components.ComponentError) as err:
        components.load_class(package, plugin)
    assert message in str(err.value)


def test_container_without_composition_interfaces_says_what_to_install():
    import subprocess
    import sys

    if importlib.util.find_spec("composition_interfaces") is not None:
        pytest.skip("composition_interfaces is installed in this environment (the container runs)")
    res = subprocess.run([sys.executable, "-m", "gnss_sim_ros2.nodes.container"], capture_output=True, text=True,
                         timeout=60, cwd=REPO)
    assert res.returncode == 2
    assert "needs the composition_interfaces package" in res.stderr and "ros2-tools" in res.stderr
    assert "Traceback" not in res.stderr

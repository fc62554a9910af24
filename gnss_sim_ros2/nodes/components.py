"""Python node classes as ROS 2 components, found through the ament index.

rclcpp_components registers a package's components as one resource file,
``share/ament_index/resource_index/rclcpp_components/<package>``, one line per
component: ``<plugin name>;<library path>``; ``ros2 component types`` lists the
first fields, and rclcpp's ``component_container`` loads the library.  gnss_sim
registers its Python nodes in the same resource so that ``ros2 component types``
lists them, with a second field naming a Python class instead of a library:

    gnss_sim::ReceiverNode;python:gnss_sim_ros2.nodes.receiver_node:ReceiverNode

(``resource/rclcpp_components/gnss_sim``, written from ``graph.COMPONENT_NODES``).  The
gnss_sim container (nodes/container.py) loads such lines; a C++ line (a library
path) is refused with a message naming rclcpp's container.
"""
from __future__ import annotations

import importlib

from gnss_sim_ros2.graph import COMPONENT_NODES, PYTHON_TARGET_PREFIX

RESOURCE_TYPE = "rclcpp_components"


class ComponentError(ValueError):
    """A component that cannot be found or loaded (the message says which and why)."""


def index_lines(specs=COMPONENT_NODES) -> str:
    """Content of gnss_sim's resource file: one ``plugin;python:module:Class`` line per node."""
    return "".join(f"{s.plugin};{s.target}\n" for s in specs)


def parse_index(content: str, where: str) -> dict[str, str]:
    """{plugin name: target} of one resource file's content."""
    out = {}
    for n, line in enumerate(content.splitlines(), 1):
        if not line.strip():
            continue
        plugin, sep, target = line.partition(";")
        if not sep or not plugin.strip() or not target.strip():
            raise ComponentError(f"{where}: line {n}: expected 'plugin_name;library_or_python_target', got {line!r}")
        out[plugin.strip()] = target.strip()
    return out


def registered(package: str) -> dict[str, str]:
    """Components that ``package`` registers in the ament index (AMENT_PREFIX_PATH)."""
    from ament_index_python import get_resource
    from ament_index_python.packages import PackageNotFoundError

    try:
        content, prefix = get_resource(RESOURCE_TYPE, package)
    except (LookupError, PackageNotFoundError):
        raise ComponentError(f"package '{package}' registers no components in the ament index "
                             f"(no share/ament_index/resource_index/{RESOURCE_TYPE}/{package} under "
                             f"AMENT_PREFIX_PATH)") from None
    return parse_index(content, f"{prefix}/share/ament_index/resource_index/{RESOURCE_TYPE}/{package}")


def load_class(package: str, plugin: str):
    """The Python class registered as ``plugin`` by ``package``."""
    components = registered(package)
    if plugin not in components:
        raise ComponentError(f"package '{package}' has no component '{plugin}' (registered: "
                             f"{', '.join(sorted(components)) or 'none'})")
    target = components[plugin]
    if not target.startswith(PYTHON_TARGET_PREFIX):
        raise ComponentError(f"component '{plugin}' of '{package}' is a C++ library ({target}): load it into "
                             f"rclcpp_components' component_container; this container loads Python classes")
    module, _, cls = target[len(PYTHON_TARGET_PREFIX):].partition(":")
    try:
        return getattr(importlib.import_module(module), cls)
    except (ImportError, AttributeError) as exc:
        raise ComponentError(f"component '{plugin}' of '{package}': cannot import {module}:{cls}: {exc}") from None

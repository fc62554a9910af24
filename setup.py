"""ament_python build of gnss_sim (colcon on a ROS 2 install; pip in the wheels venv)."""
from glob import glob

from setuptools import find_packages, setup

package_name = "gnss_sim"


def data(folder, pattern="*"):
    return [f for f in glob(f"{folder}/**/{pattern}", recursive=True) if not f.endswith("/")]


setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(include=["gnss_sim_ros2", "gnss_sim_ros2.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        # the Python nodes as components (`ros2 component types`; gnss_sim_ros2/nodes/components.py)
        ("share/ament_index/resource_index/rclcpp_components", ["resource/rclcpp_components/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", glob("launch/*.py")),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
        ("share/" + package_name + "/config/scenarios", glob("config/scenarios/*.yaml")),
        ("share/" + package_name + "/worlds", glob("worlds/*.sdf") + glob("worlds/*.md")),
    ],
    package_data={"gnss_sim_ros2": ["data/*", "core/signal_plans/*.yaml", "profiles/*.yaml"]},
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="gnss_sim maintainers",
    maintainer_email="maintainers@gnss-sim.example.org",
    description="GNSS receiver simulator for ROS 2 robots",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "gnss-sim = gnss_sim_ros2.cli:main",
            "ephemeris_node = gnss_sim_ros2.nodes.ephemeris_node:main",
            "trajectory_player = gnss_sim_ros2.nodes.trajectory_player:main",
            "visibility_node = gnss_sim_ros2.nodes.visibility_node:main",
            "receiver_node = gnss_sim_ros2.nodes.receiver_node:main",
            "container = gnss_sim_ros2.nodes.container:main",
            "lifecycle_manager = gnss_sim_ros2.nodes.lifecycle_manager:main",
            "recorder = gnss_sim_ros2.nodes.recorder_node:main",
            "rtk_node = gnss_sim_ros2.nodes.rtk_node:main",
            "quality_map_node = gnss_sim_ros2.nodes.quality_map_node:main",
        ],
    },
)

"""Many robots in one graph (issue 18): the graph, the robots' parameters, the shared scene (no ROS needed)."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from gnss_sim_ros2 import graph
from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.trajectory import robot_path
from gnss_sim_ros2.graph_params import MAX_ROBOTS, check_robot_config, check_robots, robot_params
from gnss_sim_ros2.parameters import NODE_NAMES, defaults


def test_one_robot_is_the_graph_of_before():
    assert graph.nodes(True, 1) == list(graph.NODES)
    assert graph.recorded(1) == graph.RECORDED
    assert graph.robot_parameter_sections(defaults(), 1) == {}
    assert all(s.namespace == "" and s.path == s.name for s in graph.nodes(True, 1))
    assert all(graph.remappings_of(s) == graph.REMAPPINGS for s in graph.nodes(True, 1))
    assert graph.robot_topics(1) == [[t for _, t in graph.REMAPPINGS]]


def test_robots_share_the_ephemeris_and_have_their_own_chain():
    specs = graph.nodes(True, 3)
    eph = [s for s in specs if s.key == "ephemeris"]
    assert len(eph) == 1 and eph[0].namespace == ""
    for key in graph.ROBOT_KEYS:
        assert sorted(s.path for s in specs if s.key == key) == [f"robot{k}/{NODE_NAMES[key]}" for k in range(3)]
    # the players first (TF before any cast), the ephemeris before the chains (activation goes downstream first)
    keys = [s.key for s in specs]
    assert keys.index("ephemeris") > max(i for i, k in enumerate(keys) if k == "trajectory")
    assert keys.index("ephemeris") < min(i for i, k in enumerate(keys) if k in ("visibility", "receiver"))
    assert len({s.path for s in specs}) == len(specs)
    without_player = graph.nodes(False, 3)
    assert {s.key for s in without_player} == {"ephemeris", "visibility", "receiver"}


def test_robot_layout_groups_each_robot_its_player_visibility_receiver():
    """--layout robot / composed:=robot: one process per robot with its own nodes, the shared ones apart."""
    specs = graph.nodes(True, 3) + graph.rtk_nodes()
    groups = graph.robot_groups(specs)
    assert sorted(groups) == [0, 1, 2]
    for k, group in groups.items():
        assert [s.key for s in group] == list(graph.ROBOT_KEYS) and {s.namespace for s in group} == {f"robot{k}"}
        assert graph.robot_container_namespace(k, 3) == f"robot{k}"
    shared = [s for s in specs if graph.robot_of(s) is None]
    assert [s.key for s in shared] == ["ephemeris", "visibility", "receiver", "rtk"]    # + the base station's
    assert all(s.instance or s.key == "rtk" for s in shared[1:])
    one = graph.robot_groups(graph.nodes(True, 1) + graph.rtk_nodes())
    assert list(one) == [0] and [s.path for s in one[0]] == [NODE_NAMES[k] for k in graph.ROBOT_KEYS]
    assert graph.robot_container_namespace(0, 1) == ""


def test_robot_remappings_and_recorded_topics():
    spec = next(s for s in graph.nodes(True, 2) if s.robot == 1 and s.key == "receiver")
    remap = dict(graph.remappings_of(spec))
    assert remap["satellite_states"] == "/gnss/satellite_states"      # one ephemeris for all
    assert remap["fix"] == "/robot1/gnss/fix" and remap["observations"] == "/robot1/gnss/observations"
    args = graph.ros_args(spec, None, True)
    assert "__ns:=/robot1" in args and "__node:=gnss_sim_receiver" in args
    topics = [t for t, _ in graph.recorded(2)]
    assert topics.count("/gnss/satellite_states") == 1
    for k in (0, 1):
        for t in ("fix", "observations", "status", "vel", "nmea", "visibility"):
            assert f"/robot{k}/gnss/{t}" in topics
    assert "/gnss/fix" not in topics and "/tf" in topics and "/diagnostics" in topics
    assert len(topics) == len(set(topics))


def test_robot_parameters_frames_seed_output_convoy():
    cfg = load_config(None, {"/**": {"output_dir": "/tmp/o", "seed": 7}})
    rx = [robot_params(cfg, k, 3, "receiver") for k in range(3)]
    assert [r["seed"] for r in rx] == [7, 8, 9]
    assert [r["output_dir"] for r in rx] == ["/tmp/o/robot0", "/tmp/o/robot1", "/tmp/o/robot2"]
    assert {r["marker_name"] for r in rx} == {cfg.node("receiver")["marker_name"]}
    vis = robot_params(cfg, 2, 3, "visibility")
    assert vis["antenna_frame"] == "robot2/gnss_antenna" and vis["world_frame"] == "world"
    trj = [robot_params(cfg, k, 3, "trajectory") for k in range(3)]
    assert [t["base_frame"] for t in trj] == ["robot0/base_link", "robot1/base_link", "robot2/base_link"]
    spacing = cfg.node("trajectory")["convoy_spacing_s"]
    assert [t["time_offset_s"] for t in trj] == [0.0, spacing, 2 * spacing]
    # the convoy: robot k is where robot 0 is k * spacing later
    paths = [robot_path(t) for t in trj]
    for t_s in (0.0, 12.5, 40.0):
        for k in (1, 2):
            np.testing.assert_allclose(paths[k].position(t_s), paths[0].position(t_s + k * spacing))
    assert np.linalg.norm(paths[1].position(0.0) - paths[0].position(0.0)) > 1.0


def test_each_robot_its_own_path_file(tmp_path):
    files = []
    for k in range(2):
        f = tmp_path / f"p{k}.csv"
        f.write_text(f"t_s,e_m,n_m,u_m\n0,{10 * k},0,0\n10,{10 * k},10,0\n")
        files.append(str(f))
    cfg = load_config(None, {"trajectory": {"robot_trajectory_files": files}})
    trj = [robot_params(cfg, k, 2, "trajectory") for k in range(2)]
    assert [t["trajectory_file"] for t in trj] == files
    assert [t["time_offset_s"] for t in trj] == [0.0, 0.0]
    np.testing.assert_allclose(robot_path(trj[1]).position(5.0), [10.0, 5.0, 0.0])
    with pytest.raises(ValueError, match=r"robot_trajectory_files.*2 path file.*option --robots asks for 3"):
        check_robot_config(cfg, 3, "option --robots")


@pytest.mark.parametrize("bad", [0, -1, MAX_ROBOTS + 1, "two", 1.5])
def test_bad_robot_counts_name_the_option_and_the_limit(bad):
    with pytest.raises(ValueError, match=r"option --robots is") as exc:
        check_robots(bad, "option --robots")
    assert f"1..{MAX_ROBOTS}" in str(exc.value)
    with pytest.raises(ValueError, match="launch argument robots"):
        check_robots(bad, "launch argument robots")


def test_robot_counts_accepted():
    assert [check_robots(v) for v in (1, "4", MAX_ROBOTS)] == [1, 4, MAX_ROBOTS]


def test_convoy_spacing_validated_once_naming_the_parameter(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text(yaml.safe_dump({"gnss_sim_trajectory_player": {"ros__parameters": {"convoy_spacing_s": -2.0}}}))
    with pytest.raises(ValueError, match=r"c.yaml.*convoy_spacing_s.*minimum is 0"):
        load_config(f)


def test_robot_sections_of_the_parameter_file_carry_the_robots_values():
    cfg = defaults()
    sec = graph.robot_parameter_sections(cfg, 2)
    assert set(sec) == {f"/robot{k}/{n}" for k in range(2)
                        for n in ("gnss_sim_trajectory_player", "gnss_sim_visibility", "gnss_sim_receiver")}
    assert sec["/robot1/gnss_sim_receiver"]["ros__parameters"]["seed"] == cfg.node("receiver")["seed"] + 1
    assert sec["/robot1/gnss_sim_trajectory_player"]["ros__parameters"]["antenna_frame"] == "robot1/gnss_antenna"


def test_shared_scene_is_built_once_while_held(tmp_path):
    import gc
    import shutil

    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.visibility import SCENE_LOADS, VisibilityOptions, load_scene

    world = tmp_path / "w.sdf"
    shutil.copy(demo_world_path(), world)
    before = dict(SCENE_LOADS)
    a = load_scene(str(world), shared=True)
    b = load_scene(str(world), shared=True)
    assert a is b
    assert SCENE_LOADS["loaded"] == before["loaded"] + 1 and SCENE_LOADS["shared"] == before["shared"] + 1
    other = load_scene(str(world), options=VisibilityOptions(use_visuals=True), shared=True)
    assert other is not a                        # other options, another scene
    assert load_scene(str(world)) is not a       # not shared: a scene of its own
    # an edited world is read again
    import os

    st = world.stat()
    os.utime(world, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert load_scene(str(world), shared=True) is not a
    # held by nobody: freed, the next load builds it again
    loaded = SCENE_LOADS["loaded"]
    del a, b, other
    gc.collect()
    load_scene(str(world), shared=True)
    assert SCENE_LOADS["loaded"] == loaded + 1

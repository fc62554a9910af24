"""The parameters of the nodes a run derives from one configuration: an RTK run's extra instances (the base
station, the second antenna, the heading) and the robots of a run with several (``robot<k>/...``).

parameters.py holds the table, loading and validation; this module applies it to the graph's extra nodes
(graph.node_parameters calls it).  ROS-free.
"""
from __future__ import annotations

from pathlib import Path

from gnss_sim_ros2.parameters import MAX_FLEET_ROBOTS, NODE_NAMES, Config, validate_node

#: the extra nodes of an RTK run, by instance and node key: the base station (a visibility and a receiver node of
#: the rover's classes at a static antenna), and with antenna2_frame the second antenna's receiver and the rtk
#: node in moving-base mode (heading)
INSTANCE_NODE_NAMES = {
    ("base", "visibility"): "gnss_sim_base_visibility", ("base", "receiver"): "gnss_sim_base_receiver",
    ("antenna2", "visibility"): "gnss_sim_antenna2_visibility", ("antenna2", "receiver"): "gnss_sim_antenna2_receiver",
    ("heading", "rtk"): "gnss_sim_heading",
}
BASE_ANTENNA_FRAME = "gnss_base_antenna"
#: marker name and output sub-folder of the second antenna's receiver
ANTENNA2_MARKER = "ANT2"


def base_station_params(cfg: Config, key: str) -> dict:
    """Parameters of the base station's ``visibility`` or ``receiver`` node: the rover's node's (same world,
    scene, signals and models, so the same world errors), with the antenna at ``base_position`` (rtk
    section), its own seed, marker name and output folder, RTCM3 on."""
    return instance_params(cfg, "base", key)


def instance_params(cfg: Config, instance: str, key: str) -> dict:
    """Parameters of one extra node of an RTK run (INSTANCE_NODE_NAMES), derived from the rover's sections:
    ``base``: the base station (``base_*`` of the rtk section); ``antenna2``: the receiver at antenna2_frame
    (seed + 2, marker ANT2, output_dir/antenna2); ``heading``: the rtk node in moving-base mode."""
    if (instance, key) not in INSTANCE_NODE_NAMES:
        raise KeyError(f"no node {key!r} of {instance!r} (one of {sorted(INSTANCE_NODE_NAMES)})")
    rtk = cfg.node("rtk")
    where = f"{cfg.source}: {NODE_NAMES['rtk']}"
    out = cfg.node(key)
    rover_rx = cfg.node("receiver")
    antenna2 = out["antenna2_frame"]
    if instance != "base" and not antenna2:
        raise ValueError(f"{where}: the moving baseline needs parameter 'antenna2_frame' (empty)")
    if instance == "base" and key == "visibility":
        out.update(antenna_position=list(rtk["base_position"]), antenna_position_type=rtk["base_position_type"],
                   antenna_frame=BASE_ANTENNA_FRAME)
    elif instance == "base":
        seed = rtk["base_seed"] if rtk["base_seed"] >= 0 else out["seed"] + 1
        if seed == out["seed"]:
            raise ValueError(f"{where}: parameter 'base_seed' ({seed}) equals the receiver's seed: base and rover "
                             f"would draw the same receiver noise and clock; give another one (or -1)")
        out.update(seed=seed, marker_name=rtk["base_marker_name"], rtcm=True,
                   rtcm_tcp_port=rtk["base_rtcm_tcp_port"], antenna_frame=BASE_ANTENNA_FRAME,
                   output_dir=str(Path(out["output_dir"]) / "base") if out["output_dir"] else "")
        if out["rtcm_tcp_port"] and out["rtcm_tcp_port"] == rover_rx["rtcm_tcp_port"]:
            raise ValueError(f"{where}: parameter 'base_rtcm_tcp_port' ({out['rtcm_tcp_port']}) is the rover's "
                             f"rtcm_tcp_port: one port serves one stream")
    elif instance == "antenna2" and key == "visibility":
        out.update(antenna_frame=antenna2, antenna2_frame="")      # this node is the second antenna
    elif instance == "antenna2":
        base_seed = rtk["base_seed"] if rtk["base_seed"] >= 0 else out["seed"] + 1
        seed = max(out["seed"], base_seed) + 1           # neither the rover's nor the base's
        out.update(seed=seed, marker_name=ANTENNA2_MARKER, rtcm=True, rtcm_tcp_port=0,
                   antenna_frame=antenna2, antenna2_frame="",
                   output_dir=str(Path(out["output_dir"]) / "antenna2") if out["output_dir"] else "")
    else:                                                 # the heading: rtkrcv in moving-base mode
        out.update(rtk_mode="movingbase")
    return validate_node(key, out, f"{where} ({instance})")


# ---------------------------------------------------------------------------- several robots (--robots, robots:=)
#: the most robots one graph takes (each adds a trajectory player, a visibility and a receiver node; a typo such
#: as 100 would start 300 nodes on one executor)
MAX_ROBOTS = 16
#: robot k's ROS namespace and the prefix of its TF frames ("robot0/base_link")
ROBOT_NAMESPACE = "robot{k}"


def check_robots(n, name: str = "option --robots", fleet: bool = False) -> int:
    """The number of robots of a run, 1..MAX_ROBOTS (``fleet``: the fleet layout, one visibility and one receiver
    node for all, 1..MAX_FLEET_ROBOTS); ValueError naming ``name`` (the option or launch argument the user typed)
    otherwise."""
    most, what = (MAX_FLEET_ROBOTS, "MAX_FLEET_ROBOTS in gnss_sim_ros2/parameters.py") if fleet else \
        (MAX_ROBOTS, "MAX_ROBOTS in gnss_sim_ros2/graph_params.py")
    try:
        n_int = int(n)
    except (TypeError, ValueError):
        raise ValueError(f"{name} is {n!r}; a number of robots 1..{most} is needed") from None
    if isinstance(n, float) and n != n_int or isinstance(n, bool):
        raise ValueError(f"{name} is {n!r}; a whole number of robots 1..{most} is needed")
    if not 1 <= n_int <= most:
        layout = "the fleet layout" if fleet else "a run (the fleet layout takes up to " \
                                                  f"{MAX_FLEET_ROBOTS})"
        raise ValueError(f"{name} is {n_int}; {layout} takes 1..{most} robots ({what})")
    return n_int


#: the words a launch argument switch takes (ROS 2 launch's own conditions: IfCondition takes true/false/1/0)
LAUNCH_TRUE, LAUNCH_FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


def launch_flag(value: str, name: str) -> bool:
    """A switch launch argument (``record:=true``); ValueError naming it for a value that is neither true nor false
    (``record:=ture``, ``use_sim_time:=maybe`` were false without a word)."""
    word = str(value).strip().lower()
    if word in LAUNCH_TRUE or word in LAUNCH_FALSE:
        return word in LAUNCH_TRUE
    raise ValueError(f"launch argument {name} is {value!r}; true or false (also 1/0, yes/no, on/off)")


def robot_namespace(k: int) -> str:
    return ROBOT_NAMESPACE.format(k=k)


def check_robot_config(cfg: Config, n: int, name: str = "option --robots") -> None:
    """The rules of a run with ``n`` robots between its parameters (robot_trajectory_files: none or one per robot);
    ValueError naming the parameter and ``name``."""
    files = cfg.node("trajectory")["robot_trajectory_files"]
    if files and len(files) != n:
        raise ValueError(f"{cfg.source}: {NODE_NAMES['trajectory']}: parameter 'robot_trajectory_files' lists "
                         f"{len(files)} path file(s) and {name} asks for {n} robots: give one file per robot "
                         f"(or none: a convoy along the path, convoy_spacing_s apart)")


def robot_params(cfg: Config, k: int, n: int, key: str) -> dict:
    """Parameters of robot ``k`` (of ``n``)'s ``trajectory``, ``visibility`` or ``receiver`` node: the
    configuration's, with the TF frames under ``robot<k>/`` (world_frame shared), the convoy's time offset
    (robot k: k * convoy_spacing_s ahead) or its own path file (robot_trajectory_files[k]), its own receiver
    noise and clock (seed + k) and its RINEX in output_dir/robot<k>."""
    if key not in ("trajectory", "visibility", "receiver"):
        raise KeyError(f"robot nodes are trajectory, visibility, receiver; not {key!r}")
    check_robot_config(cfg, n)
    ns = robot_namespace(k)
    return validate_node(key, robot_node_params(cfg.node(key), k, key), f"{cfg.source}: {ns}/{NODE_NAMES[key]}")


def robot_node_params(node_params: dict, k: int, key: str) -> dict:
    """Robot ``k``'s values of one node's parameters ``node_params`` (robot_params; the fleet layout's nodes derive
    each robot's from their own with it, so a fleet's robot k is the per-robot layout's robot k), unchecked."""
    ns = robot_namespace(k)
    out = dict(node_params)
    out["antenna_frame"] = f"{ns}/{out['antenna_frame']}"
    if out["antenna2_frame"]:
        out["antenna2_frame"] = f"{ns}/{out['antenna2_frame']}"
    if key == "trajectory":
        out["base_frame"] = f"{ns}/{out['base_frame']}"
        if out["robot_trajectory_files"]:
            out.update(trajectory_file=out["robot_trajectory_files"][k], waypoints=[])
        else:
            out["time_offset_s"] = out["time_offset_s"] + k * out["convoy_spacing_s"]
    if key == "receiver":
        out["seed"] = out["seed"] + k
        out["output_dir"] = str(Path(out["output_dir"]) / ns) if out["output_dir"] else ""
    return out


def fleet_robot_params(node_params: dict, k: int, key: str) -> dict:
    """Robot ``k``'s parameters in a fleet node ``key`` whose own are ``node_params`` (fleet_robots of them): the
    per-robot layout's (robot_node_params); one robot: the node's own (the root's frames, topics and seed, as a
    one-robot run)."""
    if node_params["fleet_robots"] == 1:
        return dict(node_params)
    return robot_node_params(node_params, k, key)

"""`gnss-sim run --layout fleet`: one visibility node and one receiver node serve every robot (issue 31).

Real runs of the node graph. The fleet layout's robots give what the per-robot layout's robots give with the same
seeds, byte for byte: each robot's RINEX observation file, every /robot<k>/gnss/fix, observations and visibility
message in the bag (their serialised bytes), with the default preset's multipath (auto). With the robots' bodies
as moving obstacles (obstacle_frames: each robot sees the others' boxes, never its own) the fleet sees more
satellite-epochs out of direct sight than without. Bodies are left out of the byte comparison: in both layouts an
obstacle frame is looked up at the epoch's stamp without waiting for it (nodes/visibility_node.py), so on a
loaded machine the first epochs may or may not find another robot's player's transform (seen in 2 of 3 tries:
robot 1 or 2 tracked 2 satellites in one run and solved in the other) -- a race of the TF sources, not of the
layout. Also: the graph's fleet nodes and robot k's parameters, the robot limit of the fleet layout named in the
error. The visibility handed in-process to the fleet receiver (nodes/in_process.py): the same outputs as through
the middleware (GNSS_SIM_IN_PROCESS=off), the columns handed those the message's decode gives, the link made only
within one context and executor.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
import yaml

from gnss_sim_ros2 import graph
from gnss_sim_ros2.graph_params import MAX_ROBOTS, check_robots
from gnss_sim_ros2.parameters import MAX_FLEET_ROBOTS

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]
ROBOTS = 3
DURATION_S = 6
#: a convoy 1 m apart (1 s at the demo path's 1 m/s) with 30 m tall boxes on the robots: the robot ahead and the
#: one behind stand in some satellites' way
BODIES = {"obstacle_frames": [f"robot{k}/base_link" for k in range(ROBOTS)], "obstacle_box_size_m": [2.0, 2.0, 30.0]}


def test_fleet_graph_one_visibility_one_receiver():
    specs = graph.nodes(True, 4, fleet=True)
    assert [s.path for s in specs] == ["gnss_sim_fleet_trajectory_player", "gnss_sim_ephemeris",
                                       "gnss_sim_fleet_visibility", "gnss_sim_fleet_receiver"]
    assert [s.path for s in graph.nodes(False, 4, fleet=True)] == [s.path for s in specs[1:]]
    from gnss_sim_ros2.parameters import defaults

    cfg = defaults()
    rx = graph.node_parameters(cfg, specs[-1], 4)
    assert rx["fleet_robots"] == 4 and rx["seed"] == cfg.node("receiver")["seed"]
    from gnss_sim_ros2.graph_params import fleet_robot_params, robot_params

    for k in range(4):     # robot k's receiver in the fleet: exactly the per-robot layout's robot k
        own = robot_params(cfg, k, 4, "receiver")
        mine = fleet_robot_params(rx, k, "receiver")
        assert {n: mine[n] for n in own if n != "fleet_robots"} == {n: v for n, v in own.items() if n != "fleet_robots"}
    assert graph.fleet_topic(2, 4, "fix") == "/robot2/gnss/fix" and graph.fleet_topic(0, 1, "fix") == "/gnss/fix"
    # the one player moves every robot: robot k's base frame and convoy offset, as robot k's own player
    player = graph.node_parameters(cfg, specs[0], 4)
    for k in range(4):
        own = robot_params(cfg, k, 4, "trajectory")
        mine = fleet_robot_params(player, k, "trajectory")
        assert {n: mine[n] for n in own if n != "fleet_robots"} == {n: v for n, v in own.items() if n != "fleet_robots"}


def test_fleet_robot_limit_named():
    assert check_robots(MAX_FLEET_ROBOTS, fleet=True) == MAX_FLEET_ROBOTS
    with pytest.raises(ValueError, match="fleet layout takes up to 64"):
        check_robots(MAX_ROBOTS + 1)
    with pytest.raises(ValueError, match="option --robots is 65; the fleet layout takes 1..64"):
        check_robots(65, fleet=True)


pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")

import subprocess  # noqa: E402


def _run(out: Path, layout: str, visibility: dict, env_extra: dict | None = None):
    cfg = out.parent / f"{out.name}.yaml"
    cfg.write_text(yaml.safe_dump({"gnss_sim_visibility": {"ros__parameters": visibility},
                                   "gnss_sim_trajectory_player": {"ros__parameters": {"convoy_spacing_s": 1.0}}}))
    env = dict(os.environ, ROS_DOMAIN_ID=str((os.getpid() + 11) % 100 + 1))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.update(env_extra or {})
    res = subprocess.run(CLI + ["run", "--out", str(out), "--quiet", "--robots", str(ROBOTS), "--layout", layout,
                                "--duration", str(DURATION_S), "--systems", "GE", "--config", str(cfg)],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads((out / "summary.json").read_text())


def _raw_messages(bag: Path, topics) -> dict:
    """{topic: {stamp: serialised bytes}} of the bag."""
    from rosbags.highlevel import AnyReader

    from gnss_sim_ros2.messages.conversions import stamp_of
    from gnss_sim_ros2.recorder import typestore

    out = {t: {} for t in topics}
    with AnyReader([bag], default_typestore=typestore()) as reader:
        for conn, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic in out]):
            out[conn.topic][stamp_of(bytes(raw))] = bytes(raw)
    return out


def _blocked(bag: Path) -> int:
    from rosbags.highlevel import AnyReader

    from gnss_sim_ros2.core.vocabulary import VisibilityState
    from gnss_sim_ros2.recorder import typestore

    n = 0
    with AnyReader([bag], default_typestore=typestore()) as reader:
        conns = [c for c in reader.connections if c.topic.endswith("/gnss/visibility")]
        for conn, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, conn.msgtype)
            n += sum(s.state != int(VisibilityState.VISIBLE) for s in m.satellites)   # blocked, reflected only...
    return n


def _rinex_without_run_line(path: Path) -> list[str]:
    return [ln for ln in path.read_text().splitlines() if "PGM / RUN BY / DATE" not in ln]


@pytest.mark.slow
def test_fleet_equals_separate_robots_with_the_same_seeds(tmp_path):
    fleet = _run(tmp_path / "fleet", "fleet", {})
    separate = _run(tmp_path / "composed", "composed", {})
    epochs = DURATION_S + 1
    assert fleet["mode"] == "fleet" and fleet["epochs_without_output"] == 0 and fleet["robots"] == ROBOTS
    assert separate["mode"] == "composed"
    topics = [graph.robot_topic(k, f"/gnss/{t}") for k in range(ROBOTS) for t in ("fix", "observations", "visibility")]
    a, b = _raw_messages(tmp_path / "fleet" / "bag", topics), _raw_messages(tmp_path / "composed" / "bag", topics)
    for t in topics:
        assert len(a[t]) == epochs, (t, len(a[t]))
        assert a[t] == b[t], f"{t}: the fleet's messages differ from the separate robot's"
    for k in range(ROBOTS):
        (fa,) = (tmp_path / "fleet" / f"robot{k}").glob("*_MO.rnx")
        (fb,) = (tmp_path / "composed" / f"robot{k}").glob("*_MO.rnx")
        assert fa.name == fb.name and _rinex_without_run_line(fa) == _rinex_without_run_line(fb), f"robot{k}"
    # the robots' seeds differ (seed + k): their observations are not one another's
    assert a[topics[1]] != a[topics[4]]
    # the visibility through the middleware instead of handed in-process (nodes/in_process.py): the same outputs
    from gnss_sim_ros2.nodes.in_process import IN_PROCESS_ENV

    dds = _run(tmp_path / "dds", "fleet", {}, {IN_PROCESS_ENV: "off"})
    # the run's own figures from the visibility handed to its driver or from the messages: the same
    assert [dds[f] for f in ("horizontal_error_rms_m", "epochs_without_output")] == \
        [fleet[f] for f in ("horizontal_error_rms_m", "epochs_without_output")]
    c = _raw_messages(tmp_path / "dds" / "bag", topics)
    for t in topics:
        assert c[t] == a[t], f"{t}: the messages differ between the hand-over in-process and the middleware"
    for k in range(ROBOTS):
        (fa,) = (tmp_path / "fleet" / f"robot{k}").glob("*_MO.rnx")
        (fc,) = (tmp_path / "dds" / f"robot{k}").glob("*_MO.rnx")
        assert _rinex_without_run_line(fa) == _rinex_without_run_line(fc), f"robot{k} in-process vs middleware"
    # the bodies block: the same fleet with them sees more satellite-epochs out of direct sight
    bodies = _run(tmp_path / "bodies", "fleet", BODIES)
    assert _blocked(tmp_path / "bodies" / "bag") > _blocked(tmp_path / "fleet" / "bag")
    assert bodies["epochs_without_output"] == 0


def _columns_equal(a: dict, b: dict, where: str = ""):
    assert a.keys() == b.keys(), where
    for key, x in a.items():
        y = b[key]
        if isinstance(x, tuple):
            assert x[0].tolist() == y[0].tolist(), where + key
            _columns_equal(x[1], y[1], f"{where}{key}/")
        elif x.dtype.kind == "U":
            assert x.tolist() == y.tolist(), where + key
        else:
            assert (x.dtype, x.shape, x.tobytes()) == (y.dtype, y.shape, y.tobytes()), where + key


def test_handed_visibility_is_the_message_decoded():
    """The columns the fleet visibility node hands in-process are decode_visibility(encode_visibility(...)) bit for
    bit: float32 fraction blocked rounded alike, the rows' reflections (NaN slots left out, the rest in order),
    no satellite at all."""
    import numpy as np

    from gnss_sim_ros2.core.multipath.reflections import ScenePaths
    from gnss_sim_ros2.messages.conversions import decode_visibility, encode_visibility
    from gnss_sim_ros2.nodes.fleet_visibility_node import handed_visibility

    rng = np.random.default_rng(7)
    n, k = 6, 3
    paths = ScenePaths.empty(1, n, k).take(0)
    paths.excess_m[rng.random((n, k)) < 0.5] = 1.0
    paths.excess_m *= rng.uniform(0.1, 40.0, (n, k))
    paths.gamma_co[:] = rng.normal(size=(n, k)) + 1j * rng.normal(size=(n, k))
    paths.gamma_cross[:] = rng.normal(size=(n, k)) + 1j * rng.normal(size=(n, k))
    paths.arrival_el_deg[:] = rng.uniform(-10, 80, (n, k))
    rows = np.array([0, 2, 3, 5])
    m = len(rows)
    sv = np.array(["G01", "E11", "C22", "R05", "J02", "G30"])[rows]
    fields = [(123, 456_000_000), "map", rng.normal(size=3), rng.normal(size=3) * 6e6, sv,
              rng.uniform(0, 360, m), rng.uniform(0, 90, m), np.array([0, 1, 2, 3]), rng.uniform(0, 30, m),
              rng.uniform(0, 5, m), rng.random(m) / 3.0]          # fraction blocked: float64, not a float32 value
    for case in (fields + [paths, rows], fields + [None, None]):
        _columns_equal(handed_visibility(*case), decode_visibility(encode_visibility(*case)))
    empty = np.zeros(0, dtype=np.int64)
    none = [(1, 2), "map", np.zeros(3), np.ones(3)] + [empty] * 7 + [None, empty]
    _columns_equal(handed_visibility(*none), decode_visibility(encode_visibility(*none)))


class _Context:
    def __init__(self):
        self.handle = object()


class _Node:
    """What nodes/in_process.py reads of a node: its context (handle), executor and topic names."""

    def __init__(self, context, executor):
        self.context, self.executor = context, executor

    def resolve_topic_name(self, topic):
        return topic


class _Publisher:
    topic_name = "/robot0/gnss/visibility"


def test_in_process_link_one_context_and_executor(monkeypatch):
    """Every taker of a topic is handed it by an offer of its own context and executor and has no middleware
    subscription while the offer is there; another context (another rclpy.init) is never linked; the last offer
    withdrawn, the takers subscribe again; GNSS_SIM_IN_PROCESS=off links nothing."""
    from gnss_sim_ros2.nodes import in_process

    ctx, executor = _Context(), object()
    first, second = [], []

    def deliver(payload):
        pass

    def deliver_too(payload):
        pass
    taker = in_process.Taker(_Node(ctx, executor), "/robot0/gnss/visibility", deliver, first.append)
    assert first == [True]                           # no offer yet: through the middleware
    offer = in_process.Offer(_Node(ctx, executor), _Publisher())
    assert first == [True, False] and offer.takers() == [deliver]
    too = in_process.Taker(_Node(ctx, executor), "/robot0/gnss/visibility", deliver_too, second.append)
    assert second == [False] and offer.takers() == [deliver, deliver_too]
    other = in_process.Offer(_Node(_Context(), executor), _Publisher())     # another context
    assert other.takers() == []
    elsewhere = in_process.Offer(_Node(ctx, object()), _Publisher())        # another executor: not handed
    assert elsewhere.takers() == []
    second_offer = in_process.Offer(_Node(ctx, executor), _Publisher())     # a second publisher of the topic
    too.close()
    assert offer.takers() == [deliver] and second_offer.takers() == [deliver]
    offer.withdraw()
    assert first == [True, False]                    # an offer of the context and executor is still there
    second_offer.withdraw()
    assert first == [True, False, True]              # the last one gone (another executor's does not link)
    elsewhere.withdraw()
    other.withdraw()
    taker.close()
    assert not in_process._LINKS
    # a MultiThreadedExecutor may run the taker's callbacks beside a hand-over: nothing is linked there
    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        threads = MultiThreadedExecutor(num_threads=2, context=context)
        first.clear()
        taker = in_process.Taker(_Node(ctx, threads), "/robot0/gnss/visibility", deliver, first.append)
        offer = in_process.Offer(_Node(ctx, threads), _Publisher())
        assert first == [True] and offer.takers() == [] and not in_process._LINKS
        offer.withdraw()
        taker.close()
        threads.shutdown()
    finally:
        rclpy.shutdown(context=context)
    monkeypatch.setenv(in_process.IN_PROCESS_ENV, "off")
    first.clear()
    taker = in_process.Taker(_Node(ctx, executor), "/robot0/gnss/visibility", deliver, first.append)
    offer = in_process.Offer(_Node(ctx, executor), _Publisher())
    assert first == [True] and offer.takers() == []
    monkeypatch.setenv(in_process.IN_PROCESS_ENV, "maybe")
    with pytest.raises(ValueError, match="GNSS_SIM_IN_PROCESS is 'maybe': one of on, off"):
        in_process.enabled()


def test_tf_handed_in_process_is_fed_once():
    """A /tf message a trajectory player of the process hands (nodes/tf_stream.py: with its bytes) is fed to the
    TF tree at once; the middleware's copy of it (the same bytes) is then dropped, while a message of another
    publisher (not handed) is fed, and so is the same message published again."""
    import rclpy
    from rclpy.serialization import serialize_message

    from gnss_sim_ros2.messages.tf import tf_message, transform_to_msg
    from gnss_sim_ros2.nodes.tf_source import TfSource

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("tf_handed_test", context=context)
        tf = TfSource(node, prefer_tf2_ros=False)
        fed = []
        tf._feed = lambda msg, static: fed.append(msg)

        def message(sec, child):
            stamp = rclpy.time.Time(seconds=sec).to_msg()
            return tf_message([transform_to_msg("world", child, stamp, [1.0, 2.0, 3.0], 0.5)])

        from tf2_msgs.msg import TFMessage

        pub = node.create_publisher(TFMessage, "/tf", 100)
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        executor.add_node(node)

        def through_middleware(data, n_fed):
            pub.publish(data)                     # what the player publishes: the bytes it hands
            for _ in range(200):
                executor.spin_once(timeout_sec=0.02)
                if len(fed) >= n_fed and not tf._stream._handed:
                    return

        handed = message(10, "robot0/base_link")
        data = serialize_message(handed)
        tf._stream.from_process((handed, data))
        assert fed == [handed]
        through_middleware(data, 1)                        # the middleware's copy of the message handed
        assert fed == [handed] and not tf._stream._handed
        other = message(10, "robot1/base_link")            # another publisher's, at the same stamp
        through_middleware(serialize_message(other), 2)
        assert len(fed) == 2 and fed[1].transforms[0].child_frame_id == "robot1/base_link"
        through_middleware(data, 3)                        # the same message published again: fed
        assert len(fed) == 3 and fed[2] == handed
        executor.shutdown()
        tf.close()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)

"""Moving obstacles (core/visibility/moving_obstacles.py) against geometry computed here independently.

The expected answers do not use the slab method: each ray is sampled every millimetre out to 15 m (beyond
every box here) and a sample inside a box (its distance function <= 0) blocks it; rays passing within 5 mm of
a box's surface are left out of the comparison (a sampled ray can miss a graze the analytic test sees).
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest

from gnss_sim_ros2.core import frames
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.trajectory import Trajectory
from gnss_sim_ros2.core.visibility import VisibilityOptions
from gnss_sim_ros2.core.visibility.moving_obstacles import MovingBoxes, fleet_bodies, own_body, yaw_rotations
from gnss_sim_ros2.core.vocabulary import VisibilityState
from gnss_sim_ros2.parameters import validate_node

LAT0, LON0, H0 = 22.3, 114.17, 10.0
BLOCKED = int(VisibilityState.BLOCKED)
VISIBLE = int(VisibilityState.VISIBLE)
EDGE_M = 5e-3


def write_open_world(path):
    """A georeferenced world whose only model, a small box 400 m away, blocks nothing the tests look at."""
    path.write_text(textwrap.dedent(f"""\
        <?xml version="1.0"?>
        <sdf version="1.9"><world name="w">
          <spherical_coordinates><latitude_deg>{LAT0}</latitude_deg><longitude_deg>{LON0}</longitude_deg>
            <elevation>{H0}</elevation><heading_deg>0</heading_deg></spherical_coordinates>
          <model name="far"><static>true</static><pose>400 400 0.5 0 0 0</pose><link name="L"><collision name="c">
            <geometry><box><size>1 1 1</size></box></geometry></collision></link></model>
        </world></sdf>
        """))
    return path


@pytest.fixture(scope="module")
def open_scene(tmp_path_factory):
    return Scene.from_sdf(write_open_world(tmp_path_factory.mktemp("w") / "w.sdf"))


def sats_at(scene, antenna_world_m, az_deg, el_deg):
    """Satellite ECEF positions 20 000 km from the antenna at local azimuths / elevations."""
    rx = scene.antenna_ecef(np.asarray(antenna_world_m, float))
    lat, lon, _ = frames.ecef_to_geodetic(*rx)
    enu = frames.enu_unit_from_az_el(np.asarray(az_deg, float), np.asarray(el_deg, float))
    return rx + 2.0e7 * enu @ frames.enu_rotation(lat, lon)


def sampled_hits(origin, az_deg, el_deg, centers, halves, yaws_deg, reach_m=15.0):
    """(hit, near_edge) per direction: samples every 1 mm to ``reach_m`` against boxes (centre, half size, yaw)."""
    d = frames.enu_unit_from_az_el(np.asarray(az_deg, float), np.asarray(el_deg, float)).reshape(-1, 3)
    t = np.arange(1e-3, reach_m, 1e-3)
    best = np.full(len(d), np.inf)
    for c, h, yaw in zip(centers, halves, yaws_deg):
        r = yaw_rotations(yaw)
        for i in range(len(d)):
            p = (origin + t[:, None] * d[i] - c) @ r                     # samples in the box's frame
            q = np.abs(p) - h
            sdf = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
            best[i] = min(best[i], sdf.min())
    return best <= 0.0, np.abs(best) < EDGE_M


def test_robot_parked_beside_blocks_its_side_only(open_scene):
    """Robot B (a 2 x 1.5 x 2 m vehicle) parks 3 m east of robot A: one batched cast of both antennas; A's
    satellites toward B under B's angular height are blocked, the others not; B does not see its own body."""
    size = np.array([2.0, 1.5, 2.0])
    bases = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    antennas = bases + [0.0, 0.0, 0.5]                 # B's antenna is inside B's own box: only its body's
    az, el = np.meshgrid(np.arange(0.0, 360.0, 9.7), np.arange(11.0, 89.0, 4.3), indexing="ij")
    az, el = az.ravel(), el.ravel()
    sat = sats_at(open_scene, antennas[0], az, el)
    opts = VisibilityOptions(mask_deg=10.0)
    state, _, v = opts.cast(open_scene, antennas, sat, obstacles=fleet_bodies(bases, [0.0, 0.0], size))
    # the explicit cases: east low (near face at 2 m, top 1.5 m above the antenna: 36.9 deg), east high, west low
    s = sats_at(open_scene, antennas[0], [90.0, 90.0, 270.0], [20.0, 50.0, 20.0])
    st3, _, _ = opts.cast(open_scene, antennas[0], s, obstacles=fleet_bodies(bases, [0.0, 0.0], size).rows(slice(0, 1)))
    assert st3.tolist() == [BLOCKED, VISIBLE, VISIBLE]
    # every direction against the sampled geometry of B's box
    hit, edge = sampled_hits(antennas[0], az, el, [bases[1] + [0, 0, 1.0]], [size / 2], [0.0], 6.0)
    assert hit.sum() > 10 and (~hit).sum() > 100
    assert np.array_equal(state[0][~edge] == BLOCKED, hit[~edge])
    # B sees A's body (as tall, 3 m west) but never its own, though its antenna is inside it
    hit_b, edge_b = sampled_hits(antennas[1], az, el, [bases[0] + [0, 0, 1.0]], [size / 2], [0.0], 6.0)
    assert hit_b.sum() > 10
    assert np.array_equal(state[1][~edge_b] == BLOCKED, hit_b[~edge_b])


def test_batched_cast_equals_one_cast_per_robot(open_scene):
    """One cast of R antennas (each with the other robots' bodies) equals R casts, one per robot."""
    rng = np.random.default_rng(3)
    r = 6
    bases = np.c_[rng.uniform(-8, 8, (r, 2)), np.zeros(r)]
    yaw = rng.uniform(0, 360, r)
    antennas = bases + [0.0, 0.0, 0.5]
    size = [1.2, 0.8, 1.4]
    az, el = np.meshgrid(np.arange(0.0, 360.0, 11.0), np.arange(11.0, 60.0, 4.0), indexing="ij")
    sat = sats_at(open_scene, antennas[0], az.ravel(), el.ravel())
    opts = VisibilityOptions(mask_deg=10.0)
    bodies = fleet_bodies(bases, yaw, size)
    batched, att_b, _ = opts.cast(open_scene, antennas, sat, obstacles=bodies)
    assert (batched == BLOCKED).sum() > 0
    for i in range(r):
        others = np.delete(np.arange(r), i)
        own = MovingBoxes.from_bases(bases[None, others], yaw_rotations(yaw[others])[None], size)
        one, att_1, _ = opts.cast(open_scene, antennas[i], sat, obstacles=own)
        assert np.array_equal(one, batched[i])
        assert np.array_equal(att_1, att_b[i])


def test_moving_model_crossing_blocks_only_while_it_passes(open_scene, tmp_path):
    """A bus (10 x 2.5 x 3 m) drives along y = 6 m from x = -40 to 40 m at 1 m/s, its poses a time series (the
    CSV of gnss-sim simulate --obstacle-path); the antenna at (0, 0, 0.5) sees it cross its northern sky."""
    path = tmp_path / "bus.csv"
    path.write_text("t_s,e_m,n_m,u_m,yaw_deg\n0,-40,6,0,0\n80,40,6,0,0\n")
    bus = Trajectory.from_csv(path)
    size = np.array([10.0, 2.5, 3.0])
    t = np.arange(0.0, 81.0, 1.0)
    antenna = np.array([0.0, 0.0, 0.5])
    az = np.array([0.0, 30.0, 0.0, 180.0])
    el = np.array([15.0, 15.0, 40.0, 15.0])       # behind the bus, behind it further east, over it, south
    sat = sats_at(open_scene, antenna, az, el)
    base = bus.position(t)[:, None, :]
    boxes = MovingBoxes.from_bases(base, yaw_rotations(bus.yaw(t))[:, None], size)
    state, _, _ = VisibilityOptions(mask_deg=10.0).cast(open_scene, np.repeat(antenna[None], len(t), 0),
                                                        np.broadcast_to(sat, (len(t),) + sat.shape), obstacles=boxes)
    blocked = state == BLOCKED
    for k in range(len(t)):
        hit, edge = sampled_hits(antenna, az, el, [base[k, 0] + [0, 0, 1.5]], [size / 2], [0.0])
        assert np.array_equal(blocked[k][~edge], hit[~edge]), t[k]
    # before it comes and after it has gone: nothing blocked; while it passes the first two are, in turn
    x_bus = base[:, 0, 0]
    assert not blocked[np.abs(x_bus) > 15].any()
    assert blocked[np.abs(x_bus) < 4.9, 0].all() and not blocked[np.abs(x_bus) > 5.1, 0].any()
    assert blocked[:, 1].any() and not blocked[:, 2].any() and not blocked[:, 3].any()
    assert not np.array_equal(blocked[:, 0], blocked[:, 1])        # the east one is hidden at other times


def test_no_obstacles_leaves_the_cast_as_it_was(open_scene):
    antennas = np.array([[0.0, 0.0, 0.5], [5.0, 1.0, 0.5]])
    sat = sats_at(open_scene, antennas[0], np.arange(0, 360, 20.0), np.full(18, 30.0))
    opts = VisibilityOptions(mask_deg=10.0)
    a = opts.cast(open_scene, antennas, sat)
    far = MovingBoxes.from_bases(np.full((2, 1, 3), 300.0), np.eye(3), [1, 1, 1])
    b = opts.cast(open_scene, antennas, sat, obstacles=far)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


@pytest.mark.parametrize(("name", "value"), [("obstacle_box_size_m", [1.0, 0.0, 1.0]),
                                             ("obstacle_model_size_m", [4.5, 1.8]),
                                             ("obstacle_frames", "robot1/base_link")])
def test_bad_obstacle_parameters_name_the_parameter(name, value):
    with pytest.raises(ValueError, match=name):
        validate_node("visibility", {name: value}, "node v")


def test_models_without_a_pose_topic_are_refused():
    with pytest.raises(ValueError, match="obstacle_pose_topic"):
        validate_node("visibility", {"obstacle_models": ["bus"]}, "node v")


def test_simulate_obstacle_path_blocks_while_the_box_stands_over_the_antenna(tmp_path):
    """`gnss-sim simulate --obstacle-path`: the offline chain with a 40 x 40 x 30 m box that stands over the static
    antenna from t = 10 to 20 s and 700 m away (under 2 deg high) before and after: every satellite above the mask
    is blocked in those 11 epochs, none in the others."""
    import argparse

    from gnss_sim_ros2.commands import simulate
    from gnss_sim_ros2.core.simulation import run_simulation

    world = write_open_world(tmp_path / "w.sdf")
    (tmp_path / "antenna.csv").write_text("t_s,e_m,n_m,u_m\n0,0,0,1.5\n")
    (tmp_path / "box.csv").write_text("t_s,e_m,n_m,u_m,yaw_deg\n0,500,500,-10,0\n9.5,500,500,-10,0\n"
                                      "10,0,0,-10,0\n20,0,0,-10,0\n20.5,500,500,-10,0\n30,500,500,-10,0\n")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("gnss_sim_visibility:\n  ros__parameters:\n    obstacle_model_size_m: [40.0, 40.0, 30.0]\n")
    ap = argparse.ArgumentParser()
    simulate.add_arguments(ap)
    args = ap.parse_args(["--config", str(cfg), "--world", str(world), "--trajectory", str(tmp_path / "antenna.csv"),
                          "--obstacle-path", str(tmp_path / "box.csv"), "--duration", "30", "--interval", "1",
                          "--quiet", "--out", str(tmp_path / "out")])
    res = run_simulation(simulate.setup_from_args(args))
    blocked, visible = np.array(res.blocked_per_epoch), np.array(res.visible_per_epoch)
    over = (np.arange(31) >= 10) & (np.arange(31) <= 20)
    assert len(blocked) == 31 and visible[~over].min() > 4
    assert (visible[over] == 0).all() and (blocked[over] > 4).all() and (blocked[~over] == 0).all()
    ap2 = ["--world", str(world), "--out", str(tmp_path / "o2"), "--obstacle-path", str(tmp_path / "antenna_geo.csv")]
    (tmp_path / "antenna_geo.csv").write_text("t_s,lat_deg,lon_deg,h_m\n0,22.3,114.17,10\n")
    with pytest.raises(ValueError, match="option --obstacle-path"):
        simulate.setup_from_args(ap.parse_args(ap2))


def test_own_body_is_the_frame_under_the_antenna_frames_prefix():
    assert own_body("robot2/base_link", "robot2/gnss_antenna")
    assert not own_body("robot1/base_link", "robot2/gnss_antenna") and not own_body("base_link", "gnss_antenna")


def test_fleet_with_a_shared_model_in_one_cast_equals_one_cast_per_robot(open_scene):
    """Three robots and a bus every robot sees: bodies (own left out) and the bus in one batched cast, equal
    to each robot cast alone with the two other bodies and the bus."""
    bases = np.array([[0.0, 0.0, 0.0], [2.5, 0.5, 0.0], [-1.0, 3.0, 0.0]])
    yaw = np.array([0.0, 30.0, 100.0])
    size = [1.5, 1.0, 1.2]
    antennas = bases + [0.0, 0.0, 0.5]
    bus = MovingBoxes.from_bases(np.array([[[0.0, -6.0, 0.0]]]), yaw_rotations(np.array([[0.0]])), [10, 2.5, 3])
    az, el = np.meshgrid(np.arange(0.0, 360.0, 10.0), np.arange(11.0, 50.0, 5.0), indexing="ij")
    sat = sats_at(open_scene, antennas[0], az.ravel(), el.ravel())
    opts = VisibilityOptions(mask_deg=10.0)
    batched, _, _ = opts.cast(open_scene, antennas, sat, obstacles=fleet_bodies(bases, yaw, size)
                              .concat(bus.repeat_rows(3)))
    assert (batched == BLOCKED).any(axis=1).all()
    for i in range(3):
        others = np.delete(np.arange(3), i)
        alone = MovingBoxes.from_bases(bases[None, others], yaw_rotations(yaw[others])[None], size).concat(bus)
        one, _, _ = opts.cast(open_scene, antennas[i], sat, obstacles=alone)
        assert np.array_equal(one, batched[i])

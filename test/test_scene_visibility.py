"""Visibility core against analytic scenes.

Expected values come from geometry, not from the code: the top edge of a wall
of height H at distance d is seen at elevation atan(H / d); a ray crosses an
axis-aligned box along the slab-method chord; away from the world origin the
geodetic up tilts by s / (N + h) (N = prime-vertical radius of curvature,
WGS 84) in the direction of the offset s.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from gnss_sim_ros2.core import frames
from gnss_sim_ros2.core.constants import WGS84_A_M, WGS84_F
from gnss_sim_ros2.core.scene.mesh_io import export_world
from gnss_sim_ros2.core.scene.raycast import RayScene
from gnss_sim_ros2.core.scene.visibility import (
    STATE_ATTENUATED,
    STATE_BELOW_MASK,
    STATE_BLOCKED,
    STATE_VISIBLE,
    Scene,
    knife_edge_loss_db,
)

LAT0, LON0, H0 = 50.0764, 14.4179, 250.0
REPO = Path(__file__).resolve().parents[1]


def world_sdf(tmp_path, models: str, heading_deg=0.0, name="w.sdf"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(f"""\
        <?xml version="1.0"?>
        <sdf version="1.9" xmlns:gnss_sim="urn:gnss_sim"><world name="w">
          <spherical_coordinates><latitude_deg>{LAT0}</latitude_deg><longitude_deg>{LON0}</longitude_deg>
            <elevation>{H0}</elevation><heading_deg>{heading_deg}</heading_deg></spherical_coordinates>
        """) + models + "</world></sdf>\n")
    return p


def box_model(name, center, size, yaw_deg=0.0):
    c = " ".join(map(str, center))
    s = " ".join(map(str, size))
    return (f'<model name="{name}"><static>true</static><pose degrees="true">{c} 0 0 {yaw_deg}</pose>'
            f'<link name="L"><collision name="c"><geometry><box><size>{s}</size></box></geometry></collision>'
            f"</link></model>\n")


def wall_scene(tmp_path, d, h, width=10.0, thick=0.3, heading_deg=0.0, x0=0.0):
    """Wall with its near face at world x = x0 + d, spanning |y| <= width/2, z in [0, h]."""
    return Scene.from_sdf(world_sdf(tmp_path, box_model("wall", (x0 + d + thick / 2, 0, h / 2), (thick, width, h)),
                                    heading_deg))


def threshold_sweep(scene, antenna, az_deg, el_expected, span=0.2, step=0.01):
    """Elevations across the expected edge: returns (elevations, blocked bool)."""
    el = np.arange(el_expected - span, el_expected + span + 1e-9, step)
    r = scene.visibility(np.asarray(antenna, float), az_deg=np.full(el.shape, az_deg), el_deg=el)
    return el, r.state == STATE_BLOCKED


def assert_edge(el, blocked, el_expected, tol_deg=0.05):
    # every direction more than tol below the edge is blocked, every one more than tol above is clear
    assert np.all(blocked[el < el_expected - tol_deg]), el[~blocked & (el < el_expected - tol_deg)]
    assert not np.any(blocked[el > el_expected + tol_deg]), el[blocked & (el > el_expected + tol_deg)]
    top_blocked = el[blocked].max()
    assert abs(top_blocked - el_expected) <= tol_deg


# ------------------------------------------------------------------ wall: elevation threshold
def test_wall_hides_exactly_below_its_top(tmp_path):
    d, h = 20.0, 15.0
    scene = wall_scene(tmp_path, d, h)
    el_top = math.degrees(math.atan2(h, d))            # antenna at the wall's base height z = 0
    el, blocked = threshold_sweep(scene, (0, 0, 0), 90.0, el_top)
    assert_edge(el, blocked, el_top)
    # azimuth sector: the wall spans +-atan(5 / 20) = +-14.04 deg around east
    half = math.degrees(math.atan2(5.0, d))
    az = np.array([90 - half + 0.2, 90 + half - 0.2, 90 - half - 0.2, 90 + half + 0.2, 270.0])
    r = scene.visibility(np.zeros(3), az_deg=az, el_deg=np.full(5, 10.0))
    assert list(r.state) == [STATE_BLOCKED, STATE_BLOCKED, STATE_VISIBLE, STATE_VISIBLE, STATE_VISIBLE]


def test_antenna_above_ground_and_mask(tmp_path):
    d, h, z = 12.0, 9.0, 1.5
    scene = wall_scene(tmp_path, d, h)
    el_top = math.degrees(math.atan2(h - z, d))
    el, blocked = threshold_sweep(scene, (0, 0, z), 90.0, el_top)
    assert_edge(el, blocked, el_top)
    r = scene.visibility(np.array([0, 0, z]), az_deg=[90, 90, 90], el_deg=[4.9, 5.0, 20.0], mask_deg=5.0)
    assert list(r.state) == [STATE_BELOW_MASK, STATE_BLOCKED, STATE_BLOCKED]


def test_below_mask_is_never_cast(tmp_path, monkeypatch):
    scene = wall_scene(tmp_path, 10.0, 5.0)
    cast = []
    orig = RayScene.occluded_buffer

    def spy(self, rays, **kw):
        cast.append(len(rays))
        return orig(self, rays, **kw)

    monkeypatch.setattr(RayScene, "occluded_buffer", spy)
    r = scene.visibility(np.zeros(3), az_deg=[0, 90, 180, 270], el_deg=[-10, 2, 30, 9.99], mask_deg=10)
    assert cast == [1] and list(r.state) == [STATE_BELOW_MASK, STATE_BELOW_MASK, STATE_VISIBLE, STATE_BELOW_MASK]


def test_heading_rotates_azimuths(tmp_path):
    # gz-math: enu = Rz(+heading) world, so world +x points at compass azimuth 90 - heading
    heading = 30.0
    d, h = 20.0, 15.0
    scene = wall_scene(tmp_path, d, h, heading_deg=heading)
    az_wall = 90.0 - heading
    el_top = math.degrees(math.atan2(h, d))
    el, blocked = threshold_sweep(scene, (0, 0, 0), az_wall, el_top)
    assert_edge(el, blocked, el_top)
    # at compass east (where the wall would be without the heading) the sky is clear: 30 deg > 14 deg half-sector
    r = scene.visibility(np.zeros(3), az_deg=[90.0, az_wall], el_deg=[10.0, 10.0])
    assert list(r.state) == [STATE_VISIBLE, STATE_BLOCKED]
    az, el_sky = scene.horizon_profile(np.zeros(3), az_step_deg=1.0)
    assert el_sky[int(az_wall)] == pytest.approx(el_top, abs=0.01)
    assert el_sky[90] == 0.0


def test_antenna_100km_from_origin_uses_local_geodetic_up(tmp_path):
    s = 100_000.0
    d, h = 20.0, 15.0
    scene = wall_scene(tmp_path, d, h, x0=s)
    # tilt of geodetic up 100 km east of the origin: s / (N + h0) about the local north axis
    e2 = WGS84_F * (2 - WGS84_F)
    n_m = WGS84_A_M / math.sqrt(1 - e2 * math.sin(math.radians(LAT0)) ** 2)
    tilt_deg = math.degrees(math.atan2(s, n_m + H0))
    assert 0.85 < tilt_deg < 0.95
    el_top = math.degrees(math.atan2(h, d)) + tilt_deg     # local horizon dips toward the east by the tilt
    # the antenna's local east is not world +x either (meridian convergence ~1.07 deg): look along world +x
    R = scene.world_from_local_enu(np.array([s, 0, 0]))[0]
    east_world = R[:, 0]
    az_world_x = (90.0 + math.degrees(math.atan2(east_world[1], east_world[0]))) % 360.0
    el, blocked = threshold_sweep(scene, (s, 0, 0), az_world_x, el_top)
    assert_edge(el, blocked, el_top)
    # without the rotation the edge would be at atan(h/d): half a degree above it is still blocked
    r = scene.visibility(np.array([s, 0, 0]), az_deg=[az_world_x], el_deg=[math.degrees(math.atan2(h, d)) + 0.5])
    assert r.state[0] == STATE_BLOCKED


def test_visibility_ecef_matches_az_el(tmp_path):
    d, h = 20.0, 15.0
    scene = wall_scene(tmp_path, d, h)
    ant = np.array([0.0, 0.0, 0.0])
    rx = frames.geodetic_to_ecef(LAT0, LON0, H0)
    az = np.array([90.0, 90.0, 200.0])
    el = np.array([30.0, 45.0, 60.0])
    sat = frames.enu_to_ecef(2.0e7 * frames.enu_unit_from_az_el(az, el), LAT0, LON0, H0)
    r = scene.visibility_ecef(ant, sat)
    np.testing.assert_allclose(r.az_deg, az, atol=1e-6)
    np.testing.assert_allclose(r.el_deg, el, atol=1e-6)
    assert list(r.state) == [STATE_BLOCKED, STATE_VISIBLE, STATE_VISIBLE]   # atan(15/20) = 36.87 deg
    assert np.allclose(rx, scene.antenna_ecef(ant))


# ------------------------------------------------------------------ foliage
def slab_chord(o, dvec, lo, hi):
    """Length of the ray o + t d (t >= 0) inside the box [lo, hi] (slab method)."""
    with np.errstate(divide="ignore"):
        t1 = (np.asarray(lo) - o) / dvec
        t2 = (np.asarray(hi) - o) / dvec
    tmin = np.max(np.minimum(t1, t2))
    tmax = np.min(np.maximum(t1, t2))
    return max(0.0, tmax - max(tmin, 0.0))


def test_foliage_box_attenuation_is_chord_times_rate(tmp_path):
    rate = 2.0
    y = tmp_path / "m.yaml"
    y.write_text(f"classes:\n  foliage: {{attenuation_db_per_m: {rate}}}\n")
    lo, hi = np.array([5.0, -3.0, 2.0]), np.array([11.0, 4.0, 9.0])
    world = world_sdf(tmp_path, box_model("hedge", (lo + hi) / 2, hi - lo))
    scene = Scene.from_sdf(world, materials_yaml=y)
    assert scene.has_foliage
    ant = np.array([0.0, 0.5, 0.5])
    az = np.array([90.0, 80.0, 100.0, 60.0, 90.0, 270.0])
    el = np.array([20.0, 35.0, 10.0, 40.0, 75.0, 20.0])
    r = scene.visibility(ant, az_deg=az, el_deg=el)
    dirs = frames.enu_unit_from_az_el(az, el)
    chords = np.array([slab_chord(ant, dv, lo, hi) for dv in dirs])
    assert (chords > 0).sum() >= 4 and chords[-1] == 0
    np.testing.assert_allclose(r.path_in_foliage_m, chords, atol=2e-3)
    np.testing.assert_allclose(r.attenuation_db, rate * chords, atol=4e-3)
    np.testing.assert_array_equal(r.state, np.where(chords > 0, STATE_ATTENUATED, STATE_VISIBLE))
    # antenna inside the volume: the path is the distance to the exit face
    inside = np.array([8.0, 0.0, 5.0])
    r = scene.visibility(inside, az_deg=[0.0, 90.0], el_deg=[0.0, 90.0])
    np.testing.assert_allclose(r.path_in_foliage_m, [4.0, 4.0], atol=2e-3)


def test_foliage_then_wall_is_blocked_and_sphere_crown(tmp_path):
    models = (box_model("bush", (10, 0, 5), (4, 4, 4)) + box_model("wall", (20, 0, 10), (1, 20, 20))
              + '<model name="tree_a"><static>true</static><pose>0 30 6 0 0 0</pose><link name="crown">'
              '<collision name="c"><geometry>'
              '<sphere><radius>3</radius></sphere></geometry></collision></link></model>')
    scene = Scene.from_sdf(world_sdf(tmp_path, models))
    r = scene.visibility(np.zeros(3), az_deg=[90.0], el_deg=[math.degrees(math.atan2(5, 10))])
    assert r.state[0] == STATE_BLOCKED
    # ray through the centre of the sphere crown: chord = diameter 6 m (icosphere: within 1 %)
    el_c = math.degrees(math.atan2(6, 30))
    r = scene.visibility(np.zeros(3), az_deg=[0.0], el_deg=[el_c])
    from gnss_sim_ros2.core.constants import FOLIAGE_ATTENUATION_DB_PER_M

    assert r.state[0] == STATE_ATTENUATED
    assert r.path_in_foliage_m[0] == pytest.approx(6.0, rel=0.01)
    assert r.attenuation_db[0] == pytest.approx(6.0 * FOLIAGE_ATTENUATION_DB_PER_M, rel=0.01)


def test_scene_without_foliage_uses_only_occlusion_test(tmp_path, monkeypatch):
    scene = wall_scene(tmp_path, 10.0, 5.0)
    assert not scene.has_foliage

    def boom(*a, **k):
        raise AssertionError("penetration query used on a scene without foliage")

    monkeypatch.setattr(RayScene, "penetration", boom)
    r = scene.visibility(np.zeros(3), az_deg=[90.0, 90.0], el_deg=[10.0, 60.0])
    assert list(r.state) == [STATE_BLOCKED, STATE_VISIBLE]


def test_batched_epochs_and_satellites(tmp_path):
    d, h = 20.0, 15.0
    scene = wall_scene(tmp_path, d, h)
    ants = np.array([[0.0, 0, 0], [10.0, 0, 0], [-30.0, 0, 0]])          # distances 20, 10, 50
    el = np.array([30.0, 50.0, 20.0])
    r = scene.visibility(ants, az_deg=np.full((3, 3), 90.0), el_deg=np.broadcast_to(el, (3, 3)))
    expected = np.array([[el_i < math.degrees(math.atan2(h, dd)) for el_i in el] for dd in (20.0, 10.0, 50.0)])
    np.testing.assert_array_equal(r.state == STATE_BLOCKED, expected)


# ------------------------------------------------------------------ Fresnel / knife edge
def test_knife_edge_loss_reference_points():
    # ITU-R P.526 J(nu): 6.03 dB at grazing (nu = 0, half the disc blocked); 0 dB when clear
    assert knife_edge_loss_db(0.5) == pytest.approx(6.03, abs=0.05)
    assert knife_edge_loss_db(0.0) == 0.0
    loss = knife_edge_loss_db(np.linspace(0, 1, 11))
    assert np.all(np.diff(loss) >= 0)


def test_fresnel_fraction_at_a_straight_edge(tmp_path):
    d, h = 20.0, 15.0
    scene = wall_scene(tmp_path, d, h, width=60.0)
    el_top = math.degrees(math.atan2(h, d))
    r = scene.visibility(np.zeros(3), az_deg=[90.0, 90.0, 90.0], el_deg=[el_top, el_top + 20, el_top - 20],
                         fresnel_rays=64)
    # a long straight edge through the centre of the disc blocks half of it -> ~6 dB
    assert r.fraction_blocked[0] == pytest.approx(0.5, abs=0.08)
    assert r.diffraction_db[0] == pytest.approx(6.0, abs=1.0)
    assert r.fraction_blocked[1] == 0.0 and r.diffraction_db[1] == 0.0
    assert r.fraction_blocked[2] == 1.0 and r.state[2] == STATE_BLOCKED


# ------------------------------------------------------------------ demo world
@pytest.fixture(scope="module")
def demo_scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "courtyard.ply"
    export_world(REPO / "worlds" / "courtyard.sdf", out)
    return Scene.load(out)


def dense_sky(step=5.0):
    az, el = np.meshgrid(np.arange(0, 360, step), np.arange(step, 90, step), indexing="ij")
    return az.ravel(), el.ravel()


def test_demo_world_courtyard_vs_open_ground(demo_scene):
    az, el = dense_sky()
    open_ground = demo_scene.visibility(np.array([0.0, -70.0, 1.0]), az_deg=az, el_deg=el, mask_deg=10)
    yard = demo_scene.visibility(np.array([0.0, 0.0, 1.0]), az_deg=az, el_deg=el, mask_deg=10)
    n_open = (open_ground.state == STATE_VISIBLE).sum()
    n_yard = (yard.state == STATE_VISIBLE).sum()
    assert n_yard < 0.8 * n_open
    # yard centre: the 25 m north wing 15 m away hides the north up to atan(24/15) = 58.0 deg
    north = (az == 0) & (el >= 15)
    assert np.all(yard.state[north & (el < 57)] == STATE_BLOCKED)
    assert np.all(yard.state[north & (el > 59)] != STATE_BLOCKED)


def test_demo_world_trees_and_ledge(demo_scene):
    az, el = dense_sky()
    under_tree = demo_scene.visibility(np.array([-8.5, 5.0, 1.0]), az_deg=az, el_deg=el, mask_deg=10)
    att = under_tree.attenuation_db[under_tree.state == STATE_ATTENUATED]
    assert len(att) > 50
    # crown radius 3 m: chords up to 6 m at 1.85 dB/m
    assert 0 < att.max() <= 6.0 * 1.85 * 1.01
    under_ledge = demo_scene.visibility(np.array([17.0, -3.0, 1.0]), az_deg=[0.0, 123.0], el_deg=[90.0, 60.0])
    assert list(under_ledge.state) == [STATE_BLOCKED, STATE_BLOCKED]
    az_h, el_h = demo_scene.horizon_profile(np.array([0.0, 0.0, 1.0]))
    assert el_h[0] == pytest.approx(math.degrees(math.atan2(24, 15)), abs=0.01)
    assert el_h[180] < el_h[0]   # the gate in the south


# ------------------------------------------------------------------ command line
def test_skyplot_command_with_real_navigation(opec_dir, tmp_path):
    import csv

    from gnss_sim_ros2.cli import main

    nav = [str(p) for p in sorted(opec_dir.glob("OPEC00NOR_S_20220010000_01D_*N.rnx"))]
    assert nav
    out_csv, out_png = tmp_path / "sky.csv", tmp_path / "sky.png"
    rc = main(["skyplot", "--world", str(REPO / "worlds" / "courtyard.sdf"), "--at", "0,0,1",
               "--time", "2022-01-01T00:05:00", "--nav", *nav, "--mask-deg", "5",
               "--csv", str(out_csv), "--png", str(out_png)])
    assert rc == 0 and out_png.stat().st_size > 10_000
    rows = list(csv.DictReader(out_csv.open()))
    assert len(rows) > 15 and set(rows[0]) == {"sv", "az_deg", "el_deg", "state", "attenuation_db"}
    assert {r["state"] for r in rows} <= {"visible", "blocked", "attenuated"}
    el = np.array([float(r["el_deg"]) for r in rows])
    az = np.array([float(r["az_deg"]) for r in rows])
    assert el.min() >= 5.0
    # outside the gate (az 165-195) the lowest skyline is the 12 m south-west wing's corner (-20, -15):
    # atan(11 / 25) = 23.7 deg seen from (0, 0, 1)
    low = (el < 23.5) & ((az < 160) | (az > 200))
    assert low.any() and all(r["state"] == "blocked" for r, k in zip(rows, low) if k)


def test_skyplot_command_synthetic(tmp_path):
    import csv

    from gnss_sim_ros2.cli import main

    out_csv = tmp_path / "sky.csv"
    rc = main(["skyplot", "--world", str(REPO / "worlds" / "courtyard.sdf"), "--at", "0,-70,1",
               "--time", "2022-01-01T00:05:00", "--synthetic", "--mask-deg", "10", "--csv", str(out_csv)])
    assert rc == 0
    rows = list(csv.DictReader(out_csv.open()))
    assert len(rows) >= 4
    assert all(float(r["el_deg"]) >= 10.0 and r["state"] in {"visible", "blocked", "attenuated"} for r in rows)


def test_horizon_profile_of_an_antenna_closed_in_on_every_side():
    """An antenna inside a closed box (e.g. placed under a city model's ground): every azimuth is blocked up to the
    zenith, nothing is left to refine, and the profile says 90 deg everywhere; the foliage profile of a scene
    without foliage has nothing to refine either and is 0 everywhere (it failed reshaping an empty cast)."""
    from multipath_scenes import _box

    from gnss_sim_ros2.core.scene.materials import MaterialTable
    from gnss_sim_ros2.core.scene.visibility import Scene
    from gnss_sim_ros2.core.scene.world_mesh import WorldMesh

    v, f = _box(-5.0, 5.0, -5.0, 5.0, -5.0, 5.0)
    scene = Scene(WorldMesh(v, f, np.zeros(len(f), np.int16), MaterialTable()))
    az, el = scene.horizon_profile(np.zeros(3), az_step_deg=10.0)
    assert len(az) == 36 and np.all(el == 90.0)
    _, el_foliage = scene.horizon_profile(np.zeros(3), az_step_deg=10.0, which="foliage")
    assert np.all(el_foliage == 0.0)


def test_enu_rows_of_a_few_points_on_python_floats_equal_numpys(monkeypatch):
    """_enu_rows_at_ecef and _local_enu_rows of a few points (a fleet's antennas) on Python floats: the same bits as
    their numpy path, the polar axis (longitude 0) included."""
    from gnss_sim_ros2.core.scene import visibility as vis

    rng = np.random.default_rng(5)
    few, many = [], []
    for k in range(400):
        n = int(rng.integers(1, vis._FEW_POINTS + 1))
        lat, lon = rng.uniform(-0.5 * np.pi, 0.5 * np.pi, n), rng.uniform(-np.pi, np.pi, n)
        r = WGS84_A_M + rng.uniform(-2.2e4, 1.0e5, n)
        ecef = np.stack([r * np.cos(lat) * np.cos(lon), r * np.cos(lat) * np.sin(lon), r * np.sin(lat)], axis=1)
        if k % 40 == 0:
            ecef[0, :2] = 0.0
        few.append((vis._enu_rows_at_ecef(ecef).tobytes(), vis._local_enu_rows(np.degrees(lat), np.degrees(lon))))
        with monkeypatch.context() as mp:
            mp.setattr(vis, "_FEW_POINTS", 0)
            many.append((vis._enu_rows_at_ecef(ecef).tobytes(),
                         vis._local_enu_rows(np.degrees(lat), np.degrees(lon))))
    few = [(a, b.tobytes()) for a, b in few]
    many = [(a, b.tobytes()) for a, b in many]
    assert few == many

"""Sky masks (issue 27): the CSV reader, the comparison with a scene's skyline, the mask as the scene of a static
antenna in ``gnss-sim simulate --sky-mask`` and the combinations refused."""
from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np
import pytest

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.visibility.sky_mask import (
    SkyMask,
    SkyMaskScene,
    compare_skylines,
    read_sky_mask,
    sector_count,
)
from gnss_sim_ros2.core.vocabulary import VisibilityState

HK = "22.3,114.17,10"


def _write(path, text):
    path.write_text(text)
    return path


# ------------------------------------------------------------------ reader
def test_reader_sorts_skips_comments_and_interpolates_periodically(tmp_path):
    f = _write(tmp_path / "m.csv", "# fisheye survey, point A\nelevation_deg,azimuth_deg,note\n"
                                   "20,350,x\n\n10,10,y\n40,180,z\n")
    m = read_sky_mask(f)
    np.testing.assert_array_equal(m.az_deg, [10.0, 180.0, 350.0])
    np.testing.assert_array_equal(m.el_deg, [10.0, 40.0, 20.0])
    # across north: 350 -> 20 deg, 10 -> 10 deg, so 0 is half way (15) and 5 three quarters (12.5)
    np.testing.assert_allclose(m.elevation_at([0.0, 5.0, 360.0, -10.0, 95.0]), [15.0, 12.5, 15.0, 20.0, 25.0])
    assert list(m.blocked([0.0, 0.0, 180.0], [14.9, 15.0, 41.0])) == [True, False, False]
    one = read_sky_mask(_write(tmp_path / "one.csv", "azimuth_deg,elevation_deg\n123,7.5\n"))
    np.testing.assert_array_equal(one.elevation_at([0.0, 200.0]), [7.5, 7.5])


@pytest.mark.parametrize("body, line, words", [
    ("azimuth_deg,elevation_deg\n0,10\n90,abc\n", 3, ["must be numbers"]),
    ("azimuth_deg,elevation_deg\n0,10\n360,5\n", 3, ["azimuth_deg 360", "[0, 360)"]),
    ("azimuth_deg,elevation_deg\n-1,10\n", 2, ["azimuth_deg -1"]),
    ("azimuth_deg,elevation_deg\n0,10\n# c\n45,95\n", 4, ["elevation_deg 95", "[-90, 90]"]),
    ("azimuth_deg,elevation_deg\n0,10\n90,nan\n", 3, ["elevation_deg nan"]),
    ("azimuth_deg,elevation_deg\n90,10\n0,5\n90,12\n", 4, ["given twice", "line 2"]),
    ("azimuth_deg,elevation_deg\n0\n", 2, ["1 columns"]),
    ("az,el\n0,10\n", 1, ["lacks azimuth_deg, elevation_deg"]),
])
def test_reader_names_the_file_and_line_of_a_bad_row(tmp_path, body, line, words):
    f = _write(tmp_path / "bad.csv", body)
    with pytest.raises(ValueError) as exc:
        read_sky_mask(f)
    msg = str(exc.value)
    assert f"{f}:{line}:" in msg, msg
    for w in words:
        assert w in msg, msg


def test_reader_refuses_empty_and_missing_files(tmp_path):
    for body in ("", "# only a comment\n", "azimuth_deg,elevation_deg\n"):
        with pytest.raises(ValueError, match="sky mask .*empty|no row"):
            read_sky_mask(_write(tmp_path / "e.csv", body))
    with pytest.raises(ValueError, match="cannot read"):
        read_sky_mask(tmp_path / "absent.csv")


def test_skyline_csv_of_skyplot_round_trips_as_a_mask(tmp_path):
    from gnss_sim_ros2.commands.skyplot import write_skyline_csv

    az = np.arange(0.0, 360.0, 1.0)
    el = 30.0 + 20.0 * np.sin(np.radians(3 * az))
    write_skyline_csv(tmp_path / "skyline.csv", az, el, np.zeros_like(az))
    m = read_sky_mask(tmp_path / "skyline.csv")
    np.testing.assert_allclose(m.az_deg, az)
    np.testing.assert_allclose(m.el_deg, el, atol=5e-4)          # written with 3 decimals
    c = compare_skylines(az, el, m)
    assert c.r > 0.999999 and c.rms_deg < 5e-4


# ------------------------------------------------------------------ comparison
def test_compare_skylines_sectors_r_and_misses():
    az = np.arange(0.0, 360.0, 1.0)
    model = 20.0 + 10.0 * np.cos(np.radians(az))
    mask = SkyMask(az.copy(), model.copy())
    bumped = model.copy()
    bumped[(az >= 120) & (az < 150)] += 15.0                     # the mask 15 deg higher in one sector
    c = compare_skylines(az, model, SkyMask(az, bumped), sector_deg=30.0)
    assert len(c.sectors) == 12
    lo, hi, mean, rms, miss, miss_az = c.largest_misses(1)[0]
    assert (lo, hi) == (120.0, 150.0) and 120 <= miss_az < 150
    np.testing.assert_allclose([mean, rms, miss], [-15.0, 15.0, -15.0], atol=1e-9)
    assert all(abs(s[2]) < 1e-9 and abs(s[4]) < 1e-9 for s in c.sectors if s[0] != 120.0)
    assert c.mean_deg == pytest.approx(-15.0 * 30 / 360)
    assert c.rms_deg == pytest.approx(15.0 * math.sqrt(30 / 360))
    assert c.r < 0.95 and compare_skylines(az, model, mask).r == pytest.approx(1.0)
    assert math.isnan(compare_skylines(az, np.zeros_like(az), mask).r)     # a flat skyline has no r
    assert sector_count(45.0) == 8
    for bad in (0.0, -30.0, 7.0, 400.0, float("nan")):
        with pytest.raises(ValueError, match="option --sector-deg"):
            sector_count(bad, "option --sector-deg")


def _wall_world(tmp_path):
    # a wall 60 m wide, 20 m high, its south face 19 m north of the origin; the world at 22.3 N, 114.17 E
    w = tmp_path / "wall.sdf"
    w.write_text('<sdf version="1.9"><world name="w"><spherical_coordinates><surface_model>EARTH_WGS84'
                 '</surface_model><latitude_deg>22.3</latitude_deg><longitude_deg>114.17</longitude_deg><elevation>10'
                 '</elevation><heading_deg>0</heading_deg></spherical_coordinates><model name="wall"><static>true'
                 '</static><pose>0 20 10 0 0 0</pose><link name="l"><collision name="c"><geometry><box><size>60 2 20'
                 '</size></box></geometry></collision></link></model></world></sdf>')
    return w


def _wall_mask_deg(az_deg, h_m=1.5):
    """The wall's skyline from the antenna at (0, 0, h): elevation atan((20 - h) / (19 / cos az)) where the ray
    meets the face (|19 tan az| <= 30 m), else 0."""
    a = np.radians(az_deg)
    on = (np.cos(a) > 0) & (np.abs(19.0 * np.tan(a)) <= 30.0)
    return np.where(on, np.degrees(np.arctan2((20.0 - h_m) * np.cos(a), 19.0)), 0.0)


def test_measured_mask_against_a_box_scenes_skyline(tmp_path):
    from gnss_sim_ros2.core.scene.loader import load_sdf_world
    from gnss_sim_ros2.core.scene.visibility import Scene

    scene = Scene(load_sdf_world(_wall_world(tmp_path)))
    at = np.array([0.0, 0.0, 1.5])
    az, model = scene.horizon_profile(at, az_step_deg=1.0)
    grid = np.arange(0.0, 360.0, 0.25)
    exact = SkyMask(grid, _wall_mask_deg(grid))
    c = compare_skylines(az, model, exact)
    # the analytic wall: the casts agree except at the wall's two corners (a 0.25 deg grid interpolates the step)
    assert c.r > 0.98
    assert max(abs(s[2]) for s in c.sectors) < 1.0
    missed = exact.el_deg.copy()
    missed[(grid >= 90) & (grid < 120)] = 15.0                   # a building east the model lacks
    c2 = compare_skylines(az, model, SkyMask(grid, missed))
    worst = c2.largest_misses(1)[0]
    assert worst[:2] == (90.0, 120.0) and worst[4] == pytest.approx(-15.0) and worst[2] == pytest.approx(-15.0)
    assert c2.r < c.r


def test_skyplot_sky_mask_report_and_png(tmp_path):
    world = _wall_world(tmp_path)
    grid = np.arange(0.0, 360.0, 0.5)
    mask = tmp_path / "mask.csv"
    mask.write_text("azimuth_deg,elevation_deg\n" + "".join(f"{a},{e:.4f}\n" for a, e in zip(grid, np.where(
        (grid >= 180) & (grid < 210), 25.0, _wall_mask_deg(grid)))))
    rc = main(["skyplot", "--world", str(world), "--at", "0,0,1.5", "--time", "2025-06-01T10:00:00", "--synthetic",
               "--csv", str(tmp_path / "sky.csv"), "--png", str(tmp_path / "sky.png"), "--sky-mask", str(mask)])
    assert rc == 0
    rows = [ln.split(",") for ln in (tmp_path / "sky_mask_comparison.csv").read_text().splitlines()]
    assert rows[0] == ["sector", "az_from_deg", "az_to_deg", "mean_diff_deg", "rms_diff_deg", "miss_deg",
                       "miss_az_deg", "r"]
    by = {r[0]: r for r in rows[1:]}
    assert len(by) == 13 and float(by["6"][3]) == pytest.approx(-25.0, abs=0.01)    # sector 180-210
    assert abs(float(by["all"][5]) + 25.0) < 0.01 and 0.0 < float(by["all"][7]) < 1.0
    assert (tmp_path / "sky.png").stat().st_size > 0 and (tmp_path / "skyline.csv").is_file()


def test_plot_draws_the_mask(tmp_path):
    from gnss_sim_ros2.core.skyplot import plot_skyplot

    art = plot_skyplot(tmp_path / "s.png", ["G01"], [10.0], [30.0], ["visible"], sky_mask=([0.0, 180.0], [20.0, 40.0]))
    assert art["sky_mask"] is not None and "measured mask" in art["legend"]
    assert plot_skyplot(tmp_path / "t.png", ["G01"], [10.0], [30.0], ["visible"])["sky_mask"] is None


# ------------------------------------------------------------------ the mask as a scene
def test_sky_mask_scene_states_from_az_el():
    from gnss_sim_ros2.core.frames import az_el_from_ecef, geodetic_to_ecef

    mask = SkyMask(np.array([0.0, 90.0, 180.0, 270.0]), np.array([10.0, 40.0, 10.0, 40.0]))
    rx = np.array(geodetic_to_ecef(22.3, 114.17, 10.0))
    scene = SkyMaskScene.at_ecef(mask, rx)
    rng = np.random.default_rng(1)
    sat = rx + rng.normal(size=(500, 3)) * 2.0e7
    world = scene.spherical.ecef_to_world(rx)
    assert np.linalg.norm(world) < 1e-6
    v = scene.visibility_ecef(world, sat, mask_deg=5.0)
    az, el, _ = az_el_from_ecef(rx, sat)
    np.testing.assert_allclose(v.az_deg, az, atol=1e-9)
    want = np.where(el < 5.0, -1, np.where(el < mask.elevation_at(az), int(VisibilityState.BLOCKED),
                                            int(VisibilityState.VISIBLE)))
    np.testing.assert_array_equal(v.state, want)
    assert (want == int(VisibilityState.BLOCKED)).sum() > 20 and (want == int(VisibilityState.VISIBLE)).sum() > 20
    vk = scene.visibility_ecef(np.stack([world, world]), np.stack([sat, sat]), mask_deg=5.0)   # (M, N)
    np.testing.assert_array_equal(vk.state, np.stack([want, want]))
    with pytest.raises(ValueError, match="fresnel_rays"):
        scene.visibility_ecef(world, sat, fresnel_rays=8)


def _simulate_args(tmp_path, *extra):
    from gnss_sim_ros2.commands import simulate

    p = argparse.ArgumentParser()
    simulate.add_arguments(p)
    return p.parse_args(["--out", str(tmp_path / "out"), "--quiet", "--duration", "20", "--interval", "10", *extra])


def test_simulate_sky_mask_blocks_exactly_the_satellites_under_it(tmp_path):
    from gnss_sim_ros2.commands.simulate import setup_from_args
    from gnss_sim_ros2.core.simulation import run_simulation

    mask = _write(tmp_path / "m.csv", "azimuth_deg,elevation_deg\n0,45\n90,45\n170,45\n190,5\n350,5\n")
    m = read_sky_mask(mask)
    seen = []
    setup = setup_from_args(_simulate_args(tmp_path, "--sky-mask", str(mask), "--position", HK))
    setup = dataclasses.replace(setup, observer=lambda t, ecef, obs, sol: seen.append(obs))
    res = run_simulation(setup)
    assert res.epochs == 3 and len(seen) == 3
    n_blocked = n_visible = 0
    for obs in seen:
        az, el, state = np.asarray(obs.sat_az_deg), np.asarray(obs.sat_el_deg), np.asarray(obs.sat_vis_state)
        edge = m.elevation_at(az)
        # the receiver's az/el vs the cast's: equal far from the edge; under the elevation mask nothing is cast
        # (VisibilityOptions.cast: VISIBLE, not tracked), as with a 3D scene
        sure = (np.abs(el - edge) > 0.01) & (el >= setup.elevation_mask_deg)
        under = el < edge
        assert np.all(state[sure & under] == int(VisibilityState.BLOCKED))
        assert np.all(state[sure & ~under] == int(VisibilityState.VISIBLE))
        n_blocked += int((sure & under).sum())
        n_visible += int((sure & ~under).sum())
    assert n_blocked >= 5 and n_visible >= 5
    # the blocked ones are not tracked: fewer satellites than the open sky run
    open_sky = run_simulation(setup_from_args(_simulate_args(tmp_path / "open", "--position", HK)))
    assert max(res.tracked_per_epoch) < min(open_sky.tracked_per_epoch)


@pytest.mark.parametrize("extra, words", [
    (["--trajectory", "PATH"], ["static antenna"]),
    ([], ["static antenna"]),
    (["--position", HK, "--preset", "accurate"], ["multipath 'full'", "fresnel_rays 8"]),
    (["--position", HK, "--config", "CONFIG"], ["option --sky-mask (parameter 'sky_mask_csv')", "world_file"]),
    (["--position", HK, "--world", "x.sdf"], ["not allowed with argument --sky-mask"]),
    (["--position", HK, "--mesh", "x.mesh"], ["not allowed with argument --sky-mask"]),
])
def test_simulate_sky_mask_bad_combinations_rc2(tmp_path, capsys, extra, words):
    mask = _write(tmp_path / "m.csv", "azimuth_deg,elevation_deg\n0,20\n")
    path = _write(tmp_path / "path.csv", "t_s,lat_deg,lon_deg,h_m\n0,22.3,114.17,10\n10,22.3001,114.17,10\n")
    cfg = _write(tmp_path / "cfg.yaml", "gnss_sim_visibility:\n  ros__parameters:\n    world_file: w.sdf\n")
    extra = [str(path) if e == "PATH" else str(cfg) if e == "CONFIG" else e for e in extra]
    with pytest.raises(SystemExit) as exc:
        raise SystemExit(main(["simulate", "--sky-mask", str(mask), "--out", str(tmp_path / "o"), "--quiet",
                               "--duration", "10", *extra]))
    assert exc.value.code == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err, err
    assert "Traceback" not in err and not (tmp_path / "o").exists()


def test_simulate_bad_mask_row_rc2(tmp_path, capsys):
    mask = _write(tmp_path / "m.csv", "azimuth_deg,elevation_deg\n0,20\n400,3\n")
    assert main(["simulate", "--sky-mask", str(mask), "--position", HK, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert f"{mask}:3: azimuth_deg 400" in capsys.readouterr().err


@pytest.mark.parametrize("mask_text, extra, words", [
    ("azimuth_deg,elevation_deg\n0,20\n10,91\n", [], [":3: elevation_deg 91"]),
    ("azimuth_deg,elevation_deg\n0,20\n", ["--sector-deg", "7"], ["option --sector-deg 7.0"]),
])
def test_skyplot_bad_mask_or_sector_rc2(tmp_path, capsys, mask_text, extra, words):
    mask = _write(tmp_path / "m.csv", mask_text)
    rc = main(["skyplot", "--world", str(_wall_world(tmp_path)), "--at", "0,0,1.5", "--time", "2025-06-01T10:00:00",
               "--synthetic", "--csv", str(tmp_path / "sky.csv"), "--sky-mask", str(mask), *extra])
    err = capsys.readouterr().err
    assert rc == 2 and all(w in err for w in words), err
    assert not (tmp_path / "sky.csv").exists() and not (tmp_path / "sky_mask_comparison.csv").exists()


def test_sky_mask_parameter_bad_csv_names_file_line_and_parameter(tmp_path):
    """The visibility parameter sky_mask_csv is read once by the parameter table (node, run and simulate alike)."""
    from gnss_sim_ros2.parameters import validate_node

    bad = _write(tmp_path / "bad.csv", "azimuth_deg,elevation_deg\n0,20\n90,high\n")
    with pytest.raises(ValueError, match=r"parameter 'sky_mask_csv'.*bad\.csv:3: azimuth_deg '90' and elevation_deg "
                                         r"'high' must be numbers"):
        validate_node("visibility", {"sky_mask_csv": str(bad)}, "node gnss_sim_visibility")
    good = _write(tmp_path / "good.csv", "azimuth_deg,elevation_deg\n0,20\n")
    with pytest.raises(ValueError, match=r"parameter 'sky_mask_csv'.* is the scene, but parameter 'mesh_file'"):
        validate_node("visibility", {"sky_mask_csv": str(good), "mesh_file": "x.ply"}, "node gnss_sim_visibility")
    assert validate_node("visibility", {"sky_mask_csv": str(good)}, "here")["sky_mask_csv"] == str(good.resolve())


def test_sky_mask_scene_needs_one_static_geodetic_or_ecef_antenna():
    from gnss_sim_ros2.core.visibility.sky_mask import static_antenna_ecef

    for pos, kind in (([], "llh"), ([1.0, 2.0, 3.0], "world")):
        with pytest.raises(ValueError, match="parameter 'sky_mask_csv': a sky mask is measured at one point"):
            static_antenna_ecef(pos, kind, None, "parameter 'sky_mask_csv'")
    _, ecef = static_antenna_ecef([22.3, 114.17, 10.0], "llh")
    assert np.linalg.norm(ecef) == pytest.approx(6.375e6, rel=2e-3)


def test_sky_mask_scene_sky_grid_is_the_mask():
    """The visibility node's sky view picture of a mask scene: cells under the mask opaque."""
    m = SkyMask(np.array([0.0, 180.0]), np.array([30.0, 10.0]))
    az_e, el_e, opaque, foliage = SkyMaskScene(m, (22.3, 114.17, 10.0)).sky_grid(np.zeros(3))
    cell = lambda az, el: opaque[np.searchsorted(az_e, az) - 1, np.searchsorted(el_e, el) - 1]  # noqa: E731
    assert cell(1.0, 25.5) and not cell(1.0, 30.5)        # north: the mask at 30 deg
    assert cell(179.0, 5.5) and not cell(179.0, 12.5)     # south: 10 deg
    assert opaque.shape == (180, 90) and not foliage.any()

"""Multipath mode ``auto``: the scene decides where reflections are modelled (issue 27).

Near walls (within multipath_range_m) an antenna is cast as with ``full``; elsewhere nothing beyond the wall
test is computed (core/multipath/wall_proximity.py) and the outputs are those of ``off``."""
from __future__ import annotations

import numpy as np
import pytest
from multipath_scenes import canyon_scene

from gnss_sim_ros2.core.multipath import scene_paths
from gnss_sim_ros2.core.multipath.wall_proximity import antennas_near_walls
from gnss_sim_ros2.core.visibility import VisibilityOptions
from gnss_sim_ros2.core.vocabulary import VisibilityState

LAT = 22.2982
RANGE_M = 100.0


def _satellites(scene, antennas_m):
    """(M, N, 3) ECEF satellites 20,200 km away in a grid of azimuths and elevations seen from each antenna."""
    az, el = np.meshgrid(np.radians(np.arange(5.0, 360.0, 30.0)), np.radians([18.0, 35.0, 55.0, 80.0]))
    d_world = np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1).reshape(-1, 3)
    d_ecef = d_world @ scene.spherical.rotation_world_from_ecef()        # rows: R^T d
    rx = scene.antenna_ecef(np.asarray(antennas_m, float).reshape(-1, 3))
    return rx[:, None, :] + 2.02e7 * d_ecef[None, :, :]


def _cast(mode, scene, antennas_m, sats):
    opt = VisibilityOptions(mask_deg=10.0, multipath=mode, multipath_range_m=RANGE_M)
    state, att, v = opt.cast(scene, antennas_m, sats)
    return state, att, v, getattr(v, "paths", None)


def _forbid_path_search(monkeypatch):
    def boom(*_a, **_k):
        raise AssertionError("the reflection model ran where no wall is in range")
    monkeypatch.setattr(scene_paths, "world_directions", boom)
    monkeypatch.setattr(scene_paths, "find_paths", boom)


@pytest.mark.parametrize("walls, shift_x_m", [(False, 0.0), (True, 400.0)])
def test_open_field_auto_is_off_and_searches_no_path(monkeypatch, walls, shift_x_m):
    """The ground alone, or walls 400 m away with a 100 m range: no direction, no path search, off's outputs."""
    scene = canyon_scene(shift_x_m=shift_x_m, walls=walls, latitude_deg=LAT)
    ant = np.array([[0.0, 0.0, 1.5], [20.0, -50.0, 1.5], [-60.0, 80.0, 1.5]])
    sats = _satellites(scene, ant)
    s_off, a_off, _, p_off = _cast("off", scene, ant, sats)
    _forbid_path_search(monkeypatch)
    s_auto, a_auto, _, p_auto = _cast("auto", scene, ant, sats)
    assert p_off is None and p_auto is None
    assert np.array_equal(s_auto, s_off) and np.array_equal(a_auto, a_off)
    # the ground lies under the antenna: "full" would reflect off it; auto leaves it to the receiver's own
    # statistical code multipath
    monkeypatch.undo()
    _, _, _, p_full = _cast("full", scene, ant, sats)
    assert p_full.valid.any()


def test_auto_equals_full_for_antennas_near_walls():
    scene = canyon_scene(latitude_deg=LAT)
    ant = np.array([[0.0, 0.0, 1.5], [2.0, 30.0, 1.5], [-3.0, -120.0, 1.5], [8.0, 60.0, 4.0]])
    assert antennas_near_walls(scene, ant, RANGE_M).all()
    sats = _satellites(scene, ant)
    s_full, a_full, v_full, p_full = _cast("full", scene, ant, sats)
    s_auto, a_auto, v_auto, p_auto = _cast("auto", scene, ant, sats)
    assert np.array_equal(s_auto, s_full) and np.array_equal(a_auto, a_full)
    assert (s_full == int(VisibilityState.REFLECTED_ONLY)).any()          # the canyon does reflect
    for f in ("excess_m", "gamma_co", "gamma_cross", "arrival_el_deg"):
        assert np.array_equal(getattr(p_auto, f), getattr(p_full, f), equal_nan=True), f
    assert p_auto.rays_cast == p_full.rays_cast > 0
    assert np.array_equal(v_auto.extra_path_m, v_full.extra_path_m)


def test_one_trajectory_switches_per_epoch_from_near_a_wall_to_far():
    """Antennas walking east out of the canyon (walls up to x = 11 m): each epoch is full while a wall is within
    100 m, off beyond, in one cast of the whole block."""
    scene = canyon_scene(latitude_deg=LAT)
    x = np.arange(0.0, 301.0, 25.0)
    ant = np.stack([x, np.zeros_like(x), np.full_like(x, 1.5)], axis=1)
    near = antennas_near_walls(scene, ant, RANGE_M)
    assert near.tolist() == (x - 11.0 <= RANGE_M).tolist()              # the east wall's face at x = 10-11 m
    sats = _satellites(scene, ant)
    s_auto, a_auto, v_auto, p_auto = _cast("auto", scene, ant, sats)
    s_off, a_off, _, _ = _cast("off", scene, ant, sats)
    s_full, a_full, _, p_full = _cast("full", scene, ant, sats)
    assert np.array_equal(s_auto[near], s_full[near]) and np.array_equal(a_auto[near], a_full[near])
    assert np.array_equal(p_auto.excess_m[near], p_full.excess_m[near], equal_nan=True)
    assert np.array_equal(s_auto[~near], s_off[~near]) and np.array_equal(a_auto[~near], a_off[~near])
    assert not p_auto.valid[~near].any() and p_full.valid[~near].any()  # full: the ground bounce out there
    assert np.all(v_auto.extra_path_m[~near] == 0.0)
    assert p_auto.valid[near].any()


def test_open_field_simulation_auto_writes_what_off_writes(tmp_path):
    """The whole offline chain (same seed) in a field whose walls are 400 m away: the same RINEX and fixes."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
    from gnss_sim_ros2.core.trajectory import Trajectory

    scene = canyon_scene(shift_x_m=400.0, latitude_deg=LAT)
    t = np.arange(0.0, 31.0)
    path = Trajectory(t, np.stack([t, 0.5 * t, np.full_like(t, 1.5)], axis=1), "world")
    files = {}
    for mode in ("off", "auto"):
        setup = setup_from_config(load_config(), tmp_path / mode, path, scene=scene, duration_s=30.0,
                                  interval_s=1.0, progress=False).with_params(multipath=mode, seed=7)
        res = run_simulation(setup)
        assert res.epochs == 31 and res.fixes > 25
        files[mode] = [line for line in res.obs_path.read_text().splitlines() if "PGM / RUN BY / DATE" not in line]
        files[mode + "_fix"] = res.fix_path.read_text()
    assert files["auto"] == files["off"] and files["auto_fix"] == files["off_fix"]

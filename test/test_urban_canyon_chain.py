"""The offline chain in a street canyon: multipath off costs nothing, nlos/full produce NLOS tracking."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from multipath_scenes import canyon_scene

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.trajectory import Trajectory
from gnss_sim_ros2.core.vocabulary import VisibilityState

T0 = GnssTime.from_iso("2019-04-28T05:00:00")


@pytest.fixture(scope="module")
def eph(tmp_path_factory):
    return {"synthetic": open_ephemeris("synthetic", T0, 120.0, "GC", workdir=tmp_path_factory.mktemp("eph"))}


def _scene(shift_m=0.0):
    base = canyon_scene()
    w = base.world
    world = dataclasses.replace(w, vertices_m=w.vertices_m + np.array([shift_m, 0.0, 0.0]),
                                spherical_coordinates=SphericalCoordinates(22.2982, 114.1788, 0.0))
    return Scene(world)


def _run(tmp_path, eph, scene, multipath, name):
    seen = []
    setup = setup_from_config(load_config(), tmp_path / name, Trajectory.static(np.array([0.0, 0.0, 2.0]), "world"),
                              start=T0, duration_s=60.0, interval_s=1.0, scene=scene, ephemeris=eph,
                              switches={"ionosphere": "klobuchar"},
                              observer=lambda t, ecef, obs, sol: seen.append((obs, sol))).with_params(
        systems="GC", source="synthetic", multipath=multipath, profile="ublox_m8t")
    return run_simulation(setup), seen


def test_multipath_off_and_nothing_in_range_change_nothing(tmp_path, eph):
    _, off = _run(tmp_path, eph, _scene(), "off", "off")
    # walls moved 5 km east: the canyon's facets are out of range; only the ground remains, which nlos skips
    far = _scene(5000.0)
    _, nlos_far = _run(tmp_path, eph, far, "nlos", "far")
    _, off_far = _run(tmp_path, eph, far, "off", "off_far")
    for (a, _), (b, _) in zip(off_far, nlos_far):
        np.testing.assert_array_equal(a.sv, b.sv)
        np.testing.assert_array_equal(a.pseudorange_m, b.pseudorange_m)
    assert not any(np.any(o.sat_vis_state == VisibilityState.REFLECTED_ONLY) for o, _ in off)


def test_nlos_mode_tracks_reflections_with_positive_delay(tmp_path, eph):
    _, off = _run(tmp_path, eph, _scene(), "off", "off2")
    _, nlos = _run(tmp_path, eph, _scene(), "nlos", "nlos")
    n_refl = sum(int(np.sum(o.sat_vis_state == VisibilityState.REFLECTED_ONLY)) for o, _ in nlos)
    assert n_refl > 0
    more = [len(set(b.sv)) - len(set(a.sv)) for (a, _), (b, _) in zip(off, nlos)]
    assert max(more) > 0 and min(more) >= 0              # the reflected-only satellites come on top
    # their pseudoranges exceed the geometric range by more than the visible ones' (excess > 0)
    obs = nlos[-1][0]
    refl = set(obs.sat_sv[obs.sat_vis_state == VisibilityState.REFLECTED_ONLY])
    resid = obs.pseudorange_m - obs.true_range_m
    tracked_refl = np.isin(obs.sv, list(refl))
    assert tracked_refl.any()
    los = np.median(resid[~tracked_refl])
    assert np.all(resid[tracked_refl] > los)


def test_full_mode_perturbs_line_of_sight_signals(tmp_path, eph):
    _, nlos = _run(tmp_path, eph, _scene(), "nlos", "nlos3")
    _, full = _run(tmp_path, eph, _scene(), "full", "full")
    a, b = nlos[-1][0], full[-1][0]
    common = np.intersect1d(a.sv, b.sv)
    assert len(common) > 3
    da = {s: p for s, p in zip(a.sv, a.pseudorange_m)}
    db = {s: p for s, p in zip(b.sv, b.pseudorange_m)}
    diffs = np.array([db[s] - da[s] for s in common])
    assert np.any(np.abs(diffs) > 0.05)                   # ground and wall bounces on LOS signals
    assert np.all(np.abs(diffs) < 150.0)


def test_off_casts_no_path_and_far_facets_cost_no_ray(eph, monkeypatch):
    from gnss_sim_ros2.core.multipath import reflections
    from gnss_sim_ros2.core.visibility import VisibilityOptions

    prov = eph["synthetic"][0]
    st = prov.states(T0, systems="GC")
    calls = []
    real = reflections.find_paths
    monkeypatch.setattr(reflections, "find_paths", lambda *a, **k: calls.append(1) or real(*a, **k))
    state, att, v = VisibilityOptions(mask_deg=10.0).cast(_scene(), np.array([0.0, 0.0, 2.0]), st.pos_ecef_m)
    assert not hasattr(v, "paths") and not calls
    # the whole scene (walls and ground) 5 km away: no facet in range, no ray for reflections, in either mode
    for mode in ("nlos", "full"):
        opt = VisibilityOptions(mask_deg=10.0, multipath=mode, multipath_range_m=50.0)
        state, att, v = opt.cast(_scene(5000.0), np.array([0.0, 0.0, 2.0]), st.pos_ecef_m)
        assert v.paths.rays_cast == 0 and not v.paths.valid.any()
    # in the canyon "full" casts and finds paths
    state, att, v = opt.cast(_scene(), np.array([0.0, 0.0, 2.0]), st.pos_ecef_m)
    assert v.paths.rays_cast > 0 and v.paths.valid.any()

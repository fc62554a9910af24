"""The planner (core/planning, ``gnss-sim plan``): the same casts as the simulator, DOPs as the solver's,
GeoJSON placed on the Earth within a centimetre, the best-window logic, and clear errors for bad options."""
from __future__ import annotations

import json

import numpy as np
import pytest

from gnss_sim_ros2.core.demo import DEMO_START
from gnss_sim_ros2.core.planning.windows import best_windows
from gnss_sim_ros2.core.scene.demo_world import demo_world_path
from gnss_sim_ros2.core.time import GnssTime

WORLD = demo_world_path()


@pytest.fixture(scope="module")
def courtyard():
    from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene

    return load_scene(str(WORLD), "", "", VisibilityOptions())


@pytest.fixture(scope="module")
def sky():
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.planning.sky import plan_sky, time_steps

    start = GnssTime.from_iso(DEMO_START, scale="GPS")
    times = time_steps(start, 1.0, 20.0)
    provider, _ = open_ephemeris("synthetic", start, 3600.0, "GEC")
    return plan_sky(provider, times, "GEC")


def test_states_are_the_simulators_casts(courtyard, sky):
    """Per satellite and epoch, the planner's state (batched over cells x times in chunks, satellites below the
    mask at the block's centre left out) equals VisibilityOptions.cast of that one antenna and epoch."""
    from gnss_sim_ros2.core.planning.quality import PlanInputs, quality_block
    from gnss_sim_ros2.core.planning.ranging import budget_from_profile
    from gnss_sim_ros2.core.visibility import VisibilityOptions

    # inside the courtyard, in a gap, on a roof and in the open: every state and both sides of walls
    rng = np.random.default_rng(3)
    xy = np.concatenate([rng.uniform(-30, 30, (10, 2)), [[0.0, -22.0], [25.0, 0.0], [80.0, 80.0]]])
    ant = np.c_[xy, np.full(len(xy), 1.5)]
    vis = VisibilityOptions(mask_deg=10.0)
    # a small max_rays: several time chunks, so the chunking and the previous-step carry are exercised
    inp = PlanInputs(sky.pos_ecef_m, sky.system, budget_from_profile("ublox_f9p", "GEC"), max_rays=900)
    n_t, n_s = sky.pos_ecef_m.shape[:2]
    states = np.full((len(ant), n_t, n_s), -2, np.int8)
    fields = quality_block(courtyard, vis, ant, inp, states_out=states)
    seen = set()
    for k in range(n_t):
        here = np.flatnonzero(np.isfinite(sky.pos_ecef_m[k, :, 0]))
        for i in range(len(ant)):
            state, _, v = vis.cast(courtyard, ant[i], sky.pos_ecef_m[k, here])
            want = np.full(n_s, -1, np.int8)
            above = np.asarray(v.el_deg) >= vis.mask_deg
            want[here[above]] = state[above]
            np.testing.assert_array_equal(states[i, k], want, err_msg=f"cell {i} epoch {k}")
            seen.update(want.tolist())
            assert fields["n_los"][i, k] == np.count_nonzero(want == 0)
            assert fields["n_blocked"][i, k] == np.count_nonzero(want == 1)
    assert {0, 1} <= seen, seen            # both visible and blocked satellites were compared



def test_path_quality_equals_the_grid_along_a_standing_path(courtyard, sky):
    """path_quality (one cast of P poses, each with the satellites of its own time; the quality_map node's path
    service) of an antenna standing at a cell through the plan's times equals quality_block's fields of that cell,
    RTK continuity from one pose to the next included."""
    from gnss_sim_ros2.core.planning.quality import FIELDS, PlanInputs, path_quality, quality_block
    from gnss_sim_ros2.core.planning.ranging import budget_from_profile
    from gnss_sim_ros2.core.visibility import VisibilityOptions

    vis = VisibilityOptions(mask_deg=10.0)
    inp = PlanInputs(sky.pos_ecef_m, sky.system, budget_from_profile("ublox_f9p", "GEC"))
    n_t = sky.pos_ecef_m.shape[0]
    for x, y in ((0.0, 0.0), (0.0, -22.0), (80.0, 80.0)):
        grid = quality_block(courtyard, vis, np.array([[x, y, 1.5]]), inp)
        path = path_quality(courtyard, vis, np.tile([x, y, 1.5], (n_t, 1)), sky.pos_ecef_m, sky.system, inp)
        for k in FIELDS:
            np.testing.assert_array_equal(path[k], grid[k][0], err_msg=f"{k} at {x}, {y}")
    # open ground: RTK throughout; beside the west building (3-4 satellites in sight) not throughout
    assert path["rtk"].all() and not quality_block(courtyard, vis, np.array([[-20.0, -8.0, 1.5]]), inp)["rtk"].all()


def test_quality_cost_mapping():
    """costmap.quality_cost follows its documented mapping: RTK 0, no fix 100, else 1 + 98 min(1, h / max)."""
    from gnss_sim_ros2.core.planning.costmap import quality_cost

    fields = {"rtk": np.array([True, False, False, False, False, True]),
              "hdop": np.array([0.8, np.nan, 1.0, 2.0, 1.5, np.nan]),
              "h_acc_m": np.array([2.0, np.nan, 0.0, 40.0, 5.0, np.nan])}
    np.testing.assert_array_equal(quality_cost(fields, 10.0), [0, 100, 1, 99, 50, 0])
    with pytest.raises(ValueError, match="max_accuracy_m"):
        quality_cost(fields, 0.0)

def test_dops_are_the_solvers():
    """dops_from_az_el (no solve) gives the DOPs solve_pvt reports for the same satellites (two systems)."""
    from gnss_sim_ros2.core.frames import az_el_from_ecef, geodetic_to_ecef
    from gnss_sim_ros2.core.solver import SolverConfig, dops_from_az_el, solve_pvt

    start = GnssTime.from_iso(DEMO_START, scale="GPS")
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris

    provider, _ = open_ephemeris("synthetic", start, 60.0, "GE")
    st = provider.states(start, systems="GE")
    rx = np.array(geodetic_to_ecef(47.0, 8.0, 400.0))
    az, el, rng = az_el_from_ecef(rx, st.pos_ecef_m)
    keep = el > 10.0
    sv, sat, rho = np.asarray(st.sv)[keep], st.pos_ecef_m[keep], rng[keep]
    sol = solve_pvt(sv, sat, rho, config=SolverConfig(check_residuals=False))
    assert sol.status == "fix"
    clock = np.array([0 if s[0] == "G" else 1 for s in sv])
    g, p, h, v, t = dops_from_az_el(az[keep][None], el[keep][None], np.ones((1, len(sv)), bool), clock)
    np.testing.assert_allclose([g[0], p[0], h[0], v[0], t[0]], [sol.gdop, sol.pdop, sol.hdop, sol.vdop, sol.tdop],
                               rtol=1e-6)
    # too few satellites for the unknowns: NaN, not a number from a singular matrix
    few = np.zeros((1, len(sv)), bool)
    few[0, :4] = True
    clock4 = clock.copy()
    clock4[1] = 1 - clock4[0]
    assert np.isnan(dops_from_az_el(az[keep][None], el[keep][None], few, clock4)[0][0])


def test_dops_do_not_depend_on_the_satellites_order():
    """The clock groups summed as runs of columns (satellites sorted by system, the planner's order) give the DOPs
    of the same satellites shuffled (groups interleaved: the one-hot product)."""
    from gnss_sim_ros2.core.solver import dops_from_az_el

    rng = np.random.default_rng(1)
    az, el = rng.uniform(0, 360, (200, 20)), rng.uniform(10, 85, (200, 20))
    used = rng.random((200, 20)) < 0.6
    clock = np.sort(rng.integers(0, 3, 20))
    p = rng.permutation(20)
    assert np.any(np.diff(clock[p]) < 0)
    runs = np.array(dops_from_az_el(az, el, used, clock))
    shuffled = np.array(dops_from_az_el(az[:, p], el[:, p], used[:, p], clock[p]))
    assert np.isfinite(runs).sum() > 500
    np.testing.assert_allclose(runs, shuffled, rtol=1e-9)


def test_overlapped_finish_gives_the_same_fields(courtyard, sky, monkeypatch):
    """quality.OVERLAP_FINISH (a window finished on a second thread while the next is cast) gives the fields and
    states of the windows finished one after the other (several windows: the RTK arcs carried across them)."""
    from gnss_sim_ros2.core.planning import quality
    from gnss_sim_ros2.core.planning.predicted_cn0 import predictor_from_profile
    from gnss_sim_ros2.core.planning.ranging import budget_from_profile
    from gnss_sim_ros2.core.visibility import VisibilityOptions

    xy = np.random.default_rng(4).uniform(-40, 40, (30, 2))
    ant = np.c_[xy, np.full(len(xy), 1.5)]
    inp = quality.PlanInputs(sky.pos_ecef_m, sky.system, budget_from_profile("ublox_f9p", "GEC"), max_rays=2000,
                             cn0=predictor_from_profile("ublox_f9p", "GEC"), t_s=sky.t_s)
    runs = []
    for on in (False, True):
        monkeypatch.setattr(quality, "OVERLAP_FINISH", on)
        states = np.full((len(ant),) + sky.pos_ecef_m.shape[:2], -2, np.int8)
        runs.append((quality.quality_block(courtyard, VisibilityOptions(mask_deg=10.0), ant, inp,
                                           states_out=states), states))
    assert len(quality._time_windows(np.ones(sky.pos_ecef_m.shape[:2], bool), len(ant), 2000)) > 2
    for k in quality.FIELDS:
        np.testing.assert_array_equal(runs[1][0][k], runs[0][0][k], err_msg=k)
    np.testing.assert_array_equal(runs[1][1], runs[0][1])


#: the bound test_shared_terms_stay_within_their_bound holds (docs/PLANNING.md): relative difference of a DOP (of the
#: expected accuracy, with its HDOP) <= SHARE_BOUND_FACTOR x (DOP + 1) x tile radius / 19,000 km (the nearest GNSS
#: satellites' range: every line of sight turns by at most radius / range) + SHARE_FLOAT32_REL (a few float32 ulps);
#: measured up to 0.4 (DOPs) and 2.2 / (DOP + 1) (expected accuracy, its UERE at the centre's elevation) of the
#: factor over the courtyard and 1.3 km, up to 3.6 over Hong Kong
SHARE_BOUND_FACTOR = 4.0
SHARE_FLOAT32_REL = 1e-6


@pytest.fixture(scope="module")
def sky6h():
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.planning.sky import plan_sky, time_steps

    start = GnssTime.from_iso(DEMO_START, scale="GPS")
    provider, _ = open_ephemeris("synthetic", start, 6 * 3600.0, "GREC")
    return plan_sky(provider, time_steps(start, 6.0, 20.0), "GREC")


@pytest.mark.parametrize("profile", ["ublox_f9p", "ublox_m8t_hk"])     # link budget; fitted C/N0 tables
@pytest.mark.parametrize("half_m, tile, multipath", [(40.0, "default", "off"), (40.0, 20.0, "off"),
                                                     (1000.0, "max", "off"), (40.0, "default", "nlos")])
def test_shared_terms_stay_within_their_bound(courtyard, sky6h, profile, half_m, tile, multipath):
    """Per-(time, satellite) terms shared by a tile's cells (planning/shared.py) against every cell its own:
    the states, counts, RTK indicator and good-satellite counts equal (the C/N0 per entry near its thresholds),
    NaN / inf where the per-cell fields have them, the DOPs and the expected accuracy within the documented
    bound; in and around the courtyard (the default tile; tiles of 20 m: several) and over 2 km (the largest
    tile); with reflected paths (reflected-only satellites, the C/N0 of the composite signal) too."""
    import dataclasses

    from gnss_sim_ros2.core.planning import quality
    from gnss_sim_ros2.core.planning.predicted_cn0 import predictor_from_profile
    from gnss_sim_ros2.core.planning.ranging import budget_from_profile, tracked_systems
    from gnss_sim_ros2.core.planning.shared import Tiles
    from gnss_sim_ros2.core.planning.sight_lines import AntennaAxes
    from gnss_sim_ros2.core.visibility import VisibilityOptions

    tile_m = {"default": quality.DEFAULT_SHARE_TILE_M, "max": quality.MAX_SHARE_TILE_M}.get(tile, tile)
    xy = np.random.default_rng(7).uniform(-half_m, half_m, (120, 2))
    ant = np.c_[xy, np.full(len(xy), 1.5)]
    keep = np.isin(sky6h.system, list(tracked_systems(profile, "GREC")))
    inp = quality.PlanInputs(sky6h.pos_ecef_m[:, keep], sky6h.system[keep], budget_from_profile(profile, "GREC"),
                             cn0=predictor_from_profile(profile, "GREC"), t_s=sky6h.t_s, max_rays=20000,
                             share_tile_m=0.0)
    vis = VisibilityOptions(mask_deg=10.0, multipath=multipath)
    states = [np.full((len(ant),) + inp.sat_pos_ecef_m.shape[:2], -2, np.int8) for _ in range(2)]
    ref = quality.quality_block(courtyard, vis, ant, inp, states_out=states[0])
    got = quality.quality_block(courtyard, vis, ant, dataclasses.replace(inp, share_tile_m=tile_m),
                                states_out=states[1])
    np.testing.assert_array_equal(states[1], states[0])
    tiles = Tiles.of(courtyard, ant, AntennaAxes.of(courtyard, ant), tile_m)
    radius = tiles.radius_m[tiles.index][:, None]
    assert (len(tiles.cells) > 4) == (tile_m < 40.0)
    for k, dt in quality.FIELDS.items():
        a, b = ref[k].astype(float), got[k].astype(float)
        if np.dtype(dt).kind != "f":
            np.testing.assert_array_equal(b, a, err_msg=k)
            continue
        np.testing.assert_array_equal(np.isfinite(b), np.isfinite(a), err_msg=k)
        ok = np.isfinite(a)
        assert ok.mean() > 0.5, k
        dop = ref["hdop" if k == "h_acc_m" else k].astype(float)
        bound = np.abs(a) * (SHARE_BOUND_FACTOR * (dop + 1.0) * radius / 1.9e7 + SHARE_FLOAT32_REL)
        if k == "nlos_share":
            bound = np.zeros_like(a)
        excess = (np.abs(b - a) - bound)[ok]
        assert excess.max() <= 0.0, f"{k}: {np.abs(b - a)[ok].max()} beyond the bound by {excess.max()}"
    assert got["n_good"].any() and (got["n_attenuated"].any() or half_m > 100.0)   # foliage in the courtyard
    assert got["n_reflected"].any() == (multipath != "off")


@pytest.mark.parametrize("profile", ["ublox_f9p", "ublox_m8t_hk"])
def test_shared_cn0_within_its_margin(courtyard, profile):
    """The open-sky C/N0 at a tile's centre differs from a cell's (its own range and elevation) by less than the
    margin within which the planner computes an entry per entry (Tiles.cn0_margin_db): cells over the largest tile,
    0-50 m up, every satellite above the horizon over a day; the margin stays small (< 0.05 dB)."""
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.planning import quality
    from gnss_sim_ros2.core.planning.predicted_cn0 import predictor_from_profile
    from gnss_sim_ros2.core.planning.shared import Tiles
    from gnss_sim_ros2.core.planning.sight_lines import AntennaAxes
    from gnss_sim_ros2.core.planning.sky import plan_sky, time_steps

    start = GnssTime.from_iso(DEMO_START, scale="GPS")
    provider, _ = open_ephemeris("synthetic", start, 86400.0, "GREC")
    sky = plan_sky(provider, time_steps(start, 24.0, 60.0), "GREC")
    pred = predictor_from_profile(profile, "GREC")
    half = quality.MAX_SHARE_TILE_M / 2
    rng = np.random.default_rng(5)
    ant = np.c_[rng.uniform(-half, half, (200, 2)), rng.uniform(0.0, 50.0, 200)]
    axes = AntennaAxes.of(courtyard, ant)
    tiles = Tiles.of(courtyard, ant, axes, 2 * half + 1.0)
    assert len(tiles.cells) == 1
    here = np.isfinite(sky.pos_ecef_m[..., 0]).all(axis=0)
    sat, sysv = sky.pos_ecef_m[:, here], np.asarray(sky.system)[here]
    _, rng0, sin0 = tiles.sky(sat)
    el0 = np.degrees(np.arcsin(sin0[0]))
    margin = tiles.cn0_margin_db(pred, sysv, float(rng0.min()))[0]
    range_c, enu = axes.to_satellites(sat, per_time=True)
    range_c = range_c.reshape(len(ant), len(sat), len(sysv))
    el_c = np.degrees(np.arcsin(np.clip(enu[2], -1.0, 1.0))).reshape(range_c.shape)
    compared = 0
    for k, s in enumerate(sysv.tolist()):
        up = el0[:, k] > 0.0
        if s not in pred.signal or not up.any():
            continue
        centre = pred.open_sky_dbhz(s, rng0[0, up, k], el0[up, k])
        cells = pred.open_sky_dbhz(s, range_c[:, up, k].ravel(), el_c[:, up, k].ravel()).reshape(len(ant), -1)
        assert np.abs(cells - centre).max() <= margin[k], s
        compared += cells.size
    assert compared > 10000 and margin[np.isfinite(margin)].max() < 0.05


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), 1e6, "250"])
def test_bad_share_tile_is_named(sky, bad):
    from gnss_sim_ros2.core.planning.quality import PlanInputs
    from gnss_sim_ros2.core.planning.ranging import budget_from_profile

    with pytest.raises(ValueError, match="share_tile_m"):
        PlanInputs(sky.pos_ecef_m, sky.system, budget_from_profile("ublox_f9p", "GEC"), share_tile_m=bad)


@pytest.mark.parametrize("profile", ["ublox_f9p", "ublox_m8t_hk"])     # link budget; fitted C/N0 tables
def test_predicted_cn0_is_the_receivers_link_budget(profile):
    """The planner's predicted C/N0 (each system's entries computed in blocks) is receiver/cn0.cn0_dbhz of
    each satellite's system and the profile's first code at its range and elevation, less the attenuation; -inf
    where blocked, NaN off ``where``; systems interleaved (no run of columns) as well as sorted."""
    from types import SimpleNamespace

    from gnss_sim_ros2.core.planning import predicted_cn0
    from gnss_sim_ros2.core.receiver import cn0 as cn0_model
    from gnss_sim_ros2.core.receiver.config import ReceiverConfig
    from gnss_sim_ros2.core.vocabulary import VisibilityState

    pred = predicted_cn0.predictor_from_profile(profile, "GEC")
    cfg = ReceiverConfig(profile=profile)
    rng = np.random.default_rng(5)
    m, sysv = 3 * predicted_cn0.COLUMN_BLOCK_ENTRIES // 7 + 11, np.array(list("GGGEEECC"))   # several row blocks
    for order in (np.arange(len(sysv)), rng.permutation(len(sysv))):
        s = sysv[order]
        el = rng.uniform(-20.0, 90.0, (m, len(s)))
        range_m = rng.uniform(1.9e7, 2.6e7, (m, len(s)))
        att = np.where(rng.random((m, len(s))) < 0.2, rng.uniform(0.0, 15.0, (m, len(s))), 0.0)
        state = rng.choice([int(VisibilityState.VISIBLE), int(VisibilityState.ATTENUATED),
                            int(VisibilityState.BLOCKED)], (m, len(s)))
        where = el >= 10.0
        got = pred.cn0_dbhz(s, state, att, SimpleNamespace(el_deg=el), range_m, where=where)
        blocked = state == int(VisibilityState.BLOCKED)
        assert np.isnan(got[~where]).all() and np.isneginf(got[where & blocked]).all()
        for j, letter in enumerate(s.tolist()):
            codes = cfg.profile.get(letter) or []
            rows = np.flatnonzero(where[:, j] & ~blocked[:, j])
            if not codes:
                assert np.isneginf(got[rows, j]).all()          # a system the profile does not track
                continue
            want = cn0_model.cn0_dbhz(letter, codes[0], range_m[rows, j], el[rows, j], att[rows, j],
                                      budget=cfg.link_budget)
            np.testing.assert_allclose(got[rows, j], want, rtol=0, atol=1e-9, err_msg=f"{profile} {letter}")


@pytest.mark.parametrize("heading_deg", [0.0, 37.0])
def test_geojson_back_to_world_within_a_centimetre(tmp_path, heading_deg):
    """Cell corners written as GeoJSON lon/lat/h (as rounded in the file) come back to world x, y within 1 cm."""
    from gnss_sim_ros2.core.planning.area import grid_area
    from gnss_sim_ros2.core.planning.geojson import cells_feature_collection, lonlath_to_world, write_geojson
    from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates

    sph = SphericalCoordinates(22.298251, 114.178761, 12.0, heading_deg)
    area = grid_area(50.0, (-600.0, -700.0, 600.0, 700.0))
    z = np.linspace(0.0, 30.0, area.n_cells)
    path = tmp_path / "cells.geojson"
    write_geojson(path, cells_feature_collection(sph, area.corners_xy(), z, {"k": np.arange(area.n_cells)}))
    doc = json.loads(path.read_text())
    assert doc["type"] == "FeatureCollection" and len(doc["features"]) == area.n_cells
    ring = np.array([f["geometry"]["coordinates"][0] for f in doc["features"]])          # (C, 5, 3)
    assert np.all(np.abs(ring[..., 0] - 114.178761) < 0.01) and np.all(np.abs(ring[..., 1] - 22.298251) < 0.01)
    back = lonlath_to_world(sph, ring)
    err = np.hypot(back[..., 0] - area.corners_xy()[..., 0], back[..., 1] - area.corners_xy()[..., 1])
    assert err.max() < 0.01, err.max()
    # RFC 7946: outer rings counter-clockwise (lon, lat)
    x, y = ring[0, :, 0], ring[0, :, 1]
    assert np.dot(x[:-1], y[1:]) - np.dot(y[:-1], x[1:]) > 0


def test_best_windows_on_constructed_series():
    step = 600.0
    share = np.array([0.5, 0.96, 0.97, 0.99, 0.2, 0.95, 0.96, np.nan, 1.0, 1.0, 1.0, 1.0])
    w = best_windows(share, step, 0.95)
    assert [(x.start_s, x.end_s) for x in w] == [(8 * step, 11 * step), (1 * step, 4 * step), (5 * step, 7 * step)]
    assert w[1].min_share == pytest.approx(0.96) and w[1].mean_share == pytest.approx((0.96 + 0.97 + 0.99) / 3)
    assert best_windows(share, step, 0.999, limit=1)[0].start_s == 8 * step
    assert best_windows(np.full(5, 0.5), step, 0.9) == []
    # a series ending inside a window: it ends at the last step, not past the plan
    assert best_windows(np.array([0.0, 1.0, 1.0]), step, 0.9)[0].end_s == 2 * step


def _plan(args, capsys):
    from gnss_sim_ros2.cli import main

    rc = main(["plan", *args])
    return rc, capsys.readouterr()


@pytest.mark.parametrize("extra, option", [
    (["--step-m", "0"], "--step-m"), (["--step-m", "-2"], "--step-m"), (["--hours", "0"], "--hours"),
    (["--hours", "-1"], "--hours"), (["--every-min", "0"], "--every-min"),
    (["--polygon", "5000,5000;5100,5000;5100,5100"], "--polygon"), (["--polygon", "1,2;3"], "--polygon")])
def test_bad_options_are_named(tmp_path, capsys, extra, option):
    rc, out = _plan(["--world", str(WORLD), "--out", str(tmp_path / "o"), "--hours", "1", *extra], capsys)
    assert rc == 2
    assert option in out.err and "Traceback" not in out.err, out.err
    assert not (tmp_path / "o").exists()


def test_plan_writes_its_outputs(tmp_path, capsys):
    """A small plan of the courtyard: every output, readable, the GeoJSON at the world's origin, the summary."""
    import pyarrow.parquet as pq
    import xarray as xr

    out = tmp_path / "plan"
    rc, res = _plan(["--world", str(WORLD), "--out", str(out), "--polygon=-30,-30;30,-30;30,30;-30,30",
                     "--step-m", "10", "--hours", "1", "--every-min", "30", "--systems", "GE", "--point", "0,0"],
                    capsys)
    assert rc == 0, res.err
    names = {p.name for p in out.iterdir()}
    assert {"plan.nc", "plan.parquet", "maps.png", "cells.geojson", "summary.md", "timeline_0_0.png",
            "timeline_0_0.csv"} <= names, names
    ds = xr.open_dataset(out / "plan.nc")
    assert ds.sizes["time"] == 3 and ds.sizes["cell"] == 36
    assert int(ds.n_los.max()) > 0
    assert pq.read_table(out / "plan.parquet").num_rows == 36 * 3
    doc = json.loads((out / "cells.geojson").read_text())
    lon, lat = np.array([f["geometry"]["coordinates"][0][0][:2] for f in doc["features"]]).T
    assert np.all(np.abs(lat - ds.attrs["latitude_deg"]) < 1e-3)
    assert np.all(np.abs(lon - ds.attrs["longitude_deg"]) < 1e-3)
    assert "## Best windows" in (out / "summary.md").read_text()
    # a second run into the same folder replaces its own files; a foreign file there is refused
    (out / "mine.txt").write_text("x")
    rc, res = _plan(["--world", str(WORLD), "--out", str(out), "--polygon=-10,-10;10,-10;10,10",
                     "--hours", "1", "--every-min", "30"], capsys)
    assert rc == 2 and "mine.txt" in res.err


def test_plan_option_share_tile_m_default_is_the_planners():
    """`gnss-sim plan --help` states the default tile of the shared terms that PlanInputs uses."""
    import argparse

    from gnss_sim_ros2.commands import plan
    from gnss_sim_ros2.core.planning.quality import DEFAULT_SHARE_TILE_M, PlanInputs

    parser = argparse.ArgumentParser()
    plan.add_arguments(parser)
    (action,) = [a for a in parser._actions if "--share-tile-m" in a.option_strings]
    assert f"default {DEFAULT_SHARE_TILE_M:g}" in action.help
    assert PlanInputs(np.zeros((0, 0, 3)), np.array([]), None).share_tile_m == DEFAULT_SHARE_TILE_M

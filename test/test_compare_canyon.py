"""``gnss-sim compare`` in a canyon (issue 27): core/comparison/canyon.py, canyon_report.py and the honest statistics.

Expectations come from constructed inputs, not from the code's own output:
- the wall scene of multipath_scenes.canyon_scene (west face x = -5 m, 20 m high; east face x = +10 m, 10 m high)
  around a synthetic static antenna: a satellite is blocked exactly when the straight line from the antenna meets a
  wall face below its top (computed here with plane geometry, no ray caster): the NLOS satellite-epochs of the split
  are those;
- the tracked/not agreement on hand-made tracked sets, and on a copy of the file with one satellite removed
  (agreement = 1 - its epochs above the mask / all satellite-epochs above the mask);
- one GPS satellite in the line of sight throughout has its C1C shifted by +40 m in the text (the canyon leaves 3
  GPS satellites in the line of sight at every epoch, so the receiver clock, their median, moves by less than
  their spread): the sim - real differences keep it (tails: share above 30 m = its epochs / all, nothing cut), the
  real file's line-of-sight share above 10 m is its line-of-sight epochs / all line-of-sight ones, the
  Wasserstein-1 distance of the line-of-sight residuals about 40 m x that share;
- a copy where two epochs keep 3 satellites (no single point solution there) and a real truth 100 m north: the
  positions are compared on exactly the other epochs, the real ones against their own truth (mean north -100 m).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from multipath_scenes import write_canyon_mesh
from test_compare import _join, _split, edited_copy, simulate

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.calibration.reading import gnss_times
from gnss_sim_ros2.core.comparison import compare, write_report
from gnss_sim_ros2.core.comparison.canyon import agreement
from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris
from gnss_sim_ros2.core.frames import az_el_from_ecef, ecef_to_enu, geodetic_to_ecef
from gnss_sim_ros2.core.visibility import load_scene

LAT, LON, H = 22.2982, 114.1788, 1.5     # the canyon mesh's origin (multipath_scenes), antenna 1.5 m above it
MASK_DEG = 15.0
#: a line passing within this of a wall's top edge is not asserted either way [m]
EDGE_M = 0.05


@pytest.fixture(scope="module")
def canyon(tmp_path_factory):
    root = tmp_path_factory.mktemp("compare_canyon")
    ply = write_canyon_mesh(root)
    obs, nav = simulate(root / "sim", "--synthetic", "--position", f"{LAT},{LON},{H}", "--duration", "300",
                        "--interval", "10", "--systems", "GE")
    return root, ply, obs, nav


def _geometry(cmp, nav):
    """(blocked, edge, el_deg) on (cmp.time, cmp.canyon.sv) from the wall planes (module docstring)."""
    eph = BroadcastEphemeris.from_files([str(nav)])
    ant = np.array(geodetic_to_ecef(LAT, LON, H), float).ravel()
    svs = cmp.canyon.sv.tolist()
    shape = (len(cmp.time), len(svs))
    blocked, edge, el = np.zeros(shape, bool), np.zeros(shape, bool), np.full(shape, np.nan)
    for e, t in enumerate(gnss_times(cmp.time)):
        st = eph.states(t, systems="GE")
        for s, pos in zip(st.sv, st.pos_ecef_m):
            if s not in svs:
                continue
            j = svs.index(s)
            az, elev, _ = az_el_from_ecef(ant, np.asarray(pos)[None, :])
            el[e, j] = float(np.ravel(elev)[0])
            d = np.asarray(ecef_to_enu(np.asarray(pos), LAT, LON, 0.0)) - np.asarray(ecef_to_enu(ant, LAT, LON, 0.0))
            d = d / np.linalg.norm(d)
            for face, top in ((-5.0, 20.0), (10.0, 10.0)):
                if d[0] * face <= 0:
                    continue
                t_m = face / d[0]
                z = H + d[2] * t_m
                if abs(d[1] * t_m) < 200.0:
                    blocked[e, j] |= z < top
                    edge[e, j] |= abs(z - top) < EDGE_M
    return blocked, edge, el


def test_split_counts_equal_the_wall_geometry(canyon, tmp_path):
    root, ply, obs, nav = canyon
    scene = load_scene("", str(ply))
    cmp = compare(obs, obs, nav_paths=[nav], mask_deg=MASK_DEG, scene=scene, scene_name=f"--mesh {ply}")
    blocked, edge, el = _geometry(cmp, nav)
    c = cmp.canyon
    above = np.nan_to_num(el, nan=-90.0) >= MASK_DEG + 0.1
    ok = above & ~edge
    assert ok.sum() > 200
    # the open-sky simulation tracks every satellite above the mask: tracked = above, NLOS = blocked by the walls
    assert np.array_equal(c.sim.tracked[ok], np.ones(ok.sum(), bool))
    assert np.array_equal(c.sim.blocked[ok], blocked[ok])
    assert 0.2 < blocked[ok].mean() < 0.9          # the scene does split the sky
    m = write_report(cmp, tmp_path) and json.loads((tmp_path / "urban.json").read_text())
    assert m["nlos_sim"] == m["nlos_real"] == int((c.sim.tracked & c.sim.blocked).sum())
    assert abs(m["nlos_sim"] - int(blocked[ok].sum())) <= int((above & edge).sum())
    assert m["agreement"]["agreement"] == 1.0 and m["nlos_share_ratio"] == 1.0
    assert m["residuals"]["los"]["wasserstein_m"] == 0.0 and m["residuals"]["nlos"]["wasserstein_m"] == 0.0
    # the per-signal sim - real split: LOS + NLOS of the reference signal = the satellite-epochs both track
    g = m["code_differences"]["G 1C"]
    sysg = np.array([s[0] == "G" for s in c.sv.tolist()])
    assert g["nlos"]["tails"]["n"] == int((c.sim.tracked & c.sim.blocked)[:, sysg].sum())
    assert g["los"]["tails"]["n"] == int((c.sim.tracked & ~c.sim.blocked)[:, sysg].sum())
    # the per-signal statistics of issue 26, line of sight and NLOS apart (the same file on both sides: equal)
    assert m["signals_split"]["los"]["jaccard_all"] == 1.0 and m["signals_split"]["nlos"]["jaccard_all"] == 1.0
    text = (tmp_path / "report.md").read_text()
    assert "Per-signal statistics, NLOS only" in text
    assert "## Line of sight and NLOS" in text and "87.8 %" in text and "mask given: 15 deg" in text


def test_agreement_on_hand_made_sets():
    above = np.array([[1, 1, 1, 0], [1, 1, 1, 1]], bool)
    sim = np.array([[1, 0, 0, 1], [1, 1, 0, 0]], bool)
    real = np.array([[1, 1, 0, 0], [0, 1, 0, 1]], bool)
    a = agreement(sim, real, above)
    # above: 7; both: (0,0), (1,1) = 2; neither: (0,2), (1,2) = 2; only sim (1,0); only real (0,1), (1,3)
    assert (a["n"], a["both"], a["neither"], a["only_sim"], a["only_real"]) == (7, 2, 2, 1, 2)
    assert a["agreement"] == pytest.approx(4 / 7) and a["anchor"] == 0.878
    assert math.isnan(agreement(sim, real, np.zeros_like(above))["agreement"])


def _pick(cmp, blocked, el, system):
    """A satellite of ``system`` in the line of sight above the mask at every epoch it is above it, the most epochs."""
    best, n = None, 0
    for j, s in enumerate(cmp.canyon.sv.tolist()):
        up = np.nan_to_num(el[:, j], nan=-90.0) >= MASK_DEG + 1.0
        if s[0] == system and up.sum() > n and not (blocked[:, j] & up).any() and up.all():
            best, n = s, int(up.sum())
    assert best is not None
    return best


def test_tails_reported_instead_of_cut_and_agreement_of_a_missing_satellite(canyon, tmp_path):
    root, ply, obs, nav = canyon
    scene = load_scene("", str(ply))
    base = compare(obs, obs, nav_paths=[nav], mask_deg=MASK_DEG, scene=scene, scene_name="--mesh")
    blocked, edge, el = _geometry(base, nav)
    shifted = _pick(base, blocked, el, "G")
    los = base.canyon.sim.tracked & ~base.canyon.sim.blocked
    gps = np.array([s[0] == "G" for s in base.canyon.sv.tolist()])
    assert los[:, gps].sum(axis=1).min() >= 3, "the clock needs 3 line-of-sight GPS satellites at every epoch"
    # the removed satellite: a GPS one above the mask at some epochs, never in the line of sight
    cols = [j for j, s in enumerate(base.canyon.sv.tolist()) if s[0] == "G" and not los[:, j].any()
            and (np.nan_to_num(el[:, j], nan=-90.0) >= MASK_DEG + 1.0).any()]
    dropped = base.canyon.sv[cols[0]]
    real = edited_copy(obs, tmp_path / "real.rnx", shift=(shifted, "C1C", 40.0))
    real = edited_copy(real, tmp_path / "real2.rnx", drop_sv=dropped)
    cmp = compare(obs, real, nav_paths=[nav], mask_deg=MASK_DEG, scene=scene, scene_name="--mesh")
    c = cmp.canyon
    j_d = c.sv.tolist().index(dropped)
    n_above = int(c.above.sum())
    assert cmp.canyon.metrics()["agreement"]["agreement"] == pytest.approx(1.0 - c.above[:, j_d].sum() / n_above)
    assert c.above[:, j_d].sum() >= 1
    # sim - real of GPS C1C: -40 m on the shifted satellite, kept in the tails, left out of the robust RMS
    pair = next(p for p in cmp.pairs if p.system == "G" and p.sim_code == "1C")
    j = cmp.sv.tolist().index(shifted)
    d = cmp.kinds["code"].residuals[pair]
    k = int(np.isfinite(d[:, j]).sum())
    n = int(np.isfinite(d[:, cmp.sys_of_col() == "G"]).sum())
    st = cmp.stats("code", pair)
    assert k > 5 and st["n_gross"] == k
    assert st["tails"]["share_above_30"] == pytest.approx(k / n) and st["tails"]["share_above_100"] == 0.0
    assert st["tails"]["rms"] == pytest.approx(40.0 * math.sqrt(k / n), rel=1e-6)
    assert st["rms"] < 1e-6                         # the robust RMS: what is left without the gross ones
    # each file's own residuals: the shifted satellite's line-of-sight epochs above 10 m in the real file only
    m = cmp.canyon.metrics()
    los_r = c.real.tracked & ~c.real.blocked
    k_los = int(los_r[:, c.sv.tolist().index(shifted)].sum())
    assert m["los_above_10m_sim"] == 0.0
    assert m["los_above_10m_real"] == pytest.approx(k_los / int(los_r.sum()))
    w = m["residuals"]["los"]["wasserstein_m"]
    assert w == pytest.approx(40.0 * k_los / int(los_r.sum()), abs=1.5)
    report = write_report(cmp, tmp_path / "out").read_text()
    assert "Code tails" in report and "Wasserstein" in report


def test_positions_on_common_epochs_each_against_its_truth(canyon, tmp_path):
    root, ply, obs, nav = canyon
    header, epochs = _split(obs)
    thin = (3, 7)
    epochs = [(ep, sats[:3] if i in thin else sats) for i, (ep, sats) in enumerate(epochs)]
    real = tmp_path / "real.rnx"
    real.write_text(_join(header, epochs))
    truth = np.array(geodetic_to_ecef(LAT, LON, H), float).ravel()
    north = truth + 100.0 * np.array([-np.sin(np.radians(LAT)) * np.cos(np.radians(LON)),
                                      -np.sin(np.radians(LAT)) * np.sin(np.radians(LON)), np.cos(np.radians(LAT))])
    base = compare(obs, obs, nav_paths=[nav])
    csv = tmp_path / "real_truth.csv"
    csv.write_text("time,x_m,y_m,z_m\n" + "".join(f"{str(t)[:23]},{north[0]:.4f},{north[1]:.4f},{north[2]:.4f}\n"
                                                for t in base.time))
    cmp = compare(obs, real, nav_paths=[nav], truth_ecef_m=truth, real_truth_csv=csv)
    sol = cmp.solved_epochs()
    e = len(cmp.time)
    assert sol["sim"] == e and sol["real"] == e - len(thin) and sol["both"] == e - len(thin)
    pos = cmp.positions()
    assert pos["sim_vs_truth"]["n"] == pos["real_vs_truth"]["n"] == pos["sim_vs_real"]["n"] == e - len(thin)
    assert abs(pos["real_vs_truth"]["mean_n_m"] + 100.0) < 2.0 and abs(pos["sim_vs_truth"]["mean_n_m"]) < 2.0
    out = tmp_path / "out"
    assert main(["compare", "--sim", str(obs), "--real", str(real), "--nav", str(nav), "--real-truth-csv", str(csv),
                 "--mask-deg", "10", "--out", str(out)]) == 0
    text = (out / "report.md").read_text()
    assert f"{e - len(thin)} epochs both solved" in text and "mask given: 10 deg" in text
    assert "The real file's own truth: CSV" in text


def test_scene_without_nav_is_one_clear_error(canyon, tmp_path, capsys):
    root, ply, obs, nav = canyon
    rc = main(["compare", "--sim", str(obs), "--real", str(obs), "--mesh", str(ply), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "--mesh" in err and "--nav" in err and "Traceback" not in err
    assert not Path(tmp_path / "o" / "report.md").exists()


def test_time_tags_that_wander_by_milliseconds(canyon, tmp_path):
    """A copy whose epoch time tags are 3 ms late (the Hong Kong u-blox's tags wander by +-3 ms): no epoch within
    the default 1 ms, every epoch within --epoch-tol-ms 5 (also in the per-signal statistics), the largest tag
    difference 3 ms reported."""
    root, ply, obs, nav = canyon
    header, epochs = _split(obs)
    late = [(ep[:18] + f"{float(ep[18:29]) + 0.003:11.7f}" + ep[29:], sats) for ep, sats in epochs]
    real = tmp_path / "late.rnx"
    real.write_text(_join(header, late))
    with pytest.raises(ValueError, match="no common epoch"):
        compare(obs, real)
    cmp = compare(obs, real, nav_paths=[nav], epoch_tol_ms=5.0)
    assert len(cmp.time) == len(epochs) and cmp.max_tag_difference_ms == pytest.approx(3.0, abs=1e-6)
    # the per-signal statistics take the matched epochs as one (not only those whose labels agree to 1 ms)
    assert cmp.signals["common_epochs"] == len(epochs) and cmp.signals["jaccard_all"] == 1.0
    with pytest.raises(ValueError, match="epoch tolerance"):
        compare(obs, real, epoch_tol_ms=0.0)

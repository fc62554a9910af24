"""RTK in the graph: ``gnss-sim run --rtk`` runs rover, base station and the rtk node (RTKLIB rtkrcv).

- Issue 17's acceptance run, ``gnss-sim run --rtk --duration 120`` on the demo path (open ground, the
  gate, the courtyard, under tree_1): /gnss/rtk/fix on >= 90 % of the epochs, fixed on >= 80 % of the
  solutions after the first quarter, RTK horizontal error RMS of the fixed solutions <= 0.05 m, the bag
  holds /gnss/rtk/fix.  The gate (8 m between 12 m and 15 m walls) is the hard part: 5-7 satellites, and
  RTKLIB 2.4.3 b34 fixes with two double differences of one system (no minimum number of satellites), the
  other directions from code; its MSM decoder turns the half-cycle indicator (DF420) into a loss of lock
  every epoch (rtcm3.c: LLI = lossoflock + 3), so a re-acquired data signal's phase is unusable until its
  half cycle is resolved (tracking.py: the first frame sync word, not a fixed 6 s): 4.4 cm with the
  default seeds (2.9-6.7 cm over seeds 1, 3, 5, 7: docs/VALIDATION.md "RTK").
- The same graph on open ground (a 120 s drive south of the block): RTK horizontal error RMS of the fixed
  solutions <= 0.05 m, >= 90 % of the epochs with a solution, >= 80 % fixed after the first quarter.
- The base station: same world errors, its own noise (RINEX of its own in output_dir/base).
- Bad base_position: a clear error naming the parameter, nothing started.
- Moving baseline (antenna2_frame): heading from rtkrcv in moving-base mode against the true baseline.
- EpochSync: a rover epoch never reaches rtkrcv before the base epoch of the same time.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

CLI = [sys.executable, "-m", "gnss_sim_ros2.cli"]
#: open ground south of the courtyard block (worlds/README.md): y < -27, buildings 12-15 m high to the north
OPEN_GROUND_WAYPOINTS = [0.0, -40.0, -80.0, 0.0, 120.0, 40.0, -80.0, 0.0]


def _needs_rtkrcv():
    from test_rtk_engine import rtkrcv_and_faketime

    if not rtkrcv_and_faketime():
        pytest.skip("RTKLIB rtkrcv and libfaketime are not installed (apt-get install rtklib faketime)")


def _run(out: Path, *extra, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run(CLI + ["run", "--out", str(out), "--quiet", *extra], capture_output=True, text=True,
                          timeout=timeout)


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def _print(name: str, s: dict) -> None:
    keys = ("epochs", "wall_s", "realtime_factor", "rtk_solution_ratio", "rtk_fixed_ratio", "rtk_float_ratio",
            "rtk_fixed_ratio_after_first_quarter", "rtk_first_fix_s", "rtk_horizontal_error_rms_m",
            "rtk_horizontal_error_p95_m", "rtk_horizontal_error_rms_all_m")
    print(f"\n{name}: " + ", ".join(f"{k} {s.get(k)}" for k in keys))


def test_run_rtk_demo_path_acceptance(tmp_path):
    """Issue 17: ``gnss-sim run --rtk --duration 120`` (the demo path), without the scene's reflections.

    Issue 17's acceptance was set and met with ``multipath: off`` (the default preset's until issue 27). With
    the default ``auto`` the courtyard's reflections reach rover and base (measured once, 2026-12-03: solution
    ratio 1.0, fixed after the first quarter 0.03, fixed solutions' horizontal RMS 2.6 m -- RTKLIB fixes wrong
    ambiguities in the gate and the courtyard, where satellites are tracked on reflections; on open ground the
    same default stays fixed at 0.7 mm, test_run_rtk_open_ground_accuracy).  Whether those wrong fixes are what
    a real receiver pair would do there is open (issue 27); this test keeps the pipeline's acceptance.  The
    land-mobile-satellite layer is at its default (off: docs/VALIDATION.md, issue 27's class rule)."""
    _needs_rtkrcv()
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test)")
    cfg = tmp_path / "no_reflections.yaml"
    cfg.write_text(yaml.safe_dump({"gnss_sim_visibility": {"ros__parameters": {"multipath": "off"}}}))
    out = tmp_path / "demo"
    r = _run(out, "--rtk", "--duration", "120", "--config", str(cfg))
    assert r.returncode == 0, r.stderr[-3000:]
    s = _summary(out)
    _print("demo path", s)
    assert s["epochs"] == 121
    assert s["rtk_solution_ratio"] >= 0.9
    assert s["rtk_fixed_ratio_after_first_quarter"] >= 0.8
    assert s["rtk_horizontal_error_rms_m"] <= 0.05
    assert s["bag_messages"]["/gnss/rtk/fix"] == s["rtk_epochs"] >= 0.9 * s["epochs"]
    timeline = (out / s["rtk_timeline"]).read_text().splitlines()
    assert timeline[0] == "t_s,quality,horizontal_error_m" and len(timeline) == s["rtk_epochs"] + 1
    # the base station: its own RINEX under its marker, its own fix; the rover's SPP is untouched by --rtk
    assert list((out / "base").glob("BASE*_MO.rnx"))
    assert s["bag_messages"]["/gnss/base/rtcm"] == s["bag_messages"]["/gnss/rtcm"] == s["epochs"]
    assert s["fix_availability"] >= 0.9


def test_run_rtk_open_ground_accuracy(tmp_path):
    """The rover drives 120 s on open ground: fixed, centimetre-level against the true path."""
    _needs_rtkrcv()
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test)")
    cfg = tmp_path / "open.yaml"
    cfg.write_text(yaml.safe_dump({"gnss_sim_trajectory_player": {"ros__parameters": {
        "waypoints": OPEN_GROUND_WAYPOINTS}}}))
    out = tmp_path / "open"
    r = _run(out, "--rtk", "--duration", "120", "--config", str(cfg))
    assert r.returncode == 0, r.stderr[-3000:]
    s = _summary(out)
    _print("open ground", s)
    assert s["rtk_solution_ratio"] >= 0.9
    assert s["rtk_fixed_ratio_after_first_quarter"] >= 0.8
    assert s["rtk_horizontal_error_rms_m"] <= 0.05


def test_run_rtk_moving_baseline_heading(tmp_path):
    """antenna2_frame: a second antenna 1 m behind the first (antenna2_offset_m), its receiver and rtkrcv in
    moving-base mode; the heading against the true baseline while the robot drives east, then turns north."""
    _needs_rtkrcv()
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test)")
    cfg = tmp_path / "mb.yaml"
    cfg.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"antenna2_frame": "gnss_antenna2"}},
                                   "gnss_sim_trajectory_player": {"ros__parameters": {"waypoints": [
                                       0.0, -40.0, -80.0, 0.0, 60.0, 0.0, -80.0, 0.0, 120.0, 0.0, -40.0, 0.0]}}}))
    out = tmp_path / "mb"
    r = _run(out, "--rtk", "--duration", "120", "--config", str(cfg))
    assert r.returncode == 0, r.stderr[-3000:]
    s = _summary(out)
    print("\nmoving baseline: " + ", ".join(f"{k} {v}" for k, v in s.items() if k.startswith("heading")))
    assert s["heading_ratio"] >= 0.9 and s["heading_fixed_ratio"] >= 0.8
    assert s["heading_error_rms_deg"] <= 0.5
    assert 0 < s["heading_sd_median_deg"] < 1.0
    assert s["bag_messages"]["/gnss/rtk/heading"] == s["heading_epochs"]
    assert list((out / "antenna2").glob("ANT2*_MO.rnx"))
    assert s["rtk_solution_ratio"] >= 0.9          # the rover's RTK against the base runs beside it


def test_moving_baseline_parameters():
    from gnss_sim_ros2 import graph
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.graph_params import instance_params

    assert [s.name for s in graph.rtk_nodes(load_config())] == ["gnss_sim_base_visibility", "gnss_sim_base_receiver",
                                                                "gnss_sim_rtk"]
    cfg = load_config(None, {"/**": {"antenna2_frame": "gnss_antenna2"}})
    assert [s.name for s in graph.rtk_nodes(cfg)][3:] == ["gnss_sim_antenna2_visibility",
                                                          "gnss_sim_antenna2_receiver", "gnss_sim_heading"]
    rx = instance_params(cfg, "antenna2", "receiver")
    assert rx["antenna_frame"] == "gnss_antenna2" and rx["seed"] not in (1, 2) and rx["marker_name"] == "ANT2"
    assert instance_params(cfg, "heading", "rtk")["rtk_mode"] == "movingbase"
    heading = dict(graph.remappings_of(graph.HEADING_NODES[2]))
    assert heading["base/rtcm"] == "/gnss/rtcm" and heading["rtcm"] == "/gnss/antenna2/rtcm"
    with pytest.raises(ValueError, match="parameter 'antenna2_frame' \\('gnss_antenna'\\) is antenna_frame"):
        load_config(None, {"/**": {"antenna2_frame": "gnss_antenna"}})


@pytest.mark.parametrize("position, kind, words", [
    ([0.0, 21.0], "world", "needs 3 numbers"),
    ([95.0, 14.0, 250.0], "llh", "latitude 95 deg is outside -90..90 deg"),
    ([50.0, 14.4, 250.0], "ecef", "m from the Earth's centre, deep inside the Earth"),
])
def test_bad_base_position_is_a_clear_error(tmp_path, position, kind, words):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump({"gnss_sim_rtk": {"ros__parameters": {
        "base_position": position, "base_position_type": kind}}}))
    out = tmp_path / "out"
    r = _run(out, "--rtk", "--config", str(cfg), timeout=60)
    assert r.returncode == 2, r.stderr
    assert "parameter 'base_position'" in r.stderr and words in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_run_rtk_without_rtkrcv_is_a_clear_error(tmp_path):
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test)")
    cfg = tmp_path / "nortk.yaml"
    cfg.write_text(yaml.safe_dump({"gnss_sim_rtk": {"ros__parameters": {"rtkrcv_path": "/no/such/rtkrcv"}}}))
    r = _run(tmp_path / "out", "--rtk", "--config", str(cfg), "--duration", "3", "--no-record", timeout=120)
    assert r.returncode == 3, r.stderr[-2000:]
    assert "rtkrcv not found '/no/such/rtkrcv' (parameter rtkrcv_path)" in r.stderr
    assert "apt-get install rtklib" in r.stderr and "Traceback" not in r.stderr


def test_base_seed_equal_to_the_rover_seed_is_refused():
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.graph_params import base_station_params

    cfg = load_config(None, {"rtk": {"base_seed": 1}})
    with pytest.raises(ValueError, match="parameter 'base_seed' \\(1\\) equals the receiver's seed"):
        base_station_params(cfg, "receiver")


def test_base_station_shares_the_world_and_has_its_own_noise():
    """The base's receiver: the rover's models and world (world_seed is not a parameter: one world), its own
    seed, marker, folder; its visibility node: the rover's scene with a static antenna."""
    from gnss_sim_ros2 import graph
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.receiver.chain import ChainSettings
    from gnss_sim_ros2.graph_params import base_station_params

    cfg = load_config(None, {"/**": {"output_dir": "/tmp/x"}})
    rx, base = cfg.node("receiver"), base_station_params(cfg, "receiver")
    a, b = ChainSettings.from_params(rx).receiver, ChainSettings.from_params(base).receiver
    assert b.seed == a.seed + 1 and b.world_seed == a.world_seed
    assert (b.ionosphere, b.troposphere, b.sisre_m, b.iono_error_frac) == (a.ionosphere, a.troposphere, a.sisre_m,
                                                                         a.iono_error_frac)
    assert base["rtcm"] and base["marker_name"] == "BASE" and base["output_dir"] == "/tmp/x/base"
    vis = base_station_params(cfg, "visibility")
    assert vis["antenna_position"] == [0.0, 21.0, 25.5] and vis["world_file"] == cfg.node("visibility")["world_file"]
    names = [s.name for s in graph.rtk_nodes()]
    assert names == ["gnss_sim_base_visibility", "gnss_sim_base_receiver", "gnss_sim_rtk"]
    base_spec = graph.rtk_nodes()[1]
    assert dict(graph.remappings_of(base_spec))["rtcm"] == "/gnss/base/rtcm"
    assert dict(graph.remappings_of(base_spec))["satellite_states"] == "/gnss/satellite_states"
    assert graph.node_parameters(cfg, graph.rtk_nodes()[2])["nav_files"] == [str(graph.run_navigation_file(cfg))]


def _epoch(system_msm: int, tow_ms: int) -> bytes:
    """One MSM frame with just the header fields EpochSync reads (DF002, DF003, epoch time, DF393 = 0)."""
    from gnss_sim_ros2.core.rtcm.frame import BitWriter, frame

    w = BitWriter()
    w.u(12, system_msm, "message number")
    w.u(12, 0, "station")
    w.u(30, tow_ms, "epoch time")
    w.u(1, 0, "multiple message")
    w.u(3 + 7 + 2 + 2 + 1 + 3 + 64 + 32 + 1, 0, "rest of the header")
    return frame(w.payload())


def test_epoch_time_read_back_from_our_msm():
    """msm_epoch_gps_ms on the encoder's own MSM (GPS, Galileo, BeiDou = GPS - 14 s)."""
    from gnss_sim_ros2.core.rtcm.frame import frame, message_number, msm_epoch_gps_ms
    from gnss_sim_ros2.core.rtcm.msm import MsmEncoder, SignalObs
    from gnss_sim_ros2.core.time import GnssTime

    t = GnssTime.from_iso("2022-01-01T01:00:07")
    _, tow = t.week_tow("GPS")
    enc = MsmEncoder(7, 0)
    for system, sv, code in (("G", "G05", "1C"), ("E", "E11", "1C"), ("C", "C23", "2I")):
        obs = SignalObs(code=code, pseudorange_m=2.2e7, phase_cyc=1.1e8, doppler_hz=-100.0, cn0_dbhz=45.0, lli=0)
        (payload,) = enc.encode(t, system, {sv: [obs]}, {}, more_follow=False)
        f = frame(payload)
        assert msm_epoch_gps_ms(f) == round(tow * 1000), (system, message_number(f))


def test_epoch_sync_sends_the_base_epoch_first():
    from gnss_sim_ros2.core.rtk.sync import EpochSync

    s = EpochSync(max_wait_epochs=3)
    r1, r2, b1, b2 = _epoch(1077, 1000), _epoch(1077, 2000), _epoch(1077, 1000), _epoch(1077, 2000)
    assert s.push("rover", r1) == [] and s.push("rover", r2) == []       # no base yet: held
    assert s.push("base", b1) == [("base", b1), ("rover", r1)]             # base t=1 -> rover t=1 follows
    assert s.push("base", b2) == [("base", b2), ("rover", r2)]
    r3 = _epoch(1077, 3000)
    assert s.push("rover", r3) == []
    assert s.push("rover", b"\xd3\x00\x00") == [("rover", b"\xd3\x00\x00")]   # no MSM: nothing to pair
    # the base stops: the rover waits for at most max_wait_epochs epochs, then goes alone, oldest first
    held = [_epoch(1077, 4000 + 1000 * i) for i in range(3)]
    assert [s.push("rover", x) for x in held[:2]] == [[], []]
    assert s.push("rover", held[2]) == [("rover", r3)] and s.released_unpaired == 1
    assert s.flush() == [("rover", x) for x in held]

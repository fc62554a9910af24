"""`gnss-sim bench` JSON contract on a tiny scenario (hidden option --epochs) and the batched epoch chain.

Speed figures are not asserted (no timed unit tests); what is checked is the
structure the acceptance checks read and relations that hold whatever the
machine: realtime_factor x seconds_per_epoch = epoch interval, and the
``accurate`` preset compared with itself gives zero pseudorange difference and
identical tracked sets.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from gnss_sim_ros2.cli import main


def test_bench_json_contract(tmp_path):
    out = tmp_path / "bench.json"
    png = tmp_path / "trade.png"
    assert main(["bench", "--epochs", "3", "--no-real", "--json", str(out), "--plot", str(png)]) == 0
    rep = json.loads(out.read_text())
    names = [p["name"] for p in rep["presets"]]
    assert names == ["fast", "balanced", "accurate"]
    for p in rep["presets"]:
        for key in ("realtime_factor", "seconds_per_epoch", "pseudorange_rms_m", "visible_set_jaccard",
                    "fix_horizontal_rms_m", "against"):
            assert key in p, key
        assert p["realtime_factor"] > 0 and p["seconds_per_epoch"] > 0
        # simulated s per wall s times wall s per epoch = simulated s per epoch (1e-9 relative)
        assert p["realtime_factor"] * p["seconds_per_epoch"] == pytest.approx(p["epoch_interval_s"], rel=1e-9)
        assert 0.0 <= p["visible_set_jaccard"] <= 1.0
        assert p["pseudorange_rms_m"] >= 0.0
    acc = rep["presets"][2]
    assert acc["pseudorange_rms_m"] == 0.0 and acc["visible_set_jaccard"] == 1.0
    assert rep["presets"][0]["epoch_interval_s"] == 10.0 and rep["presets"][1]["epoch_interval_s"] == 1.0
    assert rep["scenarios"]["opec"]["skipped"] == "--no-real"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_bench_rejects_unknown_preset(capsys):
    assert main(["bench", "--epochs", "3", "--presets", "fastest", "--no-real"]) == 2
    assert "fastest" in capsys.readouterr().err


def test_batched_chain_equals_epoch_by_epoch(tmp_path):
    """Blocks of 50 epochs (one ephemeris call, one raycast) give the observations of block size 1, noise on."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path
    from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
    from gnss_sim_ros2.core.time import GnssTime
    from gnss_sim_ros2.core.trajectory import demo_trajectory

    got = {}

    def observer_for(tag):
        got[tag] = []
        return lambda t, ecef, obs, sol: got[tag].append((obs.sv.copy(), obs.code.copy(), obs.pseudorange_m.copy(),
                                                           obs.cn0_dbhz.copy(), obs.sat_vis_state.copy()))

    base = setup_from_config(load_config(), tmp_path / "a", demo_trajectory(),
                             start=GnssTime.from_iso("2025-06-01T10:00:00"), duration_s=40.0, interval_s=1.0
                             ).with_params(world_file=str(demo_world_path()), systems="GE", preset="accurate")
    run_simulation(dataclasses.replace(base, batch_epochs=1, observer=observer_for("one")))
    run_simulation(dataclasses.replace(base, batch_epochs=50, out_dir=tmp_path / "b", observer=observer_for("blk")))
    assert len(got["one"]) == len(got["blk"]) == 41
    for a, b in zip(got["one"], got["blk"]):
        assert a[0].tolist() == b[0].tolist() and a[1].tolist() == b[1].tolist()
        np.testing.assert_array_equal(a[2], b[2])
        np.testing.assert_array_equal(a[3], b[3])
        np.testing.assert_array_equal(a[4], b[4])
    assert sum(len(a[0]) for a in got["one"]) > 0
    def body(d):   # the header holds the file's creation time
        return Path(next(d.glob("*_MO.rnx"))).read_bytes().split(b"END OF HEADER", 1)[1]

    assert body(tmp_path / "a") == body(tmp_path / "b")


def test_bench_speed_json_contract(tmp_path, capsys, monkeypatch):
    """`bench --speed` on a 20 s span: the demo and GPS-static runs are timed (child processes, start-up
    included) and the real-time factor follows from the wall time; with no interpreter that imports gnss_lib_py
    (no --peer-python: a given one that cannot is refused, test_bad_inputs_sweep3) the ratio is reported as
    skipped with the reason, never as a number."""
    if importlib.util.find_spec("gnss_lib_py") is not None:
        pytest.skip("gnss_lib_py is importable here: the peer would run (this test is about its absence)")
    monkeypatch.delenv("GNSS_SIM_PEER_PYTHON", raising=False)
    out = tmp_path / "speed.json"
    assert main(["bench", "--speed", "--speed-duration", "20", "--repeats", "1", "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    d, g = rep["demo"], rep["gps_static"]
    assert d["wall_s"] > 0 and d["cpu_s"] > 0
    assert d["realtime_factor"] == pytest.approx(20.0 / d["wall_s"], rel=1e-12)
    assert g["gnss_sim_epochs_per_s"] == pytest.approx(21 / g["gnss_sim_wall_s"], rel=1e-12)
    assert "ratio" not in g and "gnss_lib_py not importable" in g["skipped"]
    text = capsys.readouterr().out
    assert "x real time" in text and "gnss_lib_py: skipped" in text


def test_bench_speed_rejects_bad_duration(capsys):
    assert main(["bench", "--speed", "--speed-duration", "0", "--peer-python", "none"]) == 2
    assert "duration" in capsys.readouterr().err

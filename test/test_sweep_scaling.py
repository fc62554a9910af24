"""`gnss-sim bench --scaling` on tiny points (hidden --epochs): the report's structure, the generated box
city, the straight-line extrapolation of the long spans.  No speed is asserted (bench scripts print it)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from gnss_sim_ros2.benchmarks.scaling import EPOCH_SPANS_S, box_city, extrapolate_epochs
from gnss_sim_ros2.cli import main


def test_box_city_has_the_triangles_asked_closed_boxes_and_an_open_square():
    import trimesh

    for n in (1_000, 25_000):
        w = box_city(n, None)
        assert n <= len(w.triangles) < n + 12
        assert len(w.vertices_m) == 8 * len(w.triangles) // 12
        horizontal = np.max(np.abs(w.vertices_m[:, :2]), axis=1)
        assert horizontal.min() > 30.0                         # the square around the antenna is open
    box = trimesh.Trimesh(w.vertices_m[:8], w.triangles[:12], process=False)
    assert box.is_watertight and box.volume > 0                # outward faces
    assert box.volume == pytest.approx(14.0 * 14.0 * (w.vertices_m[:8, 2].max()), rel=1e-9)


def test_long_spans_are_extrapolated_from_the_longest_measured_one_and_marked():
    measured = [{"axis": "epochs", "duration_s": d, "epochs": int(d) + 1, "loop_s": 0.5 + 0.003 * (d + 1),
                 "cpu_s": 0.4 + 0.002 * (d + 1), "peak_rss_mb": 400 + 0.01 * d, "setup_s": 1.0 + 1e-4 * d,
                 "base_rss_mb": 380.0} for d in (60.0, 600.0, 3600.0)]
    ext = extrapolate_epochs(measured)
    assert [e["duration_s"] for e in ext] == [d for d in EPOCH_SPANS_S if d > 3600.0]
    day = ext[-1]
    assert day["extrapolated"] and day["epochs"] == 86401 and day["setup_s"] is None   # set-up not fitted
    assert day["ms_per_epoch"] == pytest.approx(1e3 * (0.5 + 0.003 * 3601) / 3601, rel=1e-12)
    assert day["cpu_ms_per_epoch"] == pytest.approx(1e3 * (0.4 + 0.002 * 3601) / 3601, rel=1e-12)
    assert day["peak_rss_mb"] == pytest.approx(400 + 0.01 * 86400, rel=1e-9)
    assert day["ms_per_epoch"] * day["epochs"] == pytest.approx(1e3 * day["loop_s"], rel=1e-12)
    # memory that fell between the measured spans (noise) is not extrapolated downwards
    noisy = [dict(m, peak_rss_mb=450 - 0.01 * m["duration_s"]) for m in measured]
    assert extrapolate_epochs(noisy)[-1]["peak_rss_mb"] == pytest.approx(noisy[-1]["peak_rss_mb"])
    assert extrapolate_epochs(measured[:1]) == []


def test_bench_scaling_report_and_plot(tmp_path, capsys):
    out, png = tmp_path / "scaling.json", tmp_path / "scaling.png"
    assert main(["bench", "--scaling", "--epochs", "4", "--json", str(out), "--plot", str(png)]) == 0
    rep = json.loads(out.read_text())
    pts = rep["points"]
    assert {p["axis"] for p in pts} == {"triangles", "satellites", "epochs", "rate"}
    for p in pts:
        assert p["ms_per_epoch"] > 0 and p["peak_rss_mb"] > 0
        if not p["extrapolated"]:
            assert p["epochs"] == int(round(p["duration_s"] * p["rate_hz"])) + 1
            assert p["ms_per_epoch"] * p["epochs"] == pytest.approx(1e3 * p["loop_s"], rel=1e-9)
            assert p["peak_rss_mb"] >= p["base_rss_mb"]
    tri = [p for p in pts if p["axis"] == "triangles"]
    assert [p["triangles"] >= p["value"] for p in tri] == [True, True] and all("build_s" in p for p in tri)
    sats = {p["value"]: p["satellites_tracked_mean"] for p in pts if p["axis"] == "satellites"}
    assert sats["G"] < sats["GECRJI"]                          # more systems, more satellites
    ext = [p for p in pts if p["extrapolated"]]
    assert ext and ext[-1]["duration_s"] == 86400.0            # 24 h always reported, marked
    text = capsys.readouterr().out
    assert "extrapolated (linear fit)" in text and "| triangles |" in text
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 20_000


def test_bench_scaling_rejects_a_bad_span(capsys):
    assert main(["bench", "--scaling", "--scaling-max-hours", "30"]) == 2
    assert "--scaling-max-hours" in capsys.readouterr().err

"""The scaling figure's robots axis (benchmarks/fleet_plot.py): one point per robot count of a bench --fleet
report, drawn to a PNG that opens, whatever order the runs came in."""
import matplotlib.image as mpimg
import pytest

from gnss_sim_ros2.benchmarks.fleet_plot import fleet_plot


def _run(n, cpu_ms):
    return {"robots": n, "cpu_ms_per_epoch": cpu_ms, "p50_ms_worst": 2.0 * n, "p99_ms_worst": 3.0 * n,
            "peak_rss_mb": 300.0 + 4.0 * n}


def test_fleet_plot_writes_a_png(tmp_path):
    report = {"rate_hz": 10.0, "duration_s": 20.0, "cores": 2, "config": "/tmp/x/fleet_fast.yaml",
              "runs": [_run(32, 380.0), _run(1, 30.0), _run(4, 53.0)]}
    out = fleet_plot(report, tmp_path / "robots.png")
    img = mpimg.imread(out)
    assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 800
    assert not list(tmp_path.glob("*.tmp*"))     # written whole (core/figures.save_figure)


def test_fleet_plot_needs_the_runs_figures(tmp_path):
    report = {"rate_hz": 10.0, "duration_s": 20.0, "cores": 2, "config": "defaults",
              "runs": [{"robots": 1}]}
    with pytest.raises(KeyError):
        fleet_plot(report, tmp_path / "robots.png")
    assert not (tmp_path / "robots.png").exists()

"""``gnss-sim bench --fleet``'s arithmetic (benchmarks/fleet.py): the counts run in rounds, each count's figures
from its repeated runs (medians of CPU and memory, the worst run's latency), the added robot from the medians,
and its options refused when impossible.  The runs themselves (real-time graphs, minutes) are the benchmark's."""
from __future__ import annotations

import pytest
from cli_helpers import assert_refused, run_cli

from gnss_sim_ros2.benchmarks import fleet


def _run(n, cpu, p99, rss=300.0, dropped=0):
    return {"robots": n, "epochs": 201, "epochs_without_output": dropped, "p99_ms_worst": p99, "worst_robot": "robot0",
            "p50_ms_worst": p99 / 2, "fix_p99_ms_worst": 2 * p99, "cpu_ms_per_epoch": cpu, "peak_rss_mb": rss,
            "configure_wall_s": 1.0, "realtime_factor": 1.0, "load_before": [0.5, 0.5, 0.5],
            "load_after": [0.6, 0.5, 0.5]}


def test_runs_in_rounds_and_medians(monkeypatch):
    # each count's three runs: CPU 10/12/30 (one busy spell) for one robot, 15/13/14 for four
    figures = {1: iter([(10.0, 3.0), (12.0, 3.5), (30.0, 9.0)]), 4: iter([(15.0, 6.0), (13.0, 8.0), (14.0, 7.0)])}
    order = []

    def run_one(n, rate_hz, duration_s, config):
        order.append(n)
        cpu, p99 = next(figures[n])
        return _run(n, cpu, p99, rss=300.0 + 3.0 * n, dropped=1 if (n, cpu) == (4, 13.0) else 0)

    monkeypatch.setattr(fleet, "run_one", run_one)
    rep = fleet.run_fleet([1, 4], duration_s=5.0, log=lambda m: None, repeats=3)
    assert order == [1, 4, 1, 4, 1, 4]                     # rounds: a busy spell falls on every count alike
    one, four = rep["runs"]
    assert one["cpu_ms_per_epoch"] == 12.0 and four["cpu_ms_per_epoch"] == 14.0         # medians
    assert one["p99_ms_worst"] == 9.0 and four["p99_ms_worst"] == 8.0                   # the worst run's
    assert four["p99_ms_runs"] == [6.0, 8.0, 7.0] and four["cpu_ms_per_epoch_runs"] == [15.0, 13.0, 14.0]
    assert four["epochs"] == 3 * 201 and four["epochs_without_output"] == 1
    assert four["added_robot_cpu_ms"] == pytest.approx(2.0 / 3, abs=0.01)
    assert four["added_robot_pct"] == pytest.approx(100 * (2.0 / 3) / 12.0, abs=0.1)
    assert four["added_robot_mb"] == pytest.approx(3.0)
    table = fleet.fleet_table(rep)
    assert "3 run(s) of 5 s" in table and "(15.0, 13.0, 14.0)" in table and "added robot <= 15 %: met" in table


@pytest.mark.parametrize("argv, words", [
    (["--fleet-repeats", "0"], ["--fleet-repeats", "0"]),
    (["--fleet-repeats", "11"], ["--fleet-repeats", "11"]),
    (["--fleet-robots", "1,x"], ["--fleet-robots"]),
    (["--fleet-duration", "0.5"], ["--fleet-duration"]),
])
def test_impossible_options_refused(argv, words, capsys):
    rc, text = run_cli(["bench", "--fleet"] + argv, capsys)
    assert_refused(rc, text, words)

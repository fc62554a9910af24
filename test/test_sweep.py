"""gnss-sim sweep: axes, one run -> one row (deterministic from its seed), Parquet, failed runs kept."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import pytest

from gnss_sim_ros2 import cli
from gnss_sim_ros2.commands import sweep as sweep_cmd
from gnss_sim_ros2.core.sweep.axes import RunPoint, parse_dates, parse_seeds, run_points
from gnss_sim_ros2.core.sweep.row import run_row
from gnss_sim_ros2.core.sweep.table import COLUMNS, TIMING_COLUMNS, read_rows, to_table, write_rows


def sweep_args(*argv):
    p = argparse.ArgumentParser()
    sweep_cmd.add_arguments(p)
    return p.parse_args(list(argv))


# ----------------------------------------------------------------------------- axes
def test_seeds_ranges_lists_and_errors():
    assert parse_seeds("1-5") == [1, 2, 3, 4, 5]
    assert parse_seeds("3, 9,1-2") == [3, 9, 1, 2]
    assert len(parse_seeds("1-100")) == 100
    for bad, word in (("5-1", "goes down"), ("a", "not a seed"), ("1,1", "twice"), ("-3", "not a seed"),
                      ("", "not a seed")):
        with pytest.raises(ValueError, match=word) as e:
            parse_seeds(bad)
        assert "--seeds" in str(e.value)


def test_dates_keep_the_time_of_day_and_expand_day_ranges():
    assert parse_dates("2025-06-01", "10:00:00") == ["2025-06-01T10:00:00"]
    assert parse_dates("2025-06-30..2025-07-02,2024-01-01T00:00:30", "08:30:00") == [
        "2025-06-30T08:30:00", "2025-07-01T08:30:00", "2025-07-02T08:30:00", "2024-01-01T00:00:30"]
    with pytest.raises(ValueError, match="--dates.*back in time"):
        parse_dates("2025-06-02..2025-06-01", "10:00:00")
    with pytest.raises(ValueError, match="--dates.*FIRST..LAST"):
        parse_dates("2025-06-02..tomorrow", "10:00:00")


def test_run_points_are_the_product_seed_innermost():
    pts = run_points(seeds=[1, 2, 3], presets=["fast", "balanced"])
    assert [(p.index, p.preset, p.seed) for p in pts] == [
        (1, "fast", 1), (2, "fast", 2), (3, "fast", 3), (4, "balanced", 1), (5, "balanced", 2), (6, "balanced", 3)]
    assert [p.name for p in pts][:2] == ["run00001", "run00002"]
    assert run_points() == [RunPoint(1)]       # nothing swept: the scenario once


def test_relative_paths_reach_the_workers_absolute(tmp_path, monkeypatch):
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    monkeypatch.chdir(demo_world_path().parent)
    args = sweep_args("--worlds", demo_world_path().name, "--out", "sweep_out", "--duration", "5")
    [(_, setup)] = sweep_cmd.build_tasks(args, Path("sweep_out"))
    assert setup.visibility_params["world_file"] == str(demo_world_path())
    assert setup.out_dir == demo_world_path().parent / "sweep_out" / "runs" / "run00001"


def test_axis_options_map_onto_simulate_and_bad_values_name_the_option(tmp_path):
    args = sweep_args("--seeds", "4-5", "--presets", "fast,accurate", "--dates", "2025-06-03", "--duration", "20",
                      "--out", str(tmp_path))
    tasks = sweep_cmd.build_tasks(args, tmp_path)
    assert [(s.receiver_params["seed"], s.preset, s.start.isoformat("GPS")) for _, s in tasks] == [
        (4, "fast", "2025-06-03T10:00:00"), (5, "fast", "2025-06-03T10:00:00"),
        (4, "accurate", "2025-06-03T10:00:00"), (5, "accurate", "2025-06-03T10:00:00")]
    assert [s.out_dir for _, s in tasks] == [tmp_path / "runs" / f"run0000{i}" for i in range(1, 5)]
    assert all(s.duration_s == 20.0 and not s.progress for _, s in tasks)
    cases = [(("--seeds", "1-3", "--seed", "2"), "--seeds and --seed exclude"),
             (("--presets", "fast,turbo"), "option --presets: parameter 'preset' is 'turbo'"),
             (("--dates", "2025-13-01"), "--dates: 2025-13-01T10:00:00: .*month"),
             (("--trajectories", str(tmp_path / "none.csv")), "--trajectories: .*none.csv"),
             (("--trajectories", str(tmp_path / "a.csv"), "--position", "50,8,100"), "--trajectories excludes")]
    for extra, msg in cases:
        with pytest.raises(ValueError, match=msg):
            sweep_cmd.build_tasks(sweep_args(*extra, "--out", str(tmp_path)), tmp_path)


# ----------------------------------------------------------------------------- one run -> one row
def _rows_equal_but_timing(a: dict, b: dict) -> list[str]:
    """The non-timing columns where two rows differ."""
    def same(x, y):
        return x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))
    return [c for c in COLUMNS if c not in TIMING_COLUMNS and not same(a.get(c), b.get(c))]


def test_one_run_is_determined_by_its_seed_cached_or_not(tmp_path):
    args = sweep_args("--seeds", "7,8", "--duration", "40", "--out", str(tmp_path))
    (p7, s7), (p8, s8) = sweep_cmd.build_tasks(args, tmp_path)
    cache = str(tmp_path / ".cache")
    first = run_row(p7, s7, cache)          # fills this process's cache
    again = run_row(p7, s7, cache)          # scene and ephemeris from the cache
    fresh = run_row(p7, s7, None)           # loads everything itself
    other = run_row(p8, s8, cache)
    assert first["status"] == "ok", first["error"]
    assert first["epochs"] == 41 and first["fixes"] > 30
    assert set(first) == set(COLUMNS)
    assert _rows_equal_but_timing(first, again) == []
    assert _rows_equal_but_timing(first, fresh) == []
    # another seed draws other noise: the errors differ, the geometry does not
    assert "h_err_p50_m" in _rows_equal_but_timing(first, other)
    assert first["sats_blocked_mean"] == other["sats_blocked_mean"]
    assert (tmp_path / "runs" / "run00001" / "fix.csv").is_file()
    assert (tmp_path / "runs" / "run00002" / "fix.csv").is_file()


def test_a_failing_run_is_a_row_with_its_error(tmp_path):
    bad = tmp_path / "broken.sdf"
    bad.write_text("<sdf version='1.9'><world name='x'><model name='m'>")   # truncated XML
    args = sweep_args("--worlds", str(bad), "--duration", "5", "--out", str(tmp_path))
    [(point, setup)] = sweep_cmd.build_tasks(args, tmp_path)
    row = run_row(point, setup, None)
    assert row["status"] == "failed"
    assert "broken.sdf" in row["error"]
    assert row["epochs"] is None and row["runtime_s"] >= 0
    assert "Traceback" in (tmp_path / "runs" / "run00001" / "error.txt").read_text()


def test_rows_round_trip_through_parquet(tmp_path):
    rows = [{"index": 2, "run": "run00002", "status": "failed", "error": "ValueError: x"},
            {"index": 1, "run": "run00001", "status": "ok", "epochs": 3, "h_err_p95_m": 1.5}]
    back = read_rows(write_rows(rows, tmp_path / "r.parquet"))
    assert [r["index"] for r in back] == [1, 2]
    assert back[0]["h_err_p95_m"] == 1.5 and back[1]["epochs"] is None and back[1]["error"] == "ValueError: x"
    assert list(back[0]) == list(COLUMNS)
    with pytest.raises(ValueError, match="unknown column.*bogus"):
        to_table([{"index": 1, "bogus": 2}])


# ----------------------------------------------------------------------------- the command on a local cluster
def test_sweep_on_a_local_cluster_keeps_going_after_a_failed_run(tmp_path, capsys):
    from gnss_sim_ros2.core.scene.demo_world import demo_world_path

    bad = tmp_path / "broken.sdf"
    bad.write_text("not xml at all")
    out = tmp_path / "sweep"
    rc = cli.main(["sweep", "--worlds", str(demo_world_path()), str(bad), "--seeds", "1-2", "--duration", "20",
                   "--workers", "2", "--quiet", "--out", str(out)])
    cap = capsys.readouterr()
    assert rc == 1, cap.err            # one world failed: reported, the others ran
    rows = read_rows(out / "results.parquet")
    assert [(r["index"], r["world"].endswith("broken.sdf"), r["status"]) for r in rows] == [
        (1, False, "ok"), (2, False, "ok"), (3, True, "failed"), (4, True, "failed")]
    assert all("broken.sdf" in r["error"] for r in rows[2:])
    assert rows[0]["epochs"] == 21 and rows[0]["fix_availability"] > 0.5
    assert len({r["worker"] for r in rows}) >= 1
    assert (out / "summary.png").stat().st_size > 10_000
    assert "4 runs on 2 worker(s)" in cap.out and "2 ok, 2 failed" in cap.out
    assert not (out / ".cache").exists()


def test_unreachable_scheduler_is_a_clear_error(tmp_path, capsys, monkeypatch):
    import socket

    from gnss_sim_ros2.core.sweep import driver

    monkeypatch.setattr(driver, "CONNECT_TIMEOUT_S", 2.0)
    with socket.socket() as s:            # a free port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    rc = cli.main(["sweep", "--seeds", "1-2", "--duration", "5", "--scheduler", f"tcp://127.0.0.1:{port}",
                   "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 2
    assert f"--scheduler tcp://127.0.0.1:{port}: cannot reach the scheduler" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("orbits", ["broadcast", "sp3"])
def test_cached_real_ephemeris_gives_the_fresh_row(opec_dir, tmp_path, orbits):
    """OPEC navigation files (and the CODE SP3 with their group delays): a worker's cached provider and a
    fresh one give the same row."""
    nav = [str(opec_dir / f"OPEC00NOR_S_20220010000_01D_{s}N.rnx") for s in "GE"]
    from gnss_sim_ros2.core.simulation import orbit_source

    extra = (["--sp3", str(opec_dir / "COD0MGXFIN_20220010000_01D_05M_ORB.SP3"), "--preset", "accurate"]
             if orbits == "sp3" else [])
    args = sweep_args("--nav", *nav, *extra, "--position-ecef", "3149785.9652,598260.8822,5495348.4927",
                      "--start", "2022-01-01T00:00:00", "--duration", "300", "--interval", "30", "--systems", "GE",
                      "--seeds", "3", "--out", str(tmp_path))
    [(point, setup)] = sweep_cmd.build_tasks(args, tmp_path)
    assert orbit_source(setup) == orbits
    cache = str(tmp_path / ".cache")
    first, cached, fresh = run_row(point, setup, cache), run_row(point, setup, cache), run_row(point, setup, None)
    assert first["status"] == "ok", first["error"]
    assert first["epochs"] == 11 and first["fixes"] == 11
    assert _rows_equal_but_timing(first, cached) == [] and _rows_equal_but_timing(first, fresh) == []


def _run_files(run_dir: Path) -> dict:
    """A run's RINEX and fix.csv bytes (the RINEX line with the wall-clock date aside)."""
    out = {}
    for f in sorted(run_dir.iterdir()):
        if f.suffix in (".rnx", ".csv"):
            out[f.name] = b"".join(ln for ln in f.read_bytes().splitlines(keepends=True)
                                   if b"PGM / RUN BY / DATE" not in ln)
    return out


def test_one_or_two_workers_give_the_same_rows_and_files(tmp_path, capsys):
    rows = {}
    for w in (1, 2):
        rc = cli.main(["sweep", "--seeds", "1-4", "--duration", "20", "--workers", str(w), "--quiet",
                       "--out", str(tmp_path / f"w{w}")])
        cap = capsys.readouterr()
        assert rc == 0, cap.err
        # the time that divides among the workers and the fixed start-up, reported apart
        assert f"s of runs on {w} worker(s) (" in cap.out and "s before the first run" in cap.out
        rows[w] = read_rows(tmp_path / f"w{w}" / "results.parquet")
    assert [r["run"] for r in rows[1]] == [r["run"] for r in rows[2]] == [f"run0000{k}" for k in range(1, 5)]
    assert [_rows_equal_but_timing(a, b) for a, b in zip(rows[1], rows[2])] == [[]] * 4
    assert all(r["status"] == "ok" and r["load_s"] is not None for r in rows[1] + rows[2])
    for r in rows[1]:
        one, two = (_run_files(tmp_path / f"w{w}" / "runs" / r["run"]) for w in (1, 2))
        assert len(one) >= 3 and one == two


def test_sweep_time_splits_the_work_from_the_fixed_start_up():
    from gnss_sim_ros2.core.sweep.timing import sweep_time

    rows = [{"runtime_s": 2.0, "load_s": 1.5}, {"runtime_s": 1.0, "load_s": 0.0}, {"runtime_s": 0.5, "load_s": None},
            {"runtime_s": None, "load_s": None}]
    t = sweep_time(rows, 2, before_s=3.0, runs_wall_s=2.0, after_s=0.5)
    assert (t.work_s, t.load_s, t.total_s) == (3.5, 1.5, 5.5)
    assert t.line().startswith("time 5.5 s: 3.0 s before the first run") and "3.5 s of work" in t.line()

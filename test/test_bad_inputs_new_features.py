"""Bad input to the features of the last sessions (planner, scenarios, moving obstacles, registration options,
threats-plot) is refused up front, naming the option, file or parameter; never a traceback, never a silent default.

Each case runs the real command line (``gnss_sim_ros2.cli.main``) in this process, as test_bad_inputs.py does.
Before these checks: ``plan --step-m 0.001`` ended in a 298 GiB MemoryError traceback, ``--hours 1e7`` and
``--every-min 1e-6`` in a MemoryError after 70-100 s, ``--height-m 1e9`` in "cannot reshape array of size 0";
``plan --workers 0``, ``--polygon=`` (the world's bounds instead), a --path or --point far outside the world,
``--good-cn0-dbhz -400``, ``--start 3025-01-01``, a sky mask's ``--origin 95,11,500`` and its --path / --polygon
(misreported or ignored) ran with rc 0; so did calibrate / compare ``--world-offset``
without a scene (ignored), ``--strong-cn0-dbhz nan`` and ``simulate --obstacle-path`` without a scene (ignored);
a scenario event starting after the run's end was never active without a word (now a warning);
``compare --antenna-height-m -5`` said "antenna_world_m: non-finite position" and ``threats-plot --png x.txt``
matplotlib's "Format 'txt' is not supported".  Later: a fault on satellite G00 was accepted, a fault on G99 or on a
system not simulated and an --obstacle-path 10,000 km away ran silently (now warnings), ``config --check`` passed
missing trajectory / world / navigation files, threats-plot of a run without an active event drew an empty panel
without a word, and ``calibrate --world-offset 1,2,1e6`` said "gnss-sim calibrate:" twice.
"""
from __future__ import annotations

from pathlib import Path

import pytest
from cli_helpers import case_ids, refuse_case, run_cli

REPO = Path(__file__).resolve().parents[1]
COURTYARD = str(REPO / "worlds" / "courtyard.sdf")


JAMMER = ("version: 1\nevents:\n  - type: jammer\n    position: [48.0, 11.0, 500.0]\n    position_type: llh\n"
          "    eirp_dbw: -40\n    center_hz: 1575.42e6\n    bandwidth_hz: 2.0e6\n    start_s: {start}\n"
          "    end_s: {end}\n")


def _cases(tmp: Path, write: bool = True):
    """(case id, argv, words the message must hold); ``write``: the input files too."""
    def _write(name: str, text: str) -> Path:
        path = tmp / name
        if write:
            path.write_text(text)
        return path

    far = _write("far.csv", "x_m,y_m\n0,0\n1e9,1e9\n")
    obstacle = _write("obstacle.csv", "t_s,e_m,n_m,u_m\n0,1,2,0\n5,1,2,0\n")
    plan = ["plan", "--world", COURTYARD, "--hours", "0.2", "--step-m", "10", "--quiet", "--out", tmp / "plan"]
    mask = _write("mask.csv", "azimuth_deg,elevation_deg\n0,10\n180,20\n")
    mask_plan = ["plan", "--sky-mask", mask, "--hours", "0.2", "--quiet", "--out", tmp / "plan", "--origin"]
    sim = ["simulate", "--duration", "5", "--position", "48,11,500", "--quiet", "--out", tmp / "sim"]
    cal = ["calibrate", "--obs", tmp / "absent.rnx", "--nav", tmp / "absent_nav.rnx", "--out", tmp / "cal"]
    cmp_ = ["compare", "--sim", tmp / "a.rnx", "--real", tmp / "b.rnx", "--nav", tmp / "n.rnx", "--out", tmp / "cmp"]
    return [
        ("plan-grid-too-fine", [*plan, "--step-m", "0.001"], ["option --step-m 0.001", "200,000 x 200,000 cells"]),
        ("plan-hours-huge", [*plan, "--hours", "1e7"], ["option --hours", "maximum is 744 h"]),
        ("plan-time-steps", [*plan, "--every-min", "1e-6"], ["--hours and --every-min", "12,000,001 time steps"]),
        ("plan-workers-0", [*plan, "--workers", "0"], ["option --workers is 0"]),
        ("plan-height-huge", [*plan, "--height-m", "1e9"], ["option --height-m", "0..10000 m"]),
        ("plan-good-cn0", [*plan, "--good-cn0-dbhz", "-400"], ["option --good-cn0-dbhz is -400"]),
        ("plan-share-tile-negative", [*plan, "--share-tile-m", "-1"], ["option --share-tile-m is -1.0", "0..2000 m"]),
        ("plan-share-tile-nan", [*plan, "--share-tile-m", "nan"], ["option --share-tile-m is nan", "0..2000 m"]),
        ("plan-start-span", [*plan, "--start", "3025-01-01T00:00:00"], ["option --start", "supported span"]),
        ("plan-polygon-empty", [*plan, "--polygon="], ["option --polygon", "empty value ''"]),   # cli.py
        ("plan-path-outside", [*plan, "--path", far], [f"option --path {far}, point 2", "outside the world"]),
        ("plan-point-outside", [*plan, "--point", "1e7,1e7"], ["option --point '1e7,1e7'", "outside the world"]),
        ("plan-origin-latitude", [*mask_plan, "95,11,500"], ["option --origin", "latitude 95 deg"]),
        ("plan-origin-height", [*mask_plan, "48,11,1e8"], ["option --origin", "height 1e+08 m"]),
        ("plan-mask-polygon", [*mask_plan, "48,11,500", "--polygon=0,0;1,0;1,1"], ["option --polygon", "one point"]),
        ("plan-mask-path", [*mask_plan, "48,11,500", "--path", far], ["option --path", "one point"]),
        ("obstacle-no-scene", [*sim, "--obstacle-path", obstacle], ["option --obstacle-path", "--world"]),
        ("calibrate-offset-no-scene", [*cal, "--world-offset", "1,2,3"], ["option --world-offset", "--world"]),
        ("calibrate-strong-nan", [*cal, "--strong-cn0-dbhz", "nan"], ["option --strong-cn0-dbhz is nan"]),
        ("compare-offset-no-scene", [*cmp_, "--world-offset", "1,2,3"], ["option --world-offset", "--world"]),
        ("compare-strong-range", [*cmp_, "--strong-cn0-dbhz", "500"], ["option --strong-cn0-dbhz is 500"]),
        ("compare-antenna-height", [*cmp_, "--world", COURTYARD, "--antenna-height-m", "-5"],
         ["option --antenna-height-m is -5"]),
        ("threats-plot-png", ["threats-plot", tmp, "--png", tmp / "figure.txt"], ["option --png", ".png"]),
        # the table's error under a command named the command twice ("gnss-sim calibrate: error: gnss-sim calibrate:")
        ("calibrate-offset-huge", [*cal, "--world", COURTYARD, "--world-offset", "1,2,1e6"],
         ["gnss-sim calibrate: error: command line: option --world-offset", "within +-1000 m"]),
    ]


CASE_IDS = case_ids(_cases)


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_is_refused_naming_the_option(case, tmp_path, capsys):
    refuse_case(_cases, case, tmp_path, capsys)
    for out in ("plan", "sim", "cal", "cmp"):
        assert not (tmp_path / out).exists() or not any((tmp_path / out).iterdir()), f"{out}: written on a refusal"
    assert not (tmp_path / "figure.txt").exists()


def test_sky_mask_error_names_the_parameter_once(tmp_path, capsys):
    """The sky mask's reader error under the parameter table names the parameter once (it said
    "parameter 'sky_mask_csv': parameter 'sky_mask_csv': ...")."""
    cfg = tmp_path / "mask.yaml"
    cfg.write_text(f"gnss_sim_visibility:\n  ros__parameters:\n    sky_mask_csv: {tmp_path / 'absent.csv'}\n")
    rc, text = run_cli(["config", "--check", cfg], capsys)
    assert rc == 2, text
    assert text.count("parameter 'sky_mask_csv'") == 1, text
    assert "absent.csv: cannot read it" in text


def test_a_failed_plan_leaves_the_previous_results(tmp_path, capsys):
    """A plan refused after its output folder was taken (a --path point outside the world, found once the scene
    is loaded) leaves the earlier plan's files as they were."""
    out = tmp_path / "plan"
    base = ["plan", "--world", COURTYARD, "--hours", "0.2", "--every-min", "10", "--quiet", "--out", out]
    good = tmp_path / "good.csv"
    good.write_text("x_m,y_m\n0,0\n5,5\n")
    rc, text = run_cli([*base, "--path", good], capsys)
    assert rc == 0, text
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert "plan.nc" in before or "plan.parquet" in before, sorted(before)
    far = tmp_path / "far.csv"
    far.write_text("x_m,y_m\n0,0\n1e9,0\n")
    rc, text = run_cli([*base, "--path", far], capsys)
    assert rc == 2 and "outside the world" in text, text
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


def test_quality_map_grid_refusal_names_its_parameter():
    """The quality_map node's grid (core/planning/live.py) goes through the same bound as the planner and names
    the node's parameter, not the planner's option."""
    from gnss_sim_ros2.core.planning.area import MAX_CELL_TIMES, grid_area

    with pytest.raises(ValueError, match=r"^parameter 'grid_step_m' 0\.01: a grid of 200,000 x 200,000 cells"):
        grid_area(0.01, (-1000.0, -1000.0, 1000.0, 1000.0), step_name="parameter 'grid_step_m'")
    area = grid_area(2.0, (-1000.0, -1000.0, 1000.0, 1000.0))          # 1e6 cells: well under the bound
    assert area.n_cells == 1_000_000 < MAX_CELL_TIMES


def test_scenario_event_after_the_run_is_said(tmp_path, capsys):
    """An event that starts after the run's end will not happen: the run says so, naming the file, the event's
    line and key (a warning: a bundled scenario run shorter on purpose is legal, test_threats_graph)."""
    late = tmp_path / "late.yaml"
    late.write_text(JAMMER.format(start=1000, end=2000))
    rc, text = run_cli(["simulate", "--duration", "5", "--position", "48,11,500", "--scenario", late,
                     "--out", tmp_path / "sim"], capsys)
    assert rc == 0, text
    for w in (f"scenario {late}, line 3", "'events[0].start_s'", "option --duration = 5 s", "will not be active"):
        assert w in text, (w, text)
    # inside the run: nothing said; the jammer stands on the antenna (same llh): its direction is undefined, was
    # NaN elevation -> "Tracker.update: 'cn0_dbhz' has non-finite values" (rc 2), now its boresight gain
    late.write_text(JAMMER.format(start=2, end=2000))
    rc, text = run_cli(["simulate", "--duration", "5", "--position", "48,11,500", "--scenario", late,
                     "--out", tmp_path / "sim"], capsys)
    assert rc == 0 and "will not be active" not in text, text


FAULT = ("version: 1\nevents:\n  - type: fault\n    kind: satellite_clock_step_m\n    satellite: {sv}\n"
         "    step_m: 100\n    start_s: 0\n    end_s: 10\n")


def test_a_malformed_satellite_id_is_refused(tmp_path, capsys):
    """A fault's satellite id that is not a RINEX one is refused naming file, line and key; PRN 00 was accepted."""
    for sv in ("X1", "G0", "G00"):
        bad = tmp_path / f"{sv}.yaml"
        bad.write_text(FAULT.format(sv=sv))
        rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--quiet", "--scenario", bad,
                         "--out", tmp_path / "sim"], capsys)
        assert rc == 2 and "Traceback" not in text, (sv, text)
        for w in (f"scenario {bad}, line 5", "'events[0].satellite'", "satellite id"):
            assert w in text, (sv, w, text)
        assert not (tmp_path / "sim").exists()


def test_a_fault_on_a_satellite_not_in_the_run_is_said(tmp_path, capsys):
    """A satellite fault on a system not simulated (said when the configuration is read) or on a satellite the
    ephemerides lack (G99, said once they are open) would change nothing: a warning naming file, line and key
    (it ran silently)."""
    two = tmp_path / "two.yaml"
    two.write_text(FAULT.format(sv="G99") + FAULT.format(sv="E05").split("events:\n", 1)[1])
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--systems", "G", "--scenario", two,
                     "--out", tmp_path / "sim"], capsys)
    assert rc == 0, text
    for w in (f"scenario {two}, line 5: key 'events[0].satellite'", "ephemerides have no G99",
              f"scenario {two}, line 11: key 'events[1].satellite'", "system E is not simulated (systems G)"):
        assert w in text, (w, text)
    assert text.count("will have no effect") == 2, text
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--systems", "GE", "--scenario",
                     two, "--out", tmp_path / "sim"], capsys)     # E05 is simulated now: only G99 is said
    assert rc == 0 and text.count("will have no effect") == 1 and "G99" in text, text


def test_config_check_names_every_missing_file(tmp_path, capsys):
    """config --check reports every input file a parameter names that is missing, with its parameter (it passed
    them; simulate and run stopped at the first they opened); nav_files beside source synthetic are not read."""
    cfg = tmp_path / "files.yaml"
    cfg.write_text(f"gnss_sim_ephemeris:\n  ros__parameters:\n    source: broadcast\n"
                   f"    nav_files: [{tmp_path / 'nav.rnx'}]\n"
                   f"gnss_sim_visibility:\n  ros__parameters:\n    world_file: {tmp_path / 'world.sdf'}\n"
                   f"gnss_sim_trajectory_player:\n  ros__parameters:\n    trajectory_file: {tmp_path / 'a.csv'}\n"
                   f"    robot_trajectory_files: [{tmp_path / 'b.csv'}]\n")
    rc, text = run_cli(["config", "--check", cfg], capsys)
    assert rc == 2 and "Traceback" not in text, text
    for name, file in (("nav_files'[0]", "nav.rnx"), ("world_file'", "world.sdf"), ("trajectory_file'", "a.csv"),
                       ("robot_trajectory_files'[0]", "b.csv")):
        assert f"parameter '{name} {tmp_path / file}: no such file" in text, (name, text)
    cfg.write_text(cfg.read_text().replace("source: broadcast", "source: synthetic"))
    (tmp_path / "world.sdf").write_text("<sdf/>")
    (tmp_path / "a.csv").write_text("t_s,e_m,n_m,u_m\n0,0,0,0\n")
    (tmp_path / "b.csv").write_text("t_s,e_m,n_m,u_m\n0,0,0,0\n")
    rc, text = run_cli(["config", "--check", cfg], capsys)
    assert rc == 0, text


def test_an_obstacle_path_far_outside_the_world_is_said(tmp_path, capsys):
    """An --obstacle-path 10,000 km from the world blocks nothing: a warning naming the option, file and line
    (it ran silently); a path leaving the world by metres is not said."""
    far = tmp_path / "far.csv"
    far.write_text("t_s,e_m,n_m,u_m\n0,1,2,0\n5,1e7,2,0\n")
    near = tmp_path / "near.csv"
    near.write_text("t_s,e_m,n_m,u_m\n0,1,2,0\n5,150,2,0\n")
    base = ["simulate", "--duration", "2", "--world", COURTYARD, "--out", tmp_path / "sim", "--obstacle-path"]
    rc, text = run_cli([*base, far], capsys)
    assert rc == 0, text
    assert f"option --obstacle-path {far}:3: x 1e+07, y 2 m lies" in text and "outside the world" in text, text
    rc, text = run_cli([*base, near], capsys)
    assert rc == 0 and "outside the world" not in text, text


def test_threats_plot_says_when_no_event_was_active(tmp_path, capsys):
    """A run whose scenario had no event inside it: threats-plot says its events panel is empty (it was silent)."""
    empty = tmp_path / "empty.yaml"
    empty.write_text("version: 1\nevents: []\n")
    run = tmp_path / "sim"
    rc, text = run_cli(["simulate", "--duration", "2", "--position", "48,11,500", "--quiet", "--scenario", empty,
                     "--out", run], capsys)
    assert rc == 0, text
    rc, text = run_cli(["threats-plot", run, "--png", tmp_path / "t.png"], capsys)
    assert rc == 0 and "no event of the scenario was active in any epoch" in text, text

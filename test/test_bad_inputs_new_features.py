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
matplotlib's "Format 'txt' is not supported".
"""
from __future__ import annotations

from pathlib import Path

import pytest

from gnss_sim_ros2.cli import main

REPO = Path(__file__).resolve().parents[1]
COURTYARD = str(REPO / "worlds" / "courtyard.sdf")


def _cli(argv, capsys) -> tuple[int, str]:
    """(exit code, stdout + stderr) of ``gnss-sim ARGV`` run in this process (argparse's exit included)."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as exc:
        rc = exc.code
    out = capsys.readouterr()
    return rc, out.out + out.err


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
        ("plan-start-span", [*plan, "--start", "3025-01-01T00:00:00"], ["option --start", "supported span"]),
        ("plan-polygon-empty", [*plan, "--polygon="], ["option --polygon ''", "three x,y vertices"]),
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
    ]


CASE_IDS = [c[0] for c in _cases(Path("."), write=False)]


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_is_refused_naming_the_option(case, tmp_path, capsys):
    _, argv, words = next(c for c in _cases(tmp_path) if c[0] == case)
    rc, text = _cli(argv, capsys)
    assert rc not in (0, None), text
    assert "Traceback" not in text, text
    for w in words:
        assert w in text, (w, text)
    for out in ("plan", "sim", "cal", "cmp"):
        assert not (tmp_path / out).exists() or not any((tmp_path / out).iterdir()), f"{out}: written on a refusal"
    assert not (tmp_path / "figure.txt").exists()


def test_sky_mask_error_names_the_parameter_once(tmp_path, capsys):
    """The sky mask's reader error under the parameter table names the parameter once (it said
    "parameter 'sky_mask_csv': parameter 'sky_mask_csv': ...")."""
    cfg = tmp_path / "mask.yaml"
    cfg.write_text(f"gnss_sim_visibility:\n  ros__parameters:\n    sky_mask_csv: {tmp_path / 'absent.csv'}\n")
    rc, text = _cli(["config", "--check", cfg], capsys)
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
    rc, text = _cli([*base, "--path", good], capsys)
    assert rc == 0, text
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert "plan.nc" in before or "plan.parquet" in before, sorted(before)
    far = tmp_path / "far.csv"
    far.write_text("x_m,y_m\n0,0\n1e9,0\n")
    rc, text = _cli([*base, "--path", far], capsys)
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
    rc, text = _cli(["simulate", "--duration", "5", "--position", "48,11,500", "--scenario", late,
                     "--out", tmp_path / "sim"], capsys)
    assert rc == 0, text
    for w in (f"scenario {late}, line 3", "'events[0].start_s'", "option --duration = 5 s", "will not be active"):
        assert w in text, (w, text)
    # inside the run: nothing said; the jammer stands on the antenna (same llh): its direction is undefined, was
    # NaN elevation -> "Tracker.update: 'cn0_dbhz' has non-finite values" (rc 2), now its boresight gain
    late.write_text(JAMMER.format(start=2, end=2000))
    rc, text = _cli(["simulate", "--duration", "5", "--position", "48,11,500", "--scenario", late,
                     "--out", tmp_path / "sim"], capsys)
    assert rc == 0 and "will not be active" not in text, text

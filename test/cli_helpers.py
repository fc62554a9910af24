"""The bad-input tests' shared steps: run ``gnss-sim ARGV`` in this process and check a refusal; a table of cases
``cases(folder, write=True)`` -> [(id, argv, words)] (its inputs written under ``folder``), its ids for parametrize
and one case run and refused (test_bad_inputs*.py)."""
from __future__ import annotations

from pathlib import Path

from gnss_sim_ros2.cli import main


def run_cli(argv, capsys) -> tuple[int, str]:
    """(exit code, stdout + stderr) of ``gnss-sim ARGV`` run in this process (argparse's exit included)."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as exc:          # argparse refusing an option
        rc = exc.code
    out = capsys.readouterr()
    return rc, out.out + out.err


def assert_refused(rc, text: str, words) -> None:
    """A refusal: a non-zero exit, no traceback, and every word of ``words`` (the option, file, line or
    parameter) in the message."""
    assert rc not in (0, None), text
    assert "Traceback" not in text, text
    for w in words:
        assert w in text, (w, text)


def case_ids(cases) -> list[str]:
    """The ids of the case table ``cases`` (pytest.mark.parametrize's list; nothing written)."""
    return [c[0] for c in cases(Path("."), write=False)]


def refuse_case(cases, case: str, tmp_path, capsys) -> None:
    """Case ``case`` of the table ``cases`` with its inputs under ``tmp_path``: run, and refused naming its words."""
    _, argv, words = next(c for c in cases(tmp_path) if c[0] == case)
    rc, text = run_cli(argv, capsys)
    assert_refused(rc, text, words)

"""The bad-input tests' two shared steps: run ``gnss-sim ARGV`` in this process and check a refusal
(test_bad_inputs*.py)."""
from __future__ import annotations

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

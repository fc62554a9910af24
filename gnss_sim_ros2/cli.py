"""``gnss-sim`` command line tool.

Each subcommand is a module of ``gnss_sim_ros2/commands/`` (``commands/<name>.py``, or a package
along its seams: ``commands/run/``), named in ``COMMANDS``, exposing ``add_arguments(parser)`` and
``run(args) -> int`` (a package from its ``__init__``).  Modules are imported only
when their subcommand runs, so ``gnss-sim --help`` stays fast and a command
never pays for another's dependencies.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import re
import signal
import sys
import warnings
from pathlib import Path

from . import __version__

#: subcommand -> (module under gnss_sim_ros2.commands, one-line help)
COMMANDS = {
    "run": ("run", "run the node graph (what sim.launch.py starts): RINEX, bag, sky plot, summary"),
    "roundtrip": ("roundtrip", "publish every gnss_sim_msgs type and receive it in another process"),
    "simulate": ("simulate", "simulate a receiver offline (no ROS): RINEX observation/navigation files + fix.csv"),
    "config": ("config", "print the default parameter file (config/gnss_sim.yaml) or check one"),
    "profile": ("profile", "list the built-in receiver profiles or print one as YAML (a start for your own)"),
    "export-world": ("export_world", "export an SDF world's geometry and materials to a scene mesh (PLY + sidecar)"),
    "skyplot": ("skyplot", "line-of-sight state of every satellite from a point of a world (CSV, sky plot PNG)"),
    "bench": ("bench", "speed against accuracy of the fidelity presets: table, JSON, cost/accuracy plot"),
    "satpos": ("satpos", "satellite positions, velocities and clocks on a time grid (broadcast or SP3) as CSV"),
    "plan": ("plan", "GNSS quality over an area and a time window: satellites, DOP, expected accuracy, RTK "
             "indicator per cell and time; maps, GeoJSON, NetCDF/Parquet, best windows"),
    "sweep": ("sweep", "one simulate scenario over seeds, dates, presets, trajectories, worlds on Dask: Parquet rows"),
    "compare": ("compare", "compare simulated and real observations (RINEX or bag): differences, visibility, "
                "positions; Markdown report with figures"),
    "threats-plot": ("threats_plot", "the threat timeline of a run with a scenario: C/N0, satellites, fix error and "
                     "the truth labels over time (PNG)"),
    "calibrate": ("calibrate", "fit a receiver profile (YAML) to a real RINEX recording: C/N0 and code noise against "
                  "elevation, tracking, flags; report with figures"),
}


def build_parser(load_all: bool = True) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gnss-sim",
        description="GNSS receiver simulator for ROS 2 robots: satellites, visibility, observations, RINEX.",
    )
    parser.add_argument("--version", action="version", version=f"gnss-sim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if load_all:
            importlib.import_module(f"gnss_sim_ros2.commands.{module}").add_arguments(p)
            _add_quiet(p)
    return parser


def _add_quiet(p: argparse.ArgumentParser) -> None:
    """Every subcommand takes --quiet: no warnings (the commands that print progress also drop it)."""
    if "--quiet" not in p._option_string_actions:
        p.add_argument("--quiet", action="store_true", help="no warnings (errors only)")


class _OneLine(logging.Formatter):
    """``gnss-sim <command>: warning: <message>``, one line per record."""

    def __init__(self, command: str):
        super().__init__()
        self.command = command

    def format(self, record: logging.LogRecord) -> str:
        text = " ".join(record.getMessage().split())
        return f"gnss-sim {self.command}: {record.levelname.lower()}: {text}"


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """warnings.showwarning: a warning through logging, one line. gnss_sim's own warnings name their file and
    reason in the message; another package's say where they come from."""
    text = str(message)
    if not (category.__module__ or "").startswith("gnss_sim_ros2"):
        text = f"{category.__name__} ({Path(filename).name}:{lineno}): {text}"
    logging.getLogger("gnss_sim_ros2").warning(text)


def route_messages(command: str, quiet: bool) -> None:
    """Warnings (Python's and gnss_sim's loggers') go to stderr through logging, one line each, named after the
    command; ``quiet``: errors only."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_OneLine(command))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(logging.ERROR if quiet else logging.WARNING)
    warnings.showwarning = _show_warning


#: a value that starts with a minus sign: -5, -3976219.5082,3382372.5671,3652512.9849, -.5, -1e-3
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d)[\d.,eE+\-]*$")


def _attach_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``--opt -3976219.5,...`` -> ``--opt=-3976219.5,...`` for every option of ``parser`` (and its
    subcommands) that takes a value, so numbers and X,Y,Z / LAT,LON,H triples west of Greenwich or
    south of the equator can be typed after a space, as users do.  argparse alone takes them for options."""
    takes_value = set()
    stack = [parser]
    while stack:
        p = stack.pop()
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                stack.extend(action.choices.values())
            elif action.option_strings and action.nargs != 0:
                takes_value.update(action.option_strings)
    out: list[str] = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in takes_value and i + 1 < len(argv) and _NEGATIVE_VALUE.match(argv[i + 1]):
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def _option_action(by_string: dict, opt: str):
    """The action of option ``opt`` as argparse resolves it: the option itself, or the one option it abbreviates
    (``--dur`` for --duration); None otherwise."""
    if opt in by_string:
        return by_string[opt]
    matches = {id(a): a for s, a in by_string.items() if opt.startswith("--") and s.startswith(opt)}
    return next(iter(matches.values())) if len(matches) == 1 else None


def _check_values(parser: argparse.ArgumentParser, args, tokens: list[str]) -> list[tuple[str, str]]:
    """Refuse (exit 2, one line) an empty or blank value of an option or argument, naming it (``--out ''``
    meant the current folder, ``--position ''`` the configuration's position, ``--rtcm ''`` the default file, a
    blank --marker the default marker: each a silent default); returns the (option, last value) of the options
    given more than once (argparse keeps the last without a word: the caller warns)."""
    by_string = parser._option_string_actions
    seen: set = set()
    twice: dict = {}
    current = None

    def blank(action, value):
        name = "/".join(action.option_strings) or action.metavar or action.dest
        what = f"option {name}" if action.option_strings else f"argument {name}"
        parser.exit(2, f"{parser.prog}: error: {what} is given an empty value {value!r}: give a value (or leave the "
                       f"option out)\n")

    for token in tokens:
        if token == "--":
            current = None
            continue
        opt, eq, value = token.partition("=") if token.startswith("--") else (token, "", "")
        action = _option_action(by_string, opt) if token.startswith("-") else None
        if action is not None:
            if action.nargs != 0 and not isinstance(action, argparse._AppendAction):
                if action.dest in seen:
                    twice[action.dest] = max(action.option_strings, key=len)      # --duration for --dur
                seen.add(action.dest)
            current = None if eq or action.nargs == 0 else action
            if eq and not value.strip():
                blank(action, value)
            continue
        if current is not None and not token.strip():
            blank(current, token)
        if current is not None and current.nargs in (None, "?", 1):
            current = None
    for action in parser._actions:      # positional arguments (a blank one read the current folder)
        value = getattr(args, action.dest, None)
        if not action.option_strings and isinstance(value, str) and not value.strip():
            blank(action, value)
    return [(opt, getattr(args, dest)) for dest, opt in twice.items()]


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    # Only the chosen subcommand's module is imported.
    chosen = next((a for a in argv if not a.startswith("-")), None)
    if chosen in COMMANDS:
        parser = build_parser(load_all=False)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        module = importlib.import_module(f"gnss_sim_ros2.commands.{COMMANDS[chosen][0]}")
        module.add_arguments(sub.choices[chosen])
        _add_quiet(sub.choices[chosen])
    else:
        parser = build_parser(load_all=False)
    argv = _attach_negative_values(parser, argv)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    module = importlib.import_module(f"gnss_sim_ros2.commands.{COMMANDS[args.command][0]}")
    command_parser = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[
        args.command]
    given_twice = _check_values(command_parser, args, argv[argv.index(args.command) + 1:])
    route_messages(args.command, bool(getattr(args, "quiet", False)))
    for option, last in given_twice:
        logging.getLogger("gnss_sim_ros2").warning(f"option {option} is given more than once: the last ({last}) is "
                                                   f"used")
    # SIGTERM unwinds like Ctrl-C (files closed by their finally blocks); `run` installs its own handlers
    signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(module.run(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except _Terminated:
        print("terminated", file=sys.stderr)
        return 143
    except OSError as exc:   # unwritable folder, a path under a regular file, disk full: one line, no traceback
        print(f"gnss-sim {args.command}: error: {os_error_text(exc)}", file=sys.stderr)
        return 1


class _Terminated(BaseException):
    """SIGTERM, raised where the program is (a BaseException: no ``except Exception`` swallows it)."""


def _terminate(signum, frame):
    raise _Terminated


def os_error_text(exc: OSError) -> str:
    """``path: reason`` of an operating-system error (both paths of a rename)."""
    where = " -> ".join(str(p) for p in (exc.filename, exc.filename2) if p)
    reason = exc.strerror or str(exc)
    return f"{where}: {reason}" if where else reason


if __name__ == "__main__":
    sys.exit(main())

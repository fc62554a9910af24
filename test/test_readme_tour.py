"""Every command of the README's "A 5-minute tour", run as written (issue 25).

The commands come from the fenced ``bash`` blocks of that section (up to its first subsection heading, "With
ROS 2 (Jazzy/Kilted) and Gazebo", which needs Gazebo): nothing is copied here, so a changed README is what runs.
Each command runs through bash (brace expansion, globs, ``2>/dev/null`` as a user's shell) with the repository
root as working folder, one after another in the README's order.

One documented substitution keeps the clone clean: every relative path the tour writes -- the value of
``--out``, ``--csv``, ``--png`` and ``-o``, and ``out/`` of ``make demo`` (its ``OUT`` variable) -- is placed
under a temporary folder, in the command that writes it and in every later command that reads it
(``cat out/summary.md``, ``opec/*_MO.rnx``).  A command fails the test when it exits with rc != 0 or when a
path it writes is missing afterwards.  A command that needs ``../shared`` skips with the reason when that
folder is absent (so does one that reads what a skipped command would have written), as does one whose
program is not installed (``rnx2rtkp``: Debian ``rtklib``).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SECTION = "A 5-minute tour"
#: options whose value is a path the command writes
OUTPUT_OPTIONS = ("--out", "--csv", "--png", "-o")
#: per command [s]: the longest (make demo) takes a few minutes on a loaded machine (145 s at load 6)
TIMEOUT_S = 600

pytestmark = pytest.mark.slow


def tour_commands(readme: Path = REPO_ROOT / "README.md") -> list[str]:
    """The shell commands of the tour section's ```bash blocks: continuation lines joined, comments and blank
    lines dropped, in the README's order."""
    text = readme.read_text(encoding="utf-8")
    m = re.search(rf"^## {re.escape(SECTION)}\s*$(.*?)^#{{2,}} ", text, flags=re.M | re.S)
    if m is None:
        raise AssertionError(f"README.md: no section '## {SECTION}' followed by another heading")
    commands = []
    for block in re.findall(r"^```(?:bash|sh|console)?\s*\n(.*?)^```", m.group(1), flags=re.M | re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = re.sub(r"(^|\s)#.*$", "", line).strip()
            if line:
                commands.append(line)
    return commands


def outputs_of(command: str) -> list[str]:
    """Relative paths ``command`` writes (the values of OUTPUT_OPTIONS; ``out`` for ``make demo``)."""
    words = command.split()
    found = [words[i + 1] for i, w in enumerate(words[:-1]) if w in OUTPUT_OPTIONS]
    if words[:2] == ["make", "demo"]:
        found.append("out/")
    return [w for w in found if not os.path.isabs(w)]


def _top(path: str) -> str:
    return path.split("/", 1)[0]


def is_output(word: str, names: set[str]) -> bool:
    """``word`` names one of the tour's outputs ``names`` or a path inside one (not a bare word such as the
    subcommand ``sweep``, whose output is ``sweep/``)."""
    return _top(word) in names and ("/" in word or "." in word)


def redirect(command: str, names: set[str], tmp: Path) -> str:
    """``command`` with every word that names one of ``names`` (the tour's outputs) or a path inside one placed
    under ``tmp``, and ``make demo`` given ``OUT=tmp/out``."""
    words = [str(tmp / w) if is_output(w, names) else w for w in command.split()]
    if words[:2] == ["make", "demo"]:
        words.insert(2, f"OUT={tmp / 'out'}")
    return " ".join(words)


COMMANDS = tour_commands()
OUTPUT_NAMES = {_top(p) for c in COMMANDS for p in outputs_of(c)}


def test_the_tour_has_its_commands():
    """The parser finds the tour (a renamed section would otherwise run nothing)."""
    assert any(c.startswith("make demo") for c in COMMANDS), COMMANDS
    assert sum(".venv/bin/gnss-sim" in c for c in COMMANDS) >= 5, COMMANDS
    assert {"out", "sky.png", "opec", "sweep"} <= OUTPUT_NAMES, OUTPUT_NAMES


@pytest.fixture(scope="module")
def tour_state(tmp_path_factory):
    """The temporary folder of the tour's outputs and the outputs of skipped commands."""
    before = {n for n in OUTPUT_NAMES if (REPO_ROOT / n).exists()}
    state = {"tmp": tmp_path_factory.mktemp("tour"), "skipped": set()}
    yield state
    created = {n for n in OUTPUT_NAMES if (REPO_ROOT / n).exists()} - before
    assert not created, f"the tour wrote into the clone: {sorted(created)} (the substitution missed them)"


@pytest.mark.parametrize("command", COMMANDS, ids=[f"{i}:{c.split()[0].split('/')[-1]} {c.split()[1]}"
                                                   for i, c in enumerate(COMMANDS)])
def test_tour_command(command, tour_state):
    tmp, skipped = tour_state["tmp"], tour_state["skipped"]
    outputs = outputs_of(command)
    words = command.split()
    program = words[0]
    reads = {_top(w) for w in words if is_output(w, OUTPUT_NAMES)} - {_top(p) for p in outputs}
    shared = REPO_ROOT.parent / "shared"
    reason = None
    if "../shared" in command and not shared.is_dir():
        reason = f"{shared} is absent (the tour's real data lives beside the clone)"
    elif reads & skipped:
        reason = f"it reads {sorted(reads & skipped)}, written by a skipped command"
    elif "/" not in program and shutil.which(program) is None:
        reason = f"{program} is not installed"
    if reason:
        skipped.update(_top(p) for p in outputs)
        pytest.skip(f"{command}: {reason}")
    run = redirect(command, OUTPUT_NAMES, tmp)
    proc = subprocess.run(["bash", "-c", run], cwd=REPO_ROOT, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert proc.returncode == 0, (f"README tour command failed (rc {proc.returncode}):\n  {command}\n"
                                  f"ran as: {run}\nstdout:\n{proc.stdout[-3000:]}\nstderr:\n{proc.stderr[-3000:]}")
    missing = [p for p in outputs if not (tmp / p).exists()]
    assert not missing, f"{command}: wrote no {missing}\nstdout:\n{proc.stdout[-2000:]}"

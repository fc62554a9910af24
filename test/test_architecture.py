"""The architecture contract (.importlinter, run by `make test` as `lint-imports`) bites.

Each case copies the package and the contract file into a temporary folder, writes one import the rules
forbid into the copy (inside a function: lazy imports count) and runs the contract it breaks there: it
must fail, naming what it found; the untouched copy must pass every contract.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")

pytestmark = pytest.mark.skipif(not LINT_IMPORTS.is_file(),
                                reason=f"{LINT_IMPORTS} is absent (requirements/test.txt: import-linter)")


def _copy(root: Path) -> Path:
    shutil.copytree(REPO / "gnss_sim_ros2", root / "gnss_sim_ros2", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(REPO / ".importlinter", root / ".importlinter")
    return root


def _lint(root: Path, *contracts: str) -> subprocess.CompletedProcess:
    args = [str(LINT_IMPORTS), "--no-cache", "--no-logo"]
    for c in contracts:
        args += ["--contract", c]
    # the copy, not the installed package, is the one analysed
    env = {**os.environ, "PYTHONPATH": str(root), "COLUMNS": "300"}
    return subprocess.run(args + [str(root / ".importlinter")], cwd=root, env=env, capture_output=True, text=True,
                          timeout=300)


def test_the_package_as_it_is_keeps_every_contract(tmp_path):
    r = _lint(_copy(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 broken" in r.stdout


@pytest.mark.parametrize("module, line, contract, found", [
    # the receiver reaching up to the offline loop
    ("core/receiver/engine.py", "from ..simulation import run_simulation", "physics-below-offline",
     "gnss_sim_ros2.core.receiver.engine -> gnss_sim_ros2.core.simulation"),
    # the antenna tables taking from the receiver again (the cycle issue 28 removed)
    ("core/multipath/antenna.py", "from ..receiver import cn0", "core-layers",
     "gnss_sim_ros2.core.multipath.antenna -> gnss_sim_ros2.core.receiver.cn0"),
    # a validation harness back inside the physics
    ("core/scene/visibility.py", "from ..comparison import drive_check", "core-layers",
     "gnss_sim_ros2.core.scene.visibility -> gnss_sim_ros2.core.comparison.drive_check"),
    # ROS inside the core
    ("core/frames.py", "import rclpy", "ros-free-core", "gnss_sim_ros2.core.frames -> rclpy"),
    # a node taking from a command
    ("nodes/common.py", "from gnss_sim_ros2.commands import simulate", "nodes-below-commands",
     "gnss_sim_ros2.nodes.common -> gnss_sim_ros2.commands.simulate"),
])
def test_an_upward_import_breaks_its_contract(tmp_path, module, line, contract, found):
    root = _copy(tmp_path)
    path = root / "gnss_sim_ros2" / module
    assert path.is_file(), path
    with open(path, "a") as f:
        f.write(f"\n\ndef _upward_import_for_the_test():\n    {line}  # noqa: F401\n")
    r = _lint(root, contract)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "BROKEN" in r.stdout and found in r.stdout, r.stdout


def _import_cycles(package_root: Path) -> list[tuple[str, str]]:
    """(a, b) for every project import a -> b (function-level ones included) from which a chain leads back
    to a: the edges of the package's import cycles (grimp, the graph import-linter builds on)."""
    code = ("import grimp, json; g = grimp.build_graph('gnss_sim_ros2', cache_dir=None); "
            "print(json.dumps([(a, b) for a in sorted(g.modules)"
            " for b in sorted(g.find_modules_directly_imported_by(a))"
            " if b.startswith('gnss_sim_ros2') and g.find_shortest_chain(importer=b, imported=a)]))")
    env = {**os.environ, "PYTHONPATH": str(package_root)}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=package_root,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    import json

    return [tuple(e) for e in json.loads(r.stdout)]


def test_no_import_cycle_in_the_package():
    assert _import_cycles(REPO) == []


def test_a_cycle_is_found(tmp_path):
    """The cycle check bites: the parameter table importing the graph again (parameters -> graph ->
    graph_params -> parameters, as before config_file.py held the loader) is reported."""
    root = _copy(tmp_path)
    with open(root / "gnss_sim_ros2" / "parameters.py", "a") as f:
        f.write("\n\ndef _cycle_for_the_test():\n    from gnss_sim_ros2 import graph  # noqa: F401\n")
    assert ("gnss_sim_ros2.parameters", "gnss_sim_ros2.graph") in _import_cycles(root)

"""Register gnss_sim in the ament index of a prefix, as a colcon install does.

    python scripts/ament_register.py PREFIX [--executables]

An editable pip install (setup.py develop) installs no ``data_files``, so
``ros2 launch gnss_sim ...``, ``ros2 component types`` and
``get_package_share_directory('gnss_sim')`` would not find the package.  This
copies every ``data_files`` entry of setup.py (the package marker, the
rclcpp_components resource, package.xml, launch/, config/, worlds/) into
PREFIX as real files (``ros2 launch`` does not walk symlinked folders);
``share/gnss_sim`` is rebuilt on every run so that it stays current.
``--executables`` also writes ``PREFIX/lib/gnss_sim/<console script>`` (for a
prefix that pip did not install into, e.g. a developer's overlay).
"""
from __future__ import annotations

import argparse
import os
import runpy
import shutil
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def setup_kwargs() -> dict:
    import setuptools

    captured = {}
    real = setuptools.setup
    setuptools.setup = lambda **kw: captured.update(kw)
    cwd = os.getcwd()
    try:
        os.chdir(REPO)
        runpy.run_path(str(REPO / "setup.py"), run_name="__main__")
    finally:
        setuptools.setup = real
        os.chdir(cwd)
    return captured


def register(prefix: Path, executables: bool) -> list[Path]:
    kw = setup_kwargs()
    name = kw["name"]
    shutil.rmtree(prefix / "share" / name, ignore_errors=True)
    written = []
    for dest, files in kw["data_files"]:
        (prefix / dest).mkdir(parents=True, exist_ok=True)
        for f in files:
            target = prefix / dest / Path(f).name
            if target.is_symlink():
                target.unlink()
            shutil.copyfile(REPO / f, target)
            written.append(target)
    if executables:
        bindir = prefix / "lib" / name
        bindir.mkdir(parents=True, exist_ok=True)
        for line in kw["entry_points"]["console_scripts"]:
            exe, _, target = (x.strip() for x in line.partition("="))
            module, _, func = target.partition(":")
            path = bindir / exe
            path.write_text(f"#!{sys.executable}\nimport sys\nfrom {module} import {func}\nsys.exit({func}())\n")
            path.chmod(0o755)
            written.append(path)
    return written


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("prefix", type=Path)
    ap.add_argument("--executables", action="store_true", help="also write lib/gnss_sim/<console script>")
    a = ap.parse_args()
    files = register(a.prefix.resolve(), a.executables)
    print(f"[ament] gnss_sim registered in {a.prefix} ({len(files)} files)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

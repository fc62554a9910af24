"""The parameters that name input files, and the check that those files exist (``gnss-sim config --check``).

The parameter table (parameters.py) checks each value's type and range; the files themselves are opened by the
run that needs them (``simulate``, ``run``, the nodes' configure), each with its own error.  ``config --check``
reports every missing file at once, naming its section and parameter, instead of letting the run find them one by
one.  ``scenario``, ``sky_mask_csv`` and ``profile`` are read by the table itself (their errors come first).
Relative paths are taken from the working directory, as the run takes them.
"""
from __future__ import annotations

from pathlib import Path

from gnss_sim_ros2.parameters import NODE_NAMES, Config

#: parameter name -> the ephemeris sources that read it (None: read whenever it is set)
FILE_PARAMETERS: dict[str, tuple | None] = {
    "trajectory_file": None,
    "robot_trajectory_files": None,
    "world_file": None,
    "mesh_file": None,
    "materials_file": None,
    "scenario_world": None,
    "sky_mask_csv": None,
    "scenario": None,
    "nav_files": ("broadcast", "sp3"),
    "sp3_files": ("broadcast", "sp3"),
    "clk_files": ("broadcast", "sp3"),
}
#: sections whose nav_files are read whatever their ``source`` (the RTK node sends them to rtkrcv)
ALWAYS_READ = {("rtk", "nav_files")}


def missing_files(cfg: Config, options: dict[str, str] | None = None) -> list[str]:
    """One message per file a parameter of ``cfg`` names that is not a readable file (section, parameter, path);
    each (parameter, path) once, under the first section naming it; ``options``: {parameter: the command-line
    option that gave it} (the message names the option instead of the file's section)."""
    out, seen = [], set()
    for key, values in cfg.values.items():
        for name, sources in FILE_PARAMETERS.items():
            value = values.get(name)
            if not value:
                continue
            if (sources is not None and (key, name) not in ALWAYS_READ
                    and values.get("source", sources[0]) not in sources):
                continue                                     # e.g. nav_files beside source synthetic: not read
            for i, path in enumerate(value if isinstance(value, list) else [value]):
                if (name, path) in seen or Path(path).expanduser().is_file():
                    continue
                seen.add((name, path))
                entry = f"[{i}]" if isinstance(value, list) else ""
                what = "no such file" if not Path(path).expanduser().exists() else "not a file"
                where = f"option {options[name]}" if options and name in options else f"{cfg.source}: {NODE_NAMES[key]}"
                out.append(f"{where}: parameter '{name}'{entry} {path}: {what}")
    return out

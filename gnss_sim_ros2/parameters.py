"""Every gnss_sim parameter, once: name, type, default, unit, range, meaning.

One configuration file drives both the ROS launch and the offline tools.  It
is an ordinary ROS 2 parameter file::

    /**:                       # shared by every gnss_sim node
      ros__parameters:
        systems: GRE
    gnss_sim_receiver:         # one node's own parameters
      ros__parameters:
        profile: single_frequency

``launch/sim.launch.py`` hands that file to the nodes; ``gnss-sim run`` and
``gnss-sim simulate --config`` read it through :func:`load_config`, so a user
never writes a setting twice.  ``config/gnss_sim.yaml`` lists every parameter
with its default; a test keeps it equal to this table.

This module is ROS-free: the nodes turn the table into parameter descriptors.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

#: ROS node names (the keys of a parameter file)
NODE_NAMES = {
    "ephemeris": "gnss_sim_ephemeris",
    "visibility": "gnss_sim_visibility",
    "receiver": "gnss_sim_receiver",
    "trajectory": "gnss_sim_trajectory_player",
}
SHARED_KEY = "/**"


@dataclass(frozen=True)
class Param:
    name: str
    default: Any
    description: str
    choices: tuple = ()
    min: float | None = None
    max: float | None = None
    #: element type for an empty list default ("string" or "double")
    item_type: str = ""

    @property
    def kind(self) -> str:
        if isinstance(self.default, bool):
            return "bool"
        if isinstance(self.default, int):
            return "integer"
        if isinstance(self.default, float):
            return "double"
        if isinstance(self.default, str):
            return "string"
        if isinstance(self.default, list):
            item = self.item_type or ("double" if self.default and isinstance(self.default[0], float) else "string")
            return f"{item}_array"
        raise TypeError(f"parameter {self.name}: unsupported default {self.default!r}")

    def check(self, value, where: str):
        """Validated (and type-normalised) value; ValueError naming the parameter and ``where``."""
        kind = self.kind
        bad = ValueError(f"{where}: parameter '{self.name}' must be {kind}, got {value!r}")
        if kind == "bool":
            if not isinstance(value, bool):
                raise bad
        elif kind == "integer":
            if isinstance(value, bool) or not isinstance(value, int):
                raise bad
        elif kind == "double":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise bad
            value = float(value)
        elif kind == "string":
            if not isinstance(value, str):
                raise bad
        else:
            if not isinstance(value, (list, tuple)):
                raise bad
            if kind == "double_array":
                if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
                    raise bad
                value = [float(v) for v in value]
            elif not all(isinstance(v, str) for v in value):
                raise bad
            value = list(value)
        if self.choices and value not in self.choices:
            raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; expected one of {list(self.choices)}")
        if self.min is not None and value < self.min:
            raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; minimum is {self.min}")
        if self.max is not None and value > self.max:
            raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; maximum is {self.max}")
        return value


SYSTEM_LETTERS = "GRECJI"

SHARED = [
    Param("systems", "GRECJI", "GNSS systems simulated, RINEX letters: G GPS, R GLONASS, E Galileo, C BeiDou, "
          "J QZSS, I NavIC"),
    Param("start_time", "2025-06-01T10:00:00", "GNSS (GPS) time of the first epoch, ISO 8601; with "
          "time_mapping=offset the ROS time 0 maps to it"),
    Param("rate_hz", 1.0, "epoch rate [Hz]", min=0.001, max=100.0),
    Param("elevation_mask_deg", 10.0, "elevation mask [deg]: satellites below are neither cast nor tracked",
          min=-5.0, max=90.0),
    Param("world_frame", "world", "TF frame of the Gazebo world (ENU at spherical_coordinates)"),
    Param("antenna_frame", "gnss_antenna", "TF frame of the receiver antenna phase centre"),
    Param("seed", 1, "seed of every random process (noise, clock, ambiguities)", min=0),
    Param("output_dir", "gnss_sim_output", "folder of the RINEX observation/navigation (and NMEA) files; "
          "empty: none written"),
    Param("marker_name", "GSIM", "RINEX marker name (its first 4 characters start the file names)"),
    Param("preset", "balanced", "fidelity preset: default values of the model switches",
          choices=("fast", "balanced", "accurate")),
]

NODE_PARAMS: dict[str, list[Param]] = {
    "ephemeris": [
        Param("source", "synthetic", "where orbits come from", choices=("synthetic", "broadcast", "sp3", "download")),
        Param("nav_files", [], "RINEX 2/3/4 navigation files (source broadcast; gz/Z/crx accepted)",
              item_type="string"),
        Param("sp3_files", [], "SP3 precise orbit files (source sp3)", item_type="string"),
        Param("clk_files", [], "RINEX clock files to go with the SP3 files", item_type="string"),
        Param("download_cache_dir", "", "cache of downloaded navigation files (source download); "
              "empty: ~/.cache/gnss_sim"),
        Param("time_mapping", "offset", "ROS time -> GNSS time: offset (ROS time 0 = start_time; simulated "
              "clocks) or utc (ROS stamps are UNIX UTC)", choices=("offset", "utc")),
        Param("duration_s", 600.0, "simulated span [s] for which ephemerides are prepared", min=1.0),
    ],
    "visibility": [
        Param("world_file", "", "Gazebo SDF world (exported to a mesh on configure); empty: the demo courtyard"),
        Param("mesh_file", "", "mesh exported by `gnss-sim export-world` (overrides world_file)"),
        Param("materials_file", "", "YAML of material classes by name pattern"),
        Param("use_visuals", False, "export visual instead of collision geometry"),
        Param("fresnel_rays", -1, "rays over the first Fresnel zone per satellite (0 off; -1 from preset)", min=-1),
    ],
    "receiver": [
        Param("profile", "geodetic", "signals tracked", choices=("geodetic", "single_frequency")),
        Param("noise", True, "receiver errors on (noise, clock wander, SISRE, ionosphere error, hardware code biases); "
              "off: an ideal receiver with the deterministic models"),
        Param("ionosphere", "", "true ionosphere (empty: from preset; auto: NeQuick-G where Galileo coefficients "
              "are given, else Klobuchar)", choices=("", "auto", "nequick", "klobuchar", "none")),
        Param("troposphere", "", "troposphere model (empty: from preset)", choices=("", "saastamoinen", "none")),
        Param("write_nmea_file", False, "also write the NMEA sentences to output_dir/gnss_sim.nmea"),
        Param("cn0_acquire_dbhz", 33.0, "C/N0 above which a signal is acquired [dB-Hz]", min=0.0, max=70.0),
        Param("cn0_lose_dbhz", 28.0, "C/N0 below which a signal is lost [dB-Hz]", min=0.0, max=70.0),
    ],
    "trajectory": [
        Param("trajectory_file", "", "CSV t_s,e_m,n_m,u_m[,yaw_deg] in the world frame; empty: waypoints"),
        Param("waypoints", [], "flat list t_s,e_m,n_m,u_m,... (empty with no file: the demo path)",
              item_type="double"),
        Param("base_frame", "base_link", "robot frame the player moves"),
        Param("antenna_offset_m", [0.0, 0.0, 0.5], "antenna position in base_frame [m] (static TF)"),
        Param("publish_rate_hz", 20.0, "TF publish rate [Hz]", min=0.1, max=1000.0),
        Param("loop", False, "restart the path at its end"),
    ],
}


@dataclass
class Config:
    """Parameters of every node after defaults < shared (``/**``) < node sections."""

    values: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = "<defaults>"

    def node(self, key: str) -> dict[str, Any]:
        """Shared + own parameters of one node (``ephemeris``, ``visibility``, ``receiver``, ``trajectory``)."""
        return dict(self.values[key])

    def ros_parameter_file_dict(self) -> dict:
        """The same configuration as a ROS 2 parameter file dict (every value explicit)."""
        return {NODE_NAMES[k]: {"ros__parameters": v} for k, v in self.values.items()}


def params_of(key: str) -> list[Param]:
    return SHARED + NODE_PARAMS[key]


def defaults() -> Config:
    return Config({k: {p.name: p.default for p in params_of(k)} for k in NODE_PARAMS})


def _apply(target: dict, section: dict, specs: dict[str, Param], where: str):
    for name, value in (section or {}).items():
        if name not in specs:
            hint = difflib.get_close_matches(name, specs, n=1)
            extra = f" (did you mean '{hint[0]}'?)" if hint else ""
            raise ValueError(f"{where}: unknown parameter '{name}'{extra}")
        target[name] = specs[name].check(value, where)


def load_config(path: str | Path | None = None, overrides: dict[str, dict] | None = None) -> Config:
    """Read a gnss_sim parameter file (ROS 2 format); ``None`` gives the defaults.

    ``overrides``: {node key or "/**": {param: value}} applied last (command line options).
    Errors name the file, the section and the parameter.
    """
    cfg = defaults()
    if path is not None:
        path = Path(path)
        try:
            doc = yaml.safe_load(path.read_text()) or {}
        except FileNotFoundError:
            raise ValueError(f"configuration file {path} does not exist") from None
        except yaml.YAMLError as exc:
            raise ValueError(f"{path}: not valid YAML: {exc}") from None
        if not isinstance(doc, dict):
            raise ValueError(f"{path}: expected a mapping of node names to ros__parameters")
        known = {v: k for k, v in NODE_NAMES.items()}
        for section_name, body in doc.items():
            where = f"{path}: section '{section_name}'"
            if not isinstance(body, dict) or set(body) != {"ros__parameters"}:
                raise ValueError(f"{where}: expected 'ros__parameters:' under it")
            params = body["ros__parameters"] or {}
            name = section_name.lstrip("/")
            if section_name in (SHARED_KEY, "/**/"):
                for key in NODE_NAMES:
                    specs = {p.name: p for p in SHARED}
                    _apply(cfg.values[key], params, specs, where)
            elif name in known:
                key = known[name]
                _apply(cfg.values[key], params, {p.name: p for p in params_of(key)}, where)
            else:
                hint = difflib.get_close_matches(name, list(known), n=1)
                extra = f" (did you mean '{hint[0]}'?)" if hint else ""
                raise ValueError(f"{where}: unknown node{extra}; expected one of {sorted(known)} or '/**'")
        cfg.source = str(path)
    for section_name, params in (overrides or {}).items():
        keys = list(NODE_NAMES) if section_name == SHARED_KEY else [section_name]
        for key in keys:
            specs = {p.name: p for p in (SHARED if section_name == SHARED_KEY else params_of(key))}
            _apply(cfg.values[key], params, specs, "command line")
    return cfg


def default_config_yaml() -> str:
    """The documented default parameter file (``config/gnss_sim.yaml``)."""
    lines = [
        "# gnss_sim parameters: one file for `ros2 launch gnss_sim sim.launch.py config:=...`,",
        "# `gnss-sim run --config ...` and `gnss-sim simulate --config ...`.",
        "# Every parameter with its default; delete what you do not change.",
        "# Generated from gnss_sim_ros2/parameters.py (`gnss-sim config`): keep them equal.",
        "",
    ]

    def emit(section: str, params: list[Param]):
        lines.append(f"{section}:")
        lines.append("  ros__parameters:")
        for p in params:
            extra = f" [{'|'.join(map(str, p.choices))}]" if p.choices else ""
            lines.append(f"    # {p.description}{extra}")
            value = yaml.safe_dump(p.default, default_flow_style=True).strip()
            if value.endswith("\n..."):
                value = value[:-4].strip()
            value = value.removesuffix("...").strip()
            lines.append(f"    {p.name}: {value}")
        lines.append("")

    emit("/**", SHARED)
    for key, params in NODE_PARAMS.items():
        emit(NODE_NAMES[key], params)
    return "\n".join(lines)

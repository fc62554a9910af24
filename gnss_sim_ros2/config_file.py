"""Reading a gnss_sim parameter file (ROS 2 format) into a :class:`~gnss_sim_ros2.parameters.Config`.

One loader for every front end: ``gnss-sim simulate|run|sweep --config``, ``config --check`` and the launch
file's ``config:=``.  It sits above the parameter table (``parameters.py``) and the node graph
(``graph.py``, ``graph_params.py``) because a file a run wrote (``params.yaml``) holds the sections of the
nodes the graph derives (an RTK run's base station, the robots' ``/robot<k>/...``), which are checked against
what this configuration derives for them.
"""
from __future__ import annotations

import difflib
import re
from pathlib import Path
from typing import Any

from gnss_sim_ros2 import graph
from gnss_sim_ros2.graph_params import INSTANCE_NODE_NAMES, check_robots
from gnss_sim_ros2.parameters import (
    NODE_NAMES,
    SHARED,
    SHARED_KEY,
    SHARED_ONLY_NAMES,
    Config,
    apply_params,
    defaults,
    params_of,
    validate_node,
)


def load_config(path: str | Path | None = None, overrides: dict[str, dict] | None = None,
                options: dict[str, str] | None = None) -> Config:
    """Read a gnss_sim parameter file (ROS 2 format); ``None`` gives the defaults.

    ``overrides``: {node key or "/**": {param: value}} applied last (command line options);
    ``options``: {param: command-line option} so that an error names the option the user typed.
    A parameter shared by every node (``shared_only``) belongs under ``/**``; a node's section may repeat it
    (a ROS parameter file with one section per node, as ``gnss-sim run`` writes ``params.yaml``) when every
    node gets one value (its section's, else ``/**``'s, else the default), else the error names two sections
    that disagree.  The sections of the nodes a run derives (the RTK run's base station and moving baseline,
    the robots' ``/robot<k>/...``) are accepted when they hold what this configuration derives for them.
    Errors name the file, the section and the parameter (or the option).
    """
    cfg = defaults()
    shared_specs = {p.name: p for p in SHARED}
    repeated: dict[str, dict[str, Any]] = {}     # shared-only parameter -> {section: value} (node sections, /**)
    derived: dict[str, tuple[str, dict]] = {}    # section of a derived node -> (its where, its parameters)

    def own_specs(key):
        return {p.name: p for p in params_of(key) if p.name not in SHARED_ONLY_NAMES}

    if path is not None:
        import yaml  # only a run with a file reads YAML (start-up)

        from gnss_sim_ros2.core import yaml_file
        from gnss_sim_ros2.core.input_file import read_utf8

        path = Path(path)
        try:
            text = read_utf8(path, str(path))
        except FileNotFoundError:
            raise ValueError(f"configuration file {path} does not exist") from None
        except IsADirectoryError:
            raise ValueError(f"configuration file {path} is a folder, not a YAML file") from None
        doc = yaml_file.parse(text, yaml_file.unique_keys(yaml.SafeLoader), str(path)) or {}
        if not isinstance(doc, dict):
            raise ValueError(f"{path}: expected a mapping of node names to ros__parameters")
        known = {v: k for k, v in NODE_NAMES.items()}
        for section_name, body in doc.items():
            where = f"{path}: section '{section_name}'"
            if not isinstance(body, dict) or set(body) != {"ros__parameters"}:
                raise ValueError(f"{where}: expected 'ros__parameters:' under it")
            params = body["ros__parameters"] or {}
            if not isinstance(params, dict):
                raise ValueError(f"{where}: 'ros__parameters' must be a mapping of parameter names to values")
            for p_name in params:       # YAML reads yes / 5 / ~ as a bool, number, null: a TypeError in difflib
                if not isinstance(p_name, str):
                    raise ValueError(f"{where}: parameter name {p_name!r} is a {type(p_name).__name__}, not a name "
                                     f"(YAML reads yes, no, on, off, numbers and ~ as values: quote it)")
            name = str(section_name).lstrip("/")
            if section_name in (SHARED_KEY, "/**/"):
                for key in NODE_NAMES:
                    apply_params(cfg.values[key], params, shared_specs, where)
                for p_name in SHARED_ONLY_NAMES & set(params):
                    repeated.setdefault(p_name, {})[SHARED_KEY] = cfg.values["receiver"][p_name]
            elif name in known:
                key = known[name]
                for p_name in SHARED_ONLY_NAMES & set(params):
                    repeated.setdefault(p_name, {})[NODE_NAMES[key]] = shared_specs[p_name].check(params[p_name],
                                                                                                  where)
                apply_params(cfg.values[key], {n: v for n, v in params.items() if n not in SHARED_ONLY_NAMES},
                       own_specs(key), where)
            elif _derived_node_key(name) is not None:
                derived[name] = (where, params)
            else:
                hint = difflib.get_close_matches(name, list(known), n=1)
                extra = f" (did you mean '{hint[0]}'?)" if hint else ""
                raise ValueError(f"{where}: unknown node{extra}; expected one of {sorted(known)} or '/**'")
        _agree_shared(cfg, repeated, path)
        cfg.source = str(path)
        _forget_run_navigation(cfg)
        if derived:
            _check_derived(cfg, derived, path)
    for section_name, params in (overrides or {}).items():
        keys = list(NODE_NAMES) if section_name == SHARED_KEY else [section_name]
        for key in keys:
            specs = shared_specs if section_name == SHARED_KEY else own_specs(key)
            apply_params(cfg.values[key], params, specs, "command line", options)
    where = cfg.source if path is None else str(path)
    for key in NODE_NAMES:
        cfg.values[key] = validate_node(key, cfg.values[key], f"{where}: {NODE_NAMES[key]}", options)
    rx, vis = cfg.values["receiver"], cfg.values["visibility"]
    if rx["scenario"]:        # an event after the run's end: said, not silently dropped (a shortened run is legal)
        import logging

        from gnss_sim_ros2.core.threats.scenario import load_scenario

        dur = "option --duration" if options and options.get("duration_s") else "parameter 'duration_s'"
        scenario = load_scenario(rx["scenario"])
        for msg in [*scenario.never_active(cfg.values["ephemeris"]["duration_s"], dur),
                    *scenario.absent_satellites(rx["systems"])]:     # a fault on a system not simulated
            logging.getLogger(__name__).warning(msg)
    if rx["scenario"] and not rx["scenario_world"]:   # the receiver places the scenario in the visibility's scene
        rx["scenario_world"] = vis["mesh_file"] or vis["world_file"]
    return cfg


def _agree_shared(cfg: Config, repeated: dict[str, dict[str, Any]], path) -> None:
    """A shared-only parameter repeated in node sections: one value for every node (as rcl reads the file:
    the node's section, else ``/**``, else the default), set on every node; else an error naming two sources."""
    for p_name, by_section in repeated.items():
        if set(by_section) == {SHARED_KEY}:
            continue                                  # under /** only: applied to every node already
        spec = {p.name: p for p in SHARED}[p_name]
        fallback = ((f"section '{SHARED_KEY}'", by_section[SHARED_KEY]) if SHARED_KEY in by_section
                    else ("the default", spec.check(spec.default, f"{path}: parameter '{p_name}'")))
        got = [(f"section '{node}'", by_section[node]) if node in by_section else (f"{fallback[0]} for '{node}'",
                                                                                   fallback[1])
               for node in NODE_NAMES.values()]
        if SHARED_KEY in by_section:
            got.insert(0, fallback)
        # two sections of the file that disagree are named before a section and what another node falls back to
        got.sort(key=lambda g: not g[0].startswith("section"))
        first = got[0]
        other = next((g for g in got if g[1] != first[1]), None)
        if other is not None:
            raise ValueError(f"{path}: {first[0]}: parameter '{p_name}' is shared by every node (one value for the "
                             f"whole graph), but it gives {first[1]!r} and {other[0]} gives {other[1]!r}: set it once "
                             f"under '{SHARED_KEY}' (or give every node's section the same value)")
        for key in NODE_NAMES:
            cfg.values[key][p_name] = first[1]


def _forget_run_navigation(cfg: Config) -> None:
    """The rtk node's nav_files as a run derived them (the navigation file the run writes into output_dir,
    graph.node_parameters): derived again, from this configuration's output_dir, not read from the old run's."""
    nav = cfg.values["rtk"]["nav_files"]
    if len(nav) == 1 and str(nav[0]).endswith("_MN.rnx") and cfg.values["ephemeris"]["output_dir"]:
        try:
            if str(nav[0]) == str(graph.run_navigation_file(cfg)):
                cfg.values["rtk"]["nav_files"] = []
        except ValueError:
            pass                                      # a bad start_time etc.: validate_node names it below


_ROBOT_SECTION = re.compile(r"^(robot\d+)/(gnss_sim_\w+)$")


def _derived_node_key(name: str) -> str | None:
    """The node key of a derived node's section name (without a leading '/'), None for any other name."""
    inst = {v: k for k, v in INSTANCE_NODE_NAMES.items()}
    if name in inst:
        return inst[name][1]
    m = _ROBOT_SECTION.match(name)
    if m and m.group(2) in {NODE_NAMES[k] for k in ("trajectory", "visibility", "receiver")}:
        return next(k for k, v in NODE_NAMES.items() if v == m.group(2))
    return None


def _check_derived(cfg: Config, derived: dict[str, tuple[str, dict]], path) -> None:
    """Sections of derived nodes (a run's params.yaml): each parameter must be what the configuration derives
    (graph.node_parameters, as the run and the launch file give them), else an error names the section, the
    parameter and both values."""
    robots = max([int(_ROBOT_SECTION.match(n).group(1)[5:]) + 1 for n in derived if _ROBOT_SECTION.match(n)]
                 or [1])
    if robots > 1:
        check_robots(robots, f"{path}: the /robot<k>/ sections")
    specs = {s.path.lstrip("/"): s for s in graph.nodes(True, robots) if s.robot >= 0} if robots > 1 else {}
    for s in graph.RTK_NODES + graph.HEADING_NODES:
        specs[s.name] = s
    for name, (where, params) in derived.items():
        spec = specs.get(name)
        if spec is None:                               # /robot<k>/... of a robot beyond the count
            raise ValueError(f"{where}: no such node in a run of {robots} robot(s)")
        try:
            want = graph.node_parameters(cfg, spec, robots)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        specs_of = {p.name: p for p in params_of(_derived_node_key(name))}
        for p_name, value in params.items():
            if p_name not in specs_of:
                hint = difflib.get_close_matches(p_name, specs_of, n=1)
                raise ValueError(f"{where}: unknown parameter '{p_name}'"
                                 + (f" (did you mean '{hint[0]}'?)" if hint else ""))
            got = specs_of[p_name].check(value, where)
            if got != want[p_name]:
                raise ValueError(f"{where}: parameter '{p_name}' is {got!r}, but this node's parameters follow from "
                                 f"the other sections ({want[p_name]!r} here): change it there (a run writes these "
                                 f"sections to show what the node ran with)")

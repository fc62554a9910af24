"""Receiver profiles: what a receiver tracks and how (signals, antenna, front end, loops, thresholds, noise,
flags), as YAML files -- the four shipped in gnss_sim_ros2/profiles/ or a user's own (docs/PROFILES.md).

    prof = load_profile("ublox_f9p")           # a built-in name
    prof = load_profile("my_receiver.yaml")    # a file (relative: to the working directory)
    ReceiverConfig(profile="my_receiver.yaml") # its values become the configuration's defaults

Reading and validation: profile_file.py; this module binds them to ``ReceiverConfig`` and prints a profile
with every default filled in (``gnss-sim profile show``).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .config import ReceiverConfig
from .profile_file import (
    BUILTIN_DIR,
    RUN_FIELDS,
    SCHEMA_VERSION,
    ProfileError,
    ReceiverProfile,
    builtin_names,
    is_path,
    read,
)

__all__ = ["BUILTIN_DIR", "RUN_FIELDS", "SCHEMA_VERSION", "ProfileError", "ReceiverProfile", "builtin_names",
           "is_path", "load_profile", "filled_in", "profile_yaml"]


def load_profile(name_or_path: str | Path | Mapping) -> ReceiverProfile:
    """The validated profile of a built-in name, a .yaml/.yml file or a mapping; ProfileError (a ValueError)
    naming the file, the key path and the line otherwise."""
    return read(name_or_path, ReceiverConfig)


def filled_in(name_or_path: str | Path | Mapping) -> dict:
    """The profile as a plain document with every field a profile may set, the profile's value where it has one,
    else the receiver's built-in default (what a run with it uses, noise on)."""
    prof = load_profile(name_or_path)
    cfg = ReceiverConfig(profile=name_or_path if not isinstance(name_or_path, Path) else str(name_or_path))
    doc = {"gnss_sim_profile": SCHEMA_VERSION, "name": prof.name, "description": prof.description,
           "source": prof.source, "signals": prof.signal_map()}
    for f in dataclasses.fields(ReceiverConfig):
        if f.name in RUN_FIELDS or not f.init:
            continue
        doc[f.name] = _plain(getattr(cfg, f.name))
    return doc


def profile_yaml(name_or_path: str | Path | Mapping) -> str:
    """:func:`filled_in` as YAML text (a starting point for a user's own profile)."""
    import yaml

    class Dumper(yaml.SafeDumper):
        pass

    def short_list(dumper, data):        # lists of scalars on one line, as the shipped files write them
        flow = all(not isinstance(v, (dict, list)) for v in data)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)

    Dumper.add_representer(list, short_list)
    return yaml.dump(filled_in(name_or_path), Dumper=Dumper, sort_keys=False, width=110)


def _plain(value):
    """A configuration value as YAML-safe data (dataclasses as mappings, arrays as lists, numpy scalars as
    Python numbers)."""
    if dataclasses.is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value) if f.init}
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value

"""Receiver profile files: a YAML document (schema version 1, docs/PROFILES.md) read and checked against the
fields of the dataclass that takes it (``ReceiverConfig``, passed in as ``owner``: this module does not import it,
so that config.py can use it).

Every top-level key other than ``gnss_sim_profile``, ``name``, ``description``, ``source`` and ``signals`` is a field
of ``owner`` that a profile may own (every field but :data:`RUN_FIELDS`); a field whose type is a dataclass
(``tracking``, ``link_budget``) is a mapping of that dataclass's fields.  The allowed keys and their types come from
the dataclasses themselves (``dataclasses.fields``, ``typing.get_type_hints``), so a new field is accepted
without editing this module; a field's ``metadata["check"]`` (a callable value -> value, raising ValueError)
checks its value further.  An error names the file, the key path (``tracking.start``) and the line.
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import functools
import math
import re
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import signals as sig

#: the schema version this reader knows (key ``gnss_sim_profile``)
SCHEMA_VERSION = 1
#: the profiles shipped with the package: <name>.yaml (setup.py package_data)
BUILTIN_DIR = Path(__file__).resolve().parents[2] / "profiles"
#: fields of the receiver configuration that belong to the run (parameters, options), never to a profile
RUN_FIELDS = frozenset({"profile", "systems", "elevation_mask_deg", "noise", "ionosphere", "troposphere",
                        "transmit_time", "light_time_iterations", "seed", "world_seed", "sisre_m",
                        "iono_error_frac", "clock", "lms_environment",
                        "spoof_capture_margin_db"})
#: the top-level keys that describe the profile rather than set a field
META_KEYS = ("gnss_sim_profile", "name", "description", "source", "signals")
PROFILE_SUFFIXES = (".yaml", ".yml")


class ProfileError(ValueError):
    """A profile that cannot be used: the message names the file (or mapping), the key path and the line."""


@dataclass(frozen=True)
class ReceiverProfile:
    """A validated profile.  ``fields``: owner field -> value (a dataclass-typed field as {its field: value});
    ``path``: the file it was read from ("" for a mapping)."""

    name: str
    description: str
    source: str
    path: str
    signals: Mapping[str, tuple[str, ...]]
    fields: Mapping[str, Any]

    def signal_map(self) -> dict[str, list[str]]:
        """system -> RINEX codes tracked (a copy)."""
        return {s: list(codes) for s, codes in self.signals.items()}

    def value(self, name: str, default=None):
        """A copy of field ``name``'s value, ``default`` where the profile does not set it (or sets null)."""
        return copy.deepcopy(self.fields[name]) if self.fields.get(name) is not None else default


def builtin_names() -> tuple[str, ...]:
    """Names of the shipped profiles (the stems of BUILTIN_DIR/*.yaml)."""
    return tuple(sorted(p.stem for p in BUILTIN_DIR.glob("*.yaml")))


def option_help() -> str:
    """The help of a command's --profile option (simulate, run)."""
    return (f"receiver profile (signals, antenna, front end, loops, thresholds, noise): a built-in name "
            f"({', '.join(builtin_names())}) or a profile YAML file, relative to the working directory "
            f"(docs/PROFILES.md; `gnss-sim profile show NAME` prints one to start from) [from config]")


def is_path(value: str) -> bool:
    """A profile given as a file (a .yaml/.yml name or a path with a folder) rather than a built-in name."""
    return str(value).lower().endswith(PROFILE_SUFFIXES) or "/" in str(value) or "\\" in str(value)


def resolve(name_or_path: str | Path) -> Path:
    """The file of a built-in name or of a path (relative: to the working directory); ProfileError if none."""
    s = str(name_or_path)
    if not s:
        raise ProfileError(f"receiver profile '': give a built-in name ({', '.join(builtin_names())}) or a "
                           f".yaml file")
    if not is_path(s):
        p = BUILTIN_DIR / f"{s}.yaml"
        if not p.is_file():
            hint = difflib.get_close_matches(s, builtin_names(), n=1)
            extra = f" (did you mean '{hint[0]}'?)" if hint else ""
            raise ProfileError(f"receiver profile {s!r} is not a built-in one{extra}: "
                               f"{', '.join(builtin_names())}, or a .yaml file")
        return p
    p = Path(s).expanduser()
    if not p.exists():
        raise ProfileError(f"receiver profile file {p} does not exist")
    if not p.is_file():
        raise ProfileError(f"receiver profile file {p} is not a file")
    return p.resolve()


def read(source: str | Path | Mapping, owner: type) -> ReceiverProfile:
    """The validated profile of a built-in name, a YAML file or a mapping (a profile document, or a bare
    {system: [codes]} signal mapping), checked against dataclass ``owner``'s fields."""
    if isinstance(source, Mapping):
        doc = dict(source)
        if "signals" not in doc and "gnss_sim_profile" not in doc:     # a bare signal mapping
            doc = {"gnss_sim_profile": SCHEMA_VERSION, "signals": doc}
        return _validate(doc, None, "receiver profile mapping", "custom", "", owner)
    path = resolve(source)
    st = path.stat()
    return _read_file(str(path), st.st_mtime_ns, st.st_size, owner)


@functools.lru_cache(maxsize=32)
def _read_file(path: str, _mtime_ns: int, _size: int, owner: type) -> ReceiverProfile:
    where = f"receiver profile {path}"
    doc, node = read_yaml(path, where, _loader(), ProfileError, lazy_nodes=True)
    return _validate(doc, node, where, Path(path).stem, path, owner)


def read_yaml(path, where: str, loader, error: type[ValueError], lazy_nodes: bool = False):
    """(document, node tree with line marks) of a YAML file read with ``loader``; ``error`` (a ValueError
    subclass) naming ``where`` when the file cannot be read or is not YAML (profiles, scenario files).
    ``lazy_nodes``: instead of the node tree, a function composing it (the text parsed a second time only when
    an error names a line)."""
    from gnss_sim_ros2.core.yaml_file import parse

    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{where}: cannot be read: {exc}") from None
    if lazy_nodes:
        return parse(text, loader, where, error), lambda: parse(text, loader, where, error, with_nodes=True)[1]
    return parse(text, loader, where, error, with_nodes=True)


@functools.lru_cache(maxsize=1)
def _loader():
    """PyYAML's safe loader reading floats as YAML 1.2 does: 16.0e6 and 1e-3 are numbers (YAML 1.1, which
    PyYAML follows, reads an exponent without a sign as text); a key given twice is refused (core/yaml_file.py).
    On libyaml's parser where PyYAML has it (CSafeLoader: the same documents, 3 ms -> 0.3 ms for a profile)."""
    import yaml

    from gnss_sim_ros2.core.yaml_file import unique_keys

    class Loader(unique_keys(getattr(yaml, "CSafeLoader", yaml.SafeLoader))):
        pass

    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"), list("-+0123456789."))
    return Loader


def _line(node, keys: tuple) -> int | None:
    """1-based line of the key path ``keys`` (str keys, int list indices) in a composed YAML node."""
    import yaml

    line = None
    for key in keys:
        if isinstance(node, yaml.MappingNode):
            for k_node, v_node in node.value:
                if k_node.value == str(key):
                    line, node = k_node.start_mark.line + 1, v_node
                    break
            else:
                return line
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
            line = node.start_mark.line + 1
        else:
            return line
    return line


def _path_text(keys: tuple) -> str:
    out = ""
    for k in keys:
        out += f"[{k}]" if isinstance(k, int) else (f".{k}" if out else str(k))
    return out


def _validate(doc, node, where: str, stem: str, path: str, owner: type) -> ReceiverProfile:
    # node: the document's node tree (the lines of the keys an error names), a function composing it, or None
    def fail(keys: tuple, msg: str):
        line = _line(node() if callable(node) else node, keys) if node is not None and keys else None
        at = f", line {line}" if line else ""
        key = f": key '{_path_text(keys)}'" if keys else ""
        raise ProfileError(f"{where}{at}{key}: {msg}")

    if not isinstance(doc, dict):
        fail((), f"expected a mapping of profile keys (gnss_sim_profile, signals, ...), got {type(doc).__name__}")
    version = doc.get("gnss_sim_profile")
    if version is None:
        fail((), f"'gnss_sim_profile: {SCHEMA_VERSION}' (the schema version) is missing")
    if version != SCHEMA_VERSION or isinstance(version, bool):
        fail(("gnss_sim_profile",), f"schema version {version!r}; this gnss_sim reads version {SCHEMA_VERSION}")
    meta = {}
    for key in ("name", "description", "source"):
        value = doc.get(key, stem if key == "name" else "")
        if not isinstance(value, str):
            fail((key,), f"must be text, got {value!r}")
        meta[key] = value.strip()
    if "signals" not in doc:
        fail((), "'signals' (system -> RINEX codes tracked) is missing")
    signals = _signals(doc["signals"], fail)
    specs = _field_specs(owner)
    fields = {}
    for key, value in doc.items():
        if key in META_KEYS:
            continue
        if key in RUN_FIELDS:
            fail((key,), "belongs to the run (a parameter or command-line option), not to a receiver profile")
        if key not in specs:
            hint = difflib.get_close_matches(str(key), list(specs) + list(META_KEYS), n=1)
            extra = f" (did you mean '{hint[0]}'?)" if hint else ""
            fail((key,), f"unknown key{extra}; a profile takes {', '.join(META_KEYS)} and the receiver fields "
                         f"{', '.join(sorted(specs))}")
        fields[key] = _check(value, specs[key], (key,), fail)
    return ReceiverProfile(name=meta["name"], description=meta["description"], source=meta["source"], path=path,
                           signals=signals, fields=fields)


def _signals(value, fail) -> dict[str, tuple[str, ...]]:
    if not isinstance(value, dict) or not value:
        fail(("signals",), f"must map system letters to lists of RINEX codes, e.g. {{G: [1C, 2W]}}, got {value!r}")
    out = {}
    for sys_, codes in value.items():
        if sys_ not in sig.SYSTEMS:
            fail(("signals", sys_), f"{sys_!r} is not a system letter ({', '.join(sig.SYSTEMS)})")
        if not isinstance(codes, list) or not codes:
            fail(("signals", sys_), f"must be a non-empty list of RINEX codes, got {codes!r}")
        for j, code in enumerate(codes):
            try:
                if not isinstance(code, str):
                    raise ValueError(f"{code!r} is not a RINEX code (text such as 1C)")
                sig.signal(sys_, code)
            except ValueError as exc:
                fail(("signals", sys_, j), str(exc))
        if len(set(codes)) != len(codes):
            fail(("signals", sys_), f"lists a code twice: {codes}")
        out[sys_] = tuple(codes)
    return out


@dataclass(frozen=True)
class _Spec:
    type_: Any
    check: Any = None
    #: the annotation admits None (``float | None``): null is a value (for a receiver field: the built-in one)
    optional: bool = False


@functools.lru_cache(maxsize=8)
def _field_specs(owner: type) -> dict[str, _Spec]:
    """The fields of ``owner`` a profile may set: name -> (type without None, metadata check)."""
    hints = typing.get_type_hints(owner)
    return {f.name: _spec(hints[f.name], f) for f in dataclasses.fields(owner) if f.name not in RUN_FIELDS and f.init}


def _spec(hint, f: dataclasses.Field) -> _Spec:
    return _Spec(_strip_none(hint), f.metadata.get("check"), type(None) in typing.get_args(hint))


def _strip_none(t):
    args = typing.get_args(t)
    if typing.get_origin(t) in (typing.Union, types.UnionType):
        rest = tuple(a for a in args if a is not type(None))
        return rest[0] if len(rest) == 1 else rest
    return t


_KIND = {float: "a number", int: "an integer", bool: "true or false", str: "text", dict: "a mapping",
         list: "a list", np.ndarray: "a list of numbers"}


def _check(value, spec: _Spec, keys: tuple, fail):
    """``value`` converted to the field's type (numbers to float, lists to arrays, a mapping to its dataclass's
    fields) and passed through its metadata check; ``fail(keys, msg)`` otherwise."""
    t = spec.type_
    if value is None and spec.optional:
        return None
    if dataclasses.is_dataclass(t):
        if not isinstance(value, dict):
            fail(keys, f"must be a mapping of {t.__name__} fields, got {value!r}")
        hints = typing.get_type_hints(t)
        sub = {f.name: _spec(hints[f.name], f) for f in dataclasses.fields(t) if f.init}
        out = {}
        for k, v in value.items():
            if k not in sub:
                hint = difflib.get_close_matches(str(k), list(sub), n=1)
                extra = f" (did you mean '{hint[0]}'?)" if hint else ""
                fail((*keys, k), f"unknown key{extra}; {t.__name__} takes {', '.join(sub)}")
            out[k] = _check(v, sub[k], (*keys, k), fail)
        try:
            t(**out)                   # the dataclass's own checks (e.g. thresholds in order)
        except (ValueError, TypeError) as exc:
            fail(keys, str(exc))
        return out
    value = _convert(value, t, keys, fail)
    if spec.check is not None:
        try:
            value = spec.check(value)
        except ValueError as exc:
            fail(keys, str(exc))
    return value


def _convert(value, t, keys, fail):
    if isinstance(t, tuple):                       # a union: the first type that takes the value
        for one in t:
            try:
                return _convert(value, one, keys, _raise)
            except ProfileError:
                continue
        fail(keys, f"{value!r} is none of {', '.join(_KIND.get(o, getattr(o, '__name__', str(o))) for o in t)}")
    base = typing.get_origin(t) or t
    if base is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            fail(keys, f"must be a finite number, got {value!r}")
        return float(value)
    if base is int:
        if isinstance(value, bool) or not isinstance(value, int):
            fail(keys, f"must be an integer, got {value!r}")
        return value
    if base in (bool, str, dict, list):
        if not isinstance(value, base) or (base is not bool and isinstance(value, bool)):
            fail(keys, f"must be {_KIND[base]}, got {value!r}")
        return value
    if base is np.ndarray:
        if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                  for v in value):
            fail(keys, f"must be {_KIND[np.ndarray]}, got {value!r}")
        return np.array(value, dtype=np.float64)
    return value                                   # a type this reader does not know: the owner checks it


def _raise(keys, msg):
    raise ProfileError(msg)

"""Filled samples of every gnss_sim_msgs type, and a field-by-field dict view.

Used by ``gnss-sim roundtrip`` and its test: every field gets a distinct,
non-default value (derived from its path in the message), so a field lost or
mangled in transport shows up in the comparison.
"""
from __future__ import annotations

import importlib
import zlib

MESSAGE_TYPES = (
    "SatelliteState",
    "SatelliteStates",
    "ReflectedPath",
    "SatelliteVisibility",
    "Visibility",
    "SignalObservation",
    "Observations",
    "ReceiverStatus",
)

_INT_RANGES = {
    "int8": (-128, 127), "uint8": (0, 255), "int16": (-32768, 32767), "uint16": (0, 65535),
    "int32": (-(2**31), 2**31 - 1), "uint32": (0, 2**32 - 1), "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1), "byte": (0, 255), "char": (0, 255), "octet": (0, 255),
}


def message_class(name: str):
    """``gnss_sim_msgs.msg.<name>``."""
    return getattr(importlib.import_module("gnss_sim_msgs.msg"), name)


def _seed(path: str) -> int:
    return zlib.crc32(path.encode())


def _value_for(ftype: str, path: str):
    s = _seed(path)
    if ftype in ("double", "float64"):
        return (s % 100000) / 7.0 + 0.125
    if ftype in ("float", "float32"):
        return float((s % 1000) + 0.5)
    if ftype == "boolean":
        return True
    if ftype == "string":
        return f"v{s % 9973}"
    if ftype in _INT_RANGES:
        lo, hi = _INT_RANGES[ftype]
        return lo + 1 + s % min(hi - lo - 1, 200)
    return None


def fill(msg, path: str = ""):
    """Fill every field of ``msg`` (recursively) with distinct non-default values."""
    for field, ftype in msg.get_fields_and_field_types().items():
        fpath = f"{path}.{field}"
        if ftype.startswith("sequence<"):
            inner = ftype[len("sequence<"):-1].split(",")[0]
            items = [_make(msg, field, inner, f"{fpath}[{i}]") for i in range(2)]
            setattr(msg, field, items)
        else:
            value = _value_for(ftype, fpath)
            if value is None:
                fill(getattr(msg, field), fpath)
            else:
                setattr(msg, field, value)
    return msg


def _make(msg, field, inner, path):
    value = _value_for(inner, path)
    if value is not None:
        return value
    pkg, _, name = inner.partition("/")
    cls = getattr(importlib.import_module(f"{pkg}.msg"), name)
    return fill(cls(), path)


def to_dict(msg):
    """Plain nested dict/list view of a message (for comparison and JSON)."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {f: to_dict(getattr(msg, f)) for f in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)) or type(msg).__name__ == "array":
        return [to_dict(v) for v in msg]
    return msg


def sample(name: str):
    """A filled instance of ``gnss_sim_msgs.msg.<name>``."""
    return fill(message_class(name)(), name)

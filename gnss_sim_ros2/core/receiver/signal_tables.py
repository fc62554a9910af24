"""Per-signal tables against elevation that a receiver profile gives (issue 26): ``link_budget.cn0_table_dbhz``
(mean open-sky C/N0 as the receiver reports it, receiver/cn0.py) and ``code_multipath_m`` (sigma of the code
multipath/residual without the DLL thermal noise, receiver/code_multipath.py).

    {"G1C": {"el_deg": [5, 15, 25, ...], "cn0_dbhz": [38.0, 44.1, ...]}, ...}

Keys: RINEX system letter + band/attribute code ("G1C", "E5Q", "C2I"); el_deg strictly increasing in
[0, 90]; values finite (and >= 0 where asked); linear interpolation, held constant beyond the ends.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .. import signals as sig


def validate(table, field: str, value_name: str, nonnegative: bool = False) -> dict:
    """``table`` checked and normalised ({key: (el_deg array, value array)}); ValueError naming ``field`` and the
    key otherwise."""
    if table is None:
        return {}
    if not isinstance(table, Mapping):
        raise ValueError(f"receiver: parameter '{field}' must be a mapping of signal keys (e.g. 'G1C') to "
                         f"{{el_deg: [...], {value_name}: [...]}}, not {type(table).__name__}")
    out = {}
    for key, row in table.items():
        where = f"receiver: parameter '{field}' key {key!r}"
        if not (isinstance(key, str) and len(key) == 3):
            raise ValueError(f"{where}: a signal key is a system letter and a RINEX code, e.g. 'G1C'")
        try:
            sig.signal(key[0], key[1:])
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        if not isinstance(row, Mapping) or set(row) != {"el_deg", value_name}:
            raise ValueError(f"{where}: must hold exactly 'el_deg' and '{value_name}' lists")
        try:
            el = np.asarray(row["el_deg"], dtype=np.float64)
            v = np.asarray(row[value_name], dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{where}: 'el_deg' and '{value_name}' must be lists of numbers") from None
        if el.ndim != 1 or v.shape != el.shape or el.size == 0:
            raise ValueError(f"{where}: 'el_deg' and '{value_name}' must be non-empty lists of the same length")
        if not (np.all(np.isfinite(el)) and np.all(np.isfinite(v))):
            raise ValueError(f"{where}: values must be finite")
        if np.any(el < 0) or np.any(el > 90) or np.any(np.diff(el) <= 0):
            raise ValueError(f"{where}: 'el_deg' must increase strictly within [0, 90]")
        if nonnegative and np.any(v < 0):
            raise ValueError(f"{where}: '{value_name}' must be >= 0")
        out[key] = (el, v)
    return out


def lookup(table: dict, keys, el_deg) -> np.ndarray:
    """Values of a :func:`validate`-d table for signal keys ``keys`` (array of "G1C") at ``el_deg`` (same shape);
    NaN for signals the table does not hold."""
    keys = np.asarray(keys)
    el = np.asarray(el_deg, dtype=np.float64)
    out = np.full(np.broadcast(keys, el).shape, np.nan)
    if not table or out.size == 0:
        return out
    keys, el = np.broadcast_arrays(keys, el)
    for key in set(np.unique(keys).tolist()) & set(table):
        m = keys == key
        e, v = table[key]
        out[m] = np.interp(el[m], e, v)
    return out


def signal_keys(systems, codes) -> np.ndarray:
    """Signal keys ("G1C") of arrays of system letters and codes."""
    return np.char.add(np.asarray(systems, dtype="<U1"), np.asarray(codes, dtype="<U2"))

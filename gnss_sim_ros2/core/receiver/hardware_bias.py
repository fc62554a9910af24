"""Receiver hardware code biases: the delay each signal path adds to the pseudorange.

A real receiver's code measurements carry a hardware delay per constellation
and signal (antenna, front end, correlator), relative to the signal that
defines its clock (here GPS L1 C/A).  Only differences matter to a user:

- between constellations (inter-system bias, ISB), which a multi-system
  solution estimates as one extra unknown per system;
- between BeiDou-2 and BeiDou-3 on the same B1I/B3I signals.  This bias is
  receiver dependent, within about 10 ns on the overlapping frequencies
  (Accounting for BDS-2/BDS-3 inter-system biases in PPP and RTK models;
  Remote Sens. 15(24):5659, 2023: "clear dependence on the receiver",
  notably Trimble NetR9; Montenbruck et al., NAVIGATION 69(3) navi.526, 2022:
  receiver-dependent "inconsistencies at the few-nanosecond level between
  BeiDou-2 and BeiDou-3"), and software that treats BeiDou as one system
  (RTKLIB 2.4.3, most receivers' own solutions) cannot absorb it: it becomes
  a position error in the direction of the BeiDou-2 satellites;
- between the frequencies of one system (receiver differential code biases):
  the table format allows them, the shipped profiles leave them out.

Phase biases are not modelled (a float or integer ambiguity absorbs them
between receivers of one type); GLONASS inter-frequency biases are not
modelled (no GLONASS data to calibrate them).

Tables (a receiver profile's ``code_bias_m``, gnss_sim_ros2/profiles/*.yaml, with their sources): group ->
{code or band -> bias [m]}.  A group is a system letter, or
"C2"/"C3" for BeiDou-2 (PRN 1-18) and BeiDou-3 (PRN >= 19); a key is a RINEX
code ("2W"), a band digit ("2", every code of that band) or "*" (every
other code of the group).  A signal without an entry has no bias.
"""
from __future__ import annotations

import numpy as np

#: last BeiDou-2 PRN (BDS-2: C01-C18; BDS-3: C19 and above, CSNO BDS-OS-PS 3.0 (2021) table 3-1)
BDS2_LAST_PRN = 18


def group_of(sv: str) -> str:
    """Bias group of a satellite id: its system letter, or "C2"/"C3" for BeiDou-2/-3."""
    if sv[0] == "C":
        return "C2" if int(sv[1:]) <= BDS2_LAST_PRN else "C3"
    return sv[0]


def validate(table: dict, name: str = "code_bias_m") -> dict[str, dict[str, float]]:
    """A copy of ``table`` with float values; ValueError naming the parameter and the bad entry."""
    if not isinstance(table, dict):
        raise ValueError(f"receiver: parameter '{name}' must be a mapping group -> {{code: metres}}, "
                         f"not {type(table).__name__}")
    out = {}
    for group, codes in table.items():
        if group not in ("G", "R", "E", "C", "C2", "C3", "J", "I") or not isinstance(codes, dict):
            raise ValueError(f"receiver: parameter '{name}': group {group!r} must be a system letter or C2/C3 "
                             f"mapped to {{code: metres}}")
        out[group] = {}
        for key, v in codes.items():
            key = str(key)
            ok_key = key == "*" or (len(key) in (1, 2) and key[0].isdigit())
            try:
                val = float(v)
            except (TypeError, ValueError):
                val = float("nan")
            if not ok_key or not np.isfinite(val):
                raise ValueError(f"receiver: parameter '{name}': entry {group}/{key} = {v!r} (a RINEX code like "
                                 f"'2W', a band digit or '*', mapped to a finite number of metres)")
            out[group][key] = val
    return out


def code_bias_m(table: dict, svs, codes) -> np.ndarray:
    """Bias [m] of each signal row (``svs[j]``, ``codes[j]``): exact code, then band, then "*", then the
    system letter's entries for BeiDou (a "C" group applies to both generations); 0 without an entry."""
    out = np.zeros(len(codes))
    for j, (sv, code) in enumerate(zip(svs, codes)):
        for group in (group_of(str(sv)), str(sv)[0]):
            entry = table.get(group)
            if entry is None:
                continue
            code = str(code)
            val = entry.get(code, entry.get(code[0], entry.get("*")))
            if val is not None:
                out[j] = val
                break
    return out

"""Consecutive broadcast records of one satellite checked against each other.

IGS merged broadcast files occasionally hold a record (flagged healthy) whose orbit is thousands of
kilometres from the satellite's other records: a mislabelled or corrupted upload.  Each record is
compared with up to ``NEIGHBOURS`` records of the same satellite and message type on each side whose
reference times are at most ``MAX_SEPARATION_S`` apart: both are evaluated at the midpoint of their
reference times (Keplerian records with the ICD algorithm, GLONASS records integrated) and agree when
the positions are within ``AGREE_M``.  A record that agrees with none of the records it was compared
with, while one of those agrees with another, is an outlier: dropped with a warning (file:line),
whatever its health flag says.  Two records that disagree with no third to decide are both kept, with
a warning.

Scale: consecutive healthy records of a satellite agree to metres (GPS/Galileo/BeiDou: the broadcast
fit error is 1-10 m at 2 h from toe; GLONASS: tens of metres at 15-30 min from tb).
"""
from __future__ import annotations

import numpy as np

from ..rinex.nav import KEPLER_SYSTEMS, NavData, SystemTable, epoch_key
from . import glonass as glo
from .kepler import KeplerParams

#: records compared when their reference times are at most this far apart [s]
MAX_SEPARATION_S = {"R": 3600.0, "default": 4 * 3600.0}
#: two records agree when their positions at the midpoint are closer than this [m]
AGREE_M = 1000.0
#: records compared on each side
NEIGHBOURS = 2


def _pairs(rec: np.ndarray, max_sep_s: float) -> list[tuple[int, int]]:
    """(i, j) record index pairs of one satellite and message type to compare."""
    out = []
    keys = np.char.add(rec["sv"].astype("U3"), rec["nav"].astype("U8"))
    for key in np.unique(keys):
        idx = np.flatnonzero(keys == key)
        idx = idx[np.argsort(rec["toe_sec"][idx], kind="stable")]
        for a in range(len(idx)):
            for b in range(a + 1, min(a + 1 + NEIGHBOURS, len(idx))):
                i, j = int(idx[a]), int(idx[b])
                if 0 < rec["toe_sec"][j] - rec["toe_sec"][i] <= max_sep_s:
                    out.append((i, j))
    return out


def _distances_m(system: str, rec: np.ndarray, pairs: list[tuple[int, int]]) -> np.ndarray:
    """Distance between the two records' positions at the midpoint of their reference times [m]."""
    i = np.array([p[0] for p in pairs], dtype=np.int64)
    j = np.array([p[1] for p in pairs], dtype=np.int64)
    t_mid = (rec["toe_sec"][i] + rec["toe_sec"][j]) // 2
    if system == "R":
        p = []
        for k in (i, j):
            dt = (t_mid - rec["toe_sec"][k]).astype(np.float64) - rec["toe_frac"][k]
            p.append(glo.integrate(rec["pos_m"][k], rec["vel_mps"][k], rec["acc_mps2"][k], dt)[0])
        return np.linalg.norm(p[0] - p[1], axis=1)
    kp = KeplerParams(rec)
    zero = np.zeros(len(i))
    pa = kp.evaluate(i, t_mid, zero, acceleration=False)["pos_ecef_m"]
    pb = kp.evaluate(j, t_mid, zero, acceleration=False)["pos_ecef_m"]
    return np.linalg.norm(np.asarray(pa) - np.asarray(pb), axis=-1)


def outliers(tab: SystemTable) -> tuple[dict[int, str], list[str]]:
    """({record index: reason} of the outliers, [undecided disagreements]) of one system's table."""
    rec = tab.rec
    max_sep = MAX_SEPARATION_S.get(tab.system, MAX_SEPARATION_S["default"])
    pairs = _pairs(rec, max_sep)
    if not pairs:
        return {}, []
    d = _distances_m(tab.system, rec, pairs)
    agree = {k: 0 for p in pairs for k in p}
    worst: dict[int, tuple[float, int]] = {}
    for (i, j), dist in zip(pairs, d.tolist()):
        ok = np.isfinite(dist) and dist <= AGREE_M
        for a, b in ((i, j), (j, i)):
            agree[a] += ok
            if not ok and dist >= worst.get(a, (-1.0, -1))[0]:
                worst[a] = (dist if np.isfinite(dist) else np.inf, b)
    partners: dict[int, list[int]] = {}
    for i, j in pairs:
        partners.setdefault(i, []).append(j)
        partners.setdefault(j, []).append(i)
    out, undecided = {}, []
    for k, n_ok in agree.items():
        if n_ok:
            continue
        dist, other = worst[k]
        if any(agree[p] for p in partners[k]):
            out[k] = (f"its orbit is {dist / 1000.0:.1f} km from the satellite's record of "
                      f"{str(tab.epoch[other]).replace('T', ' ')} (and from every neighbouring record)")
        elif k < other:
            undecided.append(f"{rec['sv'][k]} records {str(tab.epoch[k]).replace('T', ' ')} and "
                             f"{str(tab.epoch[other]).replace('T', ' ')} are {dist / 1000.0:.1f} km apart "
                             "(no third record to tell which is wrong; both kept)")
    return out, undecided


def drop_outliers(nav: NavData) -> NavData:
    """Remove the outlier records of every system of ``nav`` (in place), one warning (nav.drop) each."""
    import warnings

    from ..rinex.nav import NavDataWarning

    for s, tab in list(nav.tables.items()):
        if s not in KEPLER_SYSTEMS and s != "R":
            continue
        bad, undecided = outliers(tab)
        for k, reason in sorted(bad.items()):
            sv, nav_type = str(tab.rec["sv"][k]), str(tab.rec["nav"][k])
            where = nav.origin.get((sv, nav_type, epoch_key(tab.epoch[k])), ", ".join(nav.paths))
            nav.drop(where, sv, tab.epoch[k], reason)
        for msg in undecided:
            nav.notes.append(msg)
            warnings.warn(f"{', '.join(nav.paths)}: {msg}", NavDataWarning, stacklevel=2)
        if bad:
            keep = np.ones(len(tab), dtype=bool)
            keep[list(bad)] = False
            nav.tables[s] = tab.take(np.flatnonzero(keep))
    return nav

"""What reading navigation files gives: per-system record tables (``SystemTable``, rows of
``KEPLER_DTYPE`` or ``GLONASS_DTYPE``) gathered in ``NavData`` with the header's coefficients and what was
skipped, corrected or dropped."""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ...time import GnssTime


class NavDataWarning(UserWarning):
    """A navigation record dropped or a file's content corrected (the message names file and line)."""


#: systems whose broadcast ephemerides are Keplerian elements
KEPLER_SYSTEMS = "GECJI"


#: systems read by this module (SBAS records are skipped)
SUPPORTED_SYSTEMS = "GRECJI"


#: Keplerian record table (one row per broadcast record)
KEPLER_DTYPE = np.dtype([
    ("sv", "U3"), ("sys", "U1"), ("nav", "U4"),
    ("toc_sec", "i8"), ("toc_frac", "f8"), ("toe_sec", "i8"), ("toe_frac", "f8"),
    ("toe_tow_s", "f8"),      # toe as broadcast: seconds of the system's week (BDT for BeiDou)
    ("week", "i8"),           # continuous week of toe: GPS week (G, J, E, I as RINEX), BDT week (C)
    ("sqrt_a", "f8"), ("e", "f8"), ("i0", "f8"), ("omega0", "f8"), ("omega", "f8"), ("m0", "f8"),
    ("delta_n", "f8"), ("idot", "f8"), ("omega_dot", "f8"),
    ("cuc", "f8"), ("cus", "f8"), ("crc", "f8"), ("crs", "f8"), ("cic", "f8"), ("cis", "f8"),
    ("af0", "f8"), ("af1", "f8"), ("af2", "f8"),
    # group delay of the first frequency for this record's clock: GPS/QZSS TGD, Galileo I/NAV BGD(E1,E5b),
    # F/NAV BGD(E1,E5a), BeiDou TGD1 (B1I, clock refers to B3I), NavIC TGD
    ("tgd_s", "f8"),
    ("tgd2_s", "f8"),         # Galileo: the other BGD; BeiDou TGD2; 0 otherwise
    ("bgd_e1e5a_s", "f8"), ("bgd_e1e5b_s", "f8"),
    ("health", "i8"), ("iode", "i8"), ("iodc", "i8"),
    ("fit_h", "f8"),          # fit interval [h] resolved from the flag/hours field (G, J); NaN otherwise
    ("data_src", "i8"),       # Galileo data source bits (RINEX 3.04 A8); 0 otherwise
    ("ura", "f8"), ("tot_s", "f8"),
])


#: GLONASS record table
GLONASS_DTYPE = np.dtype([
    ("sv", "U3"), ("sys", "U1"), ("nav", "U4"),
    ("toc_sec", "i8"), ("toc_frac", "f8"),        # tb (epoch of the record) as GPS time
    ("toe_sec", "i8"), ("toe_frac", "f8"),        # same instant (reference time for selection)
    ("pos_m", "f8", (3,)), ("vel_mps", "f8", (3,)), ("acc_mps2", "f8", (3,)),  # PZ-90 ECEF
    ("tau_n_s", "f8"),        # tau_n (RINEX writes -tau_n)
    ("gamma_n", "f8"),
    ("tk_s", "f8"),           # message frame time [s of the UTC week] as RINEX
    ("health", "i8"), ("channel", "i8"), ("age_d", "f8"),
    ("iode", "i8"),           # tb index: minutes of GLONASS day / 15 (as RTKLIB)
])


@dataclass
class SystemTable:
    """Records of one system: the record table, georinex's raw values, and the epochs as written."""

    system: str
    rec: np.ndarray                # KEPLER_DTYPE or GLONASS_DTYPE rows
    raw: np.ndarray                # (n, len(fields)) georinex values (GLONASS X.. in m as georinex gives)
    fields: list[str]              # georinex names of raw's columns
    epoch: np.ndarray              # (n,) datetime64[s] record epoch as written (system time; UTC for GLONASS)

    def __len__(self) -> int:
        return len(self.rec)

    def take(self, idx) -> SystemTable:
        return SystemTable(self.system, self.rec[idx], self.raw[idx], list(self.fields), self.epoch[idx])

    @staticmethod
    def concatenate(parts: list[SystemTable]) -> SystemTable:
        parts = [p for p in parts if len(p)]
        if not parts:
            raise ValueError("no records to concatenate")
        return SystemTable(
            parts[0].system,
            np.concatenate([p.rec for p in parts]),
            np.concatenate([p.raw for p in parts]),
            list(parts[0].fields),
            np.concatenate([p.epoch for p in parts]),
        )


@dataclass
class NavData:
    """The content of one or more navigation files."""

    tables: dict[str, SystemTable] = field(default_factory=dict)
    #: header ionospheric coefficients keyed as RINEX 3 IONOSPHERIC CORR: GPSA, GPSB (Klobuchar alpha/beta),
    #: GAL (NeQuick-G ai0..ai2), QZSA, QZSB, BDSA, BDSB, IRNA, IRNB
    iono: dict[str, list[float]] = field(default_factory=dict)
    leap_seconds: int | None = None
    versions: list[float] = field(default_factory=list)
    paths: list[str] = field(default_factory=list)
    #: records not read, by reason (e.g. "RINEX4 G CNAV": 12)
    skipped: dict[str, int] = field(default_factory=dict)
    #: corrections applied to malformed input (also logged as warnings)
    notes: list[str] = field(default_factory=list)
    #: records dropped, one message each ("file:line: G05 2022-01-01 00:00:00 dropped: reason")
    dropped: list[str] = field(default_factory=list)
    #: where each record came from: (sv, nav type, epoch as written) -> "file:line"
    origin: dict[tuple, str] = field(default_factory=dict)

    def merge(self, other: NavData) -> NavData:
        tables = dict(self.tables)
        for s, tab in other.tables.items():
            tables[s] = SystemTable.concatenate([tables[s], tab]) if s in tables else tab
        iono = dict(other.iono)
        iono.update(self.iono)  # the first file's coefficients win
        skipped = dict(self.skipped)
        for k, v in other.skipped.items():
            skipped[k] = skipped.get(k, 0) + v
        return NavData(
            tables=tables,
            iono=iono,
            leap_seconds=self.leap_seconds if self.leap_seconds is not None else other.leap_seconds,
            versions=self.versions + other.versions,
            paths=self.paths + other.paths,
            skipped=skipped,
            notes=self.notes + other.notes,
            dropped=self.dropped + other.dropped,
            origin={**self.origin, **other.origin},
        )

    def drop(self, where: str, sv: str, epoch, reason: str) -> None:
        """Record (and warn) that the record of ``sv`` at ``epoch`` written at ``where`` is not used."""
        msg = f"{where}: {sv} record {str(epoch).replace('T', ' ')[:19]} dropped: {reason}"
        self.dropped.append(msg)
        warnings.warn(msg, NavDataWarning, stacklevel=3)

    def records(self, system: str) -> np.ndarray:
        """Record table of ``system`` (empty table of the right dtype when absent)."""
        if system in self.tables:
            return self.tables[system].rec
        return np.zeros(0, dtype=GLONASS_DTYPE if system == "R" else KEPLER_DTYPE)


def toe_time(rec: np.ndarray) -> GnssTime:
    """Reference time (toe, GLONASS tb) of record rows as GPS time."""
    return GnssTime(rec["toe_sec"], rec["toe_frac"])


def toc_time(rec: np.ndarray) -> GnssTime:
    """Clock reference time (toc, GLONASS tb) of record rows as GPS time."""
    return GnssTime(rec["toc_sec"], rec["toc_frac"])


def epoch_key(epoch) -> str:
    """A record epoch (datetime or datetime64) as 'YYYY-MM-DD HH:MM:SS' (dictionary key)."""
    return str(np.datetime64(epoch, "s")).replace("T", " ")

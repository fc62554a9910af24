"""RTCM3 Multiple Signal Messages, MSM4 and MSM7 (RTCM 10403.3, 3.5.12, tables 3.5-78 to 3.5-88).

One message carries one system's satellites at one epoch: header (epoch time,
satellite mask, signal mask, cell mask), satellite data (rough range, in MSM7
also the extended info and rough range rate), signal data per cell (fine
pseudorange, fine phase range, lock time, half-cycle flag, CNR, in MSM7 also
the fine phase range rate).  Where nsat x nsig exceeds 64 cells the
satellites are spread over several messages with the multiple message bit set.

The carrier phase goes out as phase range relative to the rough range; its
integer number of cycles is removed once per continuous track (RTCM 10403.3
3.5.12.3 note: the phase range may hold an arbitrary integer offset that
stays constant while the lock time grows), so a decoder's phase equals the
simulated one minus one integer per track.  :class:`MsmEncoder` keeps that
offset and the lock time per satellite and signal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import constants as k
from .. import signals as sig
from ..time import GnssTime
from .frame import BitWriter

#: one millisecond of light travel [m] (RTCM 10403.3 DF397/DF398 unit)
RANGE_MS_M = k.C_MPS * 1e-3

#: MSM message number base per system (RTCM 10403.3 table 3.5-78: 1071-1077 GPS ... 1131-1137 NavIC)
MSM_BASE = {"G": 1070, "R": 1080, "E": 1090, "J": 1110, "C": 1120, "I": 1130}

#: signal ID (1-32) -> RINEX 3 band+attribute, per system: RTCM 10403.3 tables 3.5-91 (GPS),
#: 3.5-96 (GLONASS), 3.5-99 (Galileo), 3.5-105 (QZSS), 3.5-108 with Amendment 2 (BeiDou B2a,
#: B2b, B1C: IDs 22-25, 30-32), 3.5-108.3 (NavIC)
_SIGNAL_IDS = {
    "G": {2: "1C", 3: "1P", 4: "1W", 8: "2C", 9: "2P", 10: "2W", 15: "2S", 16: "2L", 17: "2X",
          22: "5I", 23: "5Q", 24: "5X", 30: "1S", 31: "1L", 32: "1X"},
    "R": {2: "1C", 3: "1P", 8: "2C", 9: "2P"},
    "E": {2: "1C", 3: "1A", 4: "1B", 5: "1X", 6: "1Z", 8: "6C", 9: "6A", 10: "6B", 11: "6X", 12: "6Z",
          14: "7I", 15: "7Q", 16: "7X", 18: "8I", 19: "8Q", 20: "8X", 22: "5I", 23: "5Q", 24: "5X"},
    "J": {2: "1C", 9: "6S", 10: "6L", 11: "6X", 15: "2S", 16: "2L", 17: "2X", 22: "5I", 23: "5Q", 24: "5X",
          30: "1S", 31: "1L", 32: "1X"},
    "C": {2: "2I", 3: "2Q", 4: "2X", 8: "6I", 9: "6Q", 10: "6X", 14: "7I", 15: "7Q", 16: "7X",
          22: "5D", 23: "5P", 24: "5X", 25: "7D", 30: "1D", 31: "1P", 32: "1X"},
    "I": {22: "5A"},
}
#: RINEX band+attribute -> MSM signal ID, per system
SIGNAL_ID = {s: {code: i for i, code in ids.items()} for s, ids in _SIGNAL_IDS.items()}
SIGNAL_CODE = _SIGNAL_IDS

#: largest |fine pseudorange| [m]: DF405 int20 x 2^-29 ms, DF400 int15 x 2^-24 ms (both ~292.7 m)
_FINE_PR_MAX_M = 2.0 ** -10 * RANGE_MS_M * (1 - 2.0 ** -9)
#: largest |fine phase range| [m]: DF406 int24 x 2^-31 ms, DF401 int22 x 2^-29 ms (~1171 m)
_FINE_CP_MAX_M = 2.0 ** -8 * RANGE_MS_M * (1 - 2.0 ** -9)
#: largest |fine phase range rate| [m/s]: DF404 int15 x 0.0001 m/s
_FINE_RATE_MAX_MPS = 1.6383
#: MSM cell limit: nsat x nsig <= 64 (RTCM 10403.3 DF396)
MAX_CELLS = 64


def lock_indicator_msm7(lock_ms):
    """DF407 extended lock time indicator (RTCM 10403.3 table 3.5-76) from the lock time [ms]:
    i = t below 64 ms, then i = (t + n 2^(n+5)) / 2^n for t in [2^(n+5), 2^(n+6)), n = 1..20;
    704 at and beyond 2^26 ms."""
    t = int(max(lock_ms, 0))
    if t < 64:
        return t
    n = t.bit_length() - 6          # t in [2^(n+5), 2^(n+6))
    if n > 20:
        return 704
    return (t + n * (1 << (n + 5))) >> n


def lock_indicator_msm4(lock_ms):
    """DF402 lock time indicator (RTCM 10403.3 table 3.5-74): 0 below 32 ms, then i for
    t >= 2^(i+4) ms, up to 15 (t >= 524288 ms)."""
    t = int(max(lock_ms, 0))
    if t < 32:
        return 0
    return min(t.bit_length() - 5, 15)


def epoch_time_field(system: str, t: GnssTime) -> int:
    """The 30-bit MSM epoch time (DF004 GPS, DF248 Galileo, DF427 BeiDou, DF428 QZSS, NavIC TOW
    in ms; GLONASS DF416 day of week << 27 | DF034 time of day in ms, GLONASS time UTC(SU) + 3 h)."""
    if system == "R":
        sec, frac = t.seconds_in("GLO")
        sec = int(sec)
        dow = (sec // 86400) % 7              # 1980-01-06 was a Sunday (day 0)
        tod_ms = int(round(((sec % 86400) + float(frac)) * 1000.0))
        if tod_ms >= 86_400_000:
            tod_ms -= 86_400_000
            dow = (dow + 1) % 7
        return (dow << 27) | tod_ms
    scale = {"G": "GPS", "E": "GST", "J": "QZS", "C": "BDT", "I": "IRN"}[system]
    _, tow = t.week_tow(scale)
    ms = int(round(tow * 1000.0))
    return ms % 604_800_000


@dataclass
class SignalObs:
    """One satellite's observations of one signal at one epoch (NaN: missing)."""

    code: str                 #: RINEX band+attribute, "1C"
    pseudorange_m: float
    phase_cyc: float
    doppler_hz: float
    cn0_dbhz: float
    lli: int                  #: RINEX LLI of the phase (bit 0 loss of lock, bit 1 half cycle); -1 unknown


@dataclass
class _Track:
    t_start: GnssTime
    offset_m: float = 0.0


class MsmEncoder:
    """MSM messages epoch after epoch, keeping lock times and phase offsets per track.

    ``msm``: 7 (full resolution, Doppler, extended CNR) or 4; ``station_id``: DF003.
    """

    def __init__(self, msm: int = 7, station_id: int = 0):
        if msm not in (4, 7):
            raise ValueError(f"msm = {msm!r}: MSM4 or MSM7 (parameter rtcm_msm)")
        if not 0 <= int(station_id) < 4096:
            raise ValueError(f"station_id = {station_id!r}: must be 0..4095 (RTCM DF003)")
        self.msm = msm
        self.station_id = int(station_id)
        self._tracks: dict[tuple[str, str], _Track] = {}
        self.iods = 0

    def encode(self, t: GnssTime, system: str, sats: dict[str, list[SignalObs]], glo_channel: dict[str, int],
               more_follow: bool) -> list[bytes]:
        """Payloads of one system's MSM at ``t``: ``sats`` {sv: [SignalObs]} (signals without an MSM
        ID are left out); ``more_follow``: other messages of this epoch come after (multiple
        message bit of the last payload)."""
        ids = SIGNAL_ID.get(system)
        if ids is None:
            raise ValueError(f"MSM: system {system!r} has no RTCM MSM (known: {''.join(MSM_BASE)})")
        rows = []
        for sv in sorted(sats, key=lambda s: int(s[1:])):
            prn = int(sv[1:])
            if not 1 <= prn <= 64:
                raise ValueError(f"MSM: satellite {sv} outside the 64 satellite mask bits")
            cells = [o for o in sats[sv] if o.code in ids and np.isfinite(o.pseudorange_m)]
            if cells:
                rows.append((sv, prn, cells))
        groups = _split_cells(rows, ids)
        out = []
        for gi, group in enumerate(groups):
            more = more_follow or gi < len(groups) - 1
            out.append(self._message(t, system, group, ids, glo_channel, more))
        return out

    # -----------------------------------------------------------------------------------------
    def _message(self, t, system, group, ids, glo_channel, more: bool) -> bytes:
        sig_ids = sorted({ids[o.code] for _, _, cells in group for o in cells})
        col = {sid: j for j, sid in enumerate(sig_ids)}
        nsig = len(sig_ids)
        w = BitWriter()
        w.u(12, MSM_BASE[system] + self.msm, "DF002").u(12, self.station_id, "DF003")
        w.u(30, epoch_time_field(system, t), "epoch time")
        w.u(1, 1 if more else 0, "DF393").u(3, self.iods, "DF409").u(7, 0, "DF001")
        w.u(2, 0, "DF411").u(2, 0, "DF412").u(1, 0, "DF417").u(3, 0, "DF418")
        prns = {prn for _, prn, _ in group}
        w.bits(p in prns for p in range(1, 65))
        sids = set(sig_ids)
        w.bits(s in sids for s in range(1, 33))
        cell_mask = np.zeros((len(group), nsig), dtype=bool)
        by_cell = {}
        for i, (_, _, cells) in enumerate(group):
            for o in cells:
                j = col[ids[o.code]]
                cell_mask[i, j] = True
                by_cell[(i, j)] = o
        w.bits(cell_mask.ravel().tolist())
        # satellite data: rough range from the first signal (DF397 + DF398, 2^-10 ms), GLONASS
        # channel (DF419 = k + 7), rough range rate from its Doppler (DF399, 1 m/s)
        rough_m, rough_rate, ext = [], [], []
        for sv, _, cells in group:
            o = cells[0]
            n10 = int(round(o.pseudorange_m / RANGE_MS_M * 1024.0))
            if not 0 < n10 < 255 * 1024:
                raise ValueError(f"MSM {sv} {o.code}: pseudorange {o.pseudorange_m!r} m outside 0..255 ms")
            rough_m.append(n10 * RANGE_MS_M / 1024.0)
            rr = np.nan
            for c in cells:
                if np.isfinite(c.doppler_hz):
                    rr = -c.doppler_hz * _wavelength_m(system, c.code, glo_channel, sv)
                    break
            rough_rate.append(int(round(rr)) if np.isfinite(rr) and abs(rr) <= 8191 else None)
            ext.append(glo_channel.get(sv, -8) + 7 if system == "R" else 0)
        for r in rough_m:
            w.u(8, int(round(r / RANGE_MS_M * 1024.0)) >> 10, "DF397")
        if self.msm == 7:
            for e in ext:
                w.u(4, e if 0 <= e <= 13 else 15, "DF419")
        for r in rough_m:
            w.u(10, int(round(r / RANGE_MS_M * 1024.0)) & 0x3FF, "DF398")
        if self.msm == 7:
            for rr in rough_rate:
                w.s(14, -8192 if rr is None else rr, "DF399")
        # signal data, cell by cell (satellite-major, as the cell mask)
        cells = [(i, j, by_cell[(i, j)]) for i in range(len(group)) for j in range(nsig) if cell_mask[i, j]]
        fine_pr, fine_cp, lock, half, cnr, fine_rate = [], [], [], [], [], []
        for i, _, o in cells:
            sv = group[i][0]
            lam = _wavelength_m(system, o.code, glo_channel, sv)
            d = o.pseudorange_m - rough_m[i]
            fine_pr.append(d if abs(d) <= _FINE_PR_MAX_M else None)
            lock_ms, cp = self._phase(t, sv, o, lam, rough_m[i])
            fine_cp.append(cp)
            lock.append(lock_ms)
            half.append(1 if (o.lli >= 0 and o.lli & 2) else 0)
            cnr.append(o.cn0_dbhz)
            rate = None
            if rough_rate[i] is not None and np.isfinite(o.doppler_hz):
                r = -o.doppler_hz * lam - rough_rate[i]
                rate = r if abs(r) <= _FINE_RATE_MAX_MPS else None
            fine_rate.append(rate)
        values = {"pr": fine_pr, "cp": fine_cp, "lock": lock, "half": half, "cnr": cnr, "rate": fine_rate}
        for df, bits, key, lsb in _CELL_FIELDS[self.msm]:
            put = w.u if key in ("lock", "half", "cnr") else w.s      # unsigned / two's complement fields
            for v in values[key]:
                put(bits, _cell_field(key, bits, lsb, v, self.msm), df)
        return w.payload()

    def _phase(self, t: GnssTime, sv: str, o: SignalObs, lam: float, rough_m: float):
        """(lock time [ms], fine phase range [m] or None) of one cell; starts a new track (lock time 0,
        new integer offset) on loss of lock, after a gap (:meth:`forget`) or when the phase range
        drifts out of range."""
        key = (sv, o.code)
        tr = self._tracks.get(key)
        if not np.isfinite(o.phase_cyc):
            if tr is not None:
                del self._tracks[key]
            return 0, None
        phr = o.phase_cyc * lam - rough_m
        if tr is None or (o.lli >= 0 and o.lli & 1) or abs(phr - tr.offset_m) > _FINE_CP_MAX_M:
            tr = _Track(t_start=t, offset_m=round(phr / lam) * lam)
            self._tracks[key] = tr
        return (t - tr.t_start) * 1000.0, phr - tr.offset_m

    def forget(self, sv_codes_seen: set) -> None:
        """Drop the tracks of signals not seen at this epoch (their next epoch starts a new track)."""
        for key in [k_ for k_ in self._tracks if k_ not in sv_codes_seen]:
            del self._tracks[key]


#: signal data fields in message order (RTCM 10403.3 tables 3.5-86 MSM4, 3.5-89 MSM7):
#: (data field, bits, quantity, LSB: ms for ranges, m/s for the rate, dB-Hz for CNR)
_CELL_FIELDS = {
    7: (("DF405", 20, "pr", 2.0 ** -29), ("DF406", 24, "cp", 2.0 ** -31), ("DF407", 10, "lock", 0),
        ("DF420", 1, "half", 0), ("DF408", 10, "cnr", 1.0 / 16.0), ("DF404", 15, "rate", 0.0001)),
    4: (("DF400", 15, "pr", 2.0 ** -24), ("DF401", 22, "cp", 2.0 ** -29), ("DF402", 4, "lock", 0),
        ("DF420", 1, "half", 0), ("DF403", 6, "cnr", 1.0)),
}


def _cell_field(key: str, bits: int, lsb: float, v, msm: int) -> int:
    """Integer of one signal data field; a missing range or rate is the field's invalid value -2^(bits-1),
    a missing CNR 0 (not available)."""
    if key == "lock":
        return lock_indicator_msm7(v) if msm == 7 else lock_indicator_msm4(v)
    if key == "half":
        return int(v)
    if key == "cnr":
        return int(np.clip(round(v / lsb), 1, (1 << bits) - 1)) if np.isfinite(v) else 0
    if v is None:
        return -(1 << (bits - 1))
    return int(round(v / (RANGE_MS_M * lsb if key in ("pr", "cp") else lsb)))


def _wavelength_m(system: str, code: str, glo_channel: dict, sv: str) -> float:
    if system == "R":
        if sv not in glo_channel:
            raise ValueError(f"MSM: GLONASS {sv} has no frequency channel (header glonass_slots)")
        return float(sig.wavelength_m("R", code, glo_channel[sv]))
    return float(sig.wavelength_m(system, code))


def _split_cells(rows, ids) -> list[list]:
    """Satellites in groups whose nsat x nsig stays within the 64 cells of one message."""
    groups, cur, cur_sigs = [], [], set()
    for row in rows:
        s = {ids[o.code] for o in row[2]}
        union = cur_sigs | s
        if cur and (len(cur) + 1) * len(union) > MAX_CELLS:
            groups.append(cur)
            cur, union = [], set(s)
        cur.append(row)
        cur_sigs = union
    if cur:
        groups.append(cur)
    return groups

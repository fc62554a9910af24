"""Streaming RTCM3 writer with the epoch-by-epoch shape of core/rinex/obs_write.RinexObsWriter.

::

    hdr = header(obs_types, "BASE", base_ecef_m, 1.0, glonass_slots)   # core/receiver/outputs.py
    with RtcmWriter("base.rtcm3", hdr, navigation=records_as_dicts(nav)) as w:
        for t, obs in epochs:
            w.write_epoch(t, epoch_arrays(obs, obs_types))   # the same EpochArrays as the RINEX writer

Per epoch, in this order: station messages (1006 antenna reference point from
the header's APPROX POSITION and antenna height, 1033 descriptors, 1230 GLONASS
code-phase biases when GLONASS is observed) at the first epoch and every
``station_interval_s``; the broadcast ephemeris of each satellite observed
(1019/1020/1041/1042/1044/1045/1046) when its record changes and every
``ephemeris_interval_s``; then one MSM per system (several where its cells
exceed 64), each but the last of the epoch with the multiple message bit set
so that decoders (RTKLIB) collect them into one epoch.

The sink is a file path (written unbuffered: every epoch goes to the OS at
once, a killed process leaves whole messages) or any object with
``write(bytes)`` (a socket file, ``io.BytesIO``).  ``write_epoch`` also
returns the bytes of the epoch (what the node publishes).

What RTCM does not carry: the receiver clock offset (MSM has none; the
``clock_offset_s`` argument is accepted and ignored), and the integer part of
the carrier phase (see msm.py: one integer per continuous track is removed).
"""
from __future__ import annotations

import bisect
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..rinex.obs_write import EpochArrays, RinexObsHeader
from ..time import GnssTime
from . import ephemeris as eph
from .frame import frame
from .msm import MSM_BASE, SIGNAL_ID, MsmEncoder, SignalObs
from .station import encode_1005, encode_1033, encode_1230


class RtcmWriter:
    """Write RTCM3 (MSM7 or MSM4, station, ephemerides) epoch by epoch (module docstring).

    ``header``: the :class:`RinexObsHeader` (or its dict) of the RINEX file of
    the same run: observation types, approximate position (the station's
    antenna reference point), antenna height, GLONASS slots and biases.
    ``navigation``: ``{system: [record dicts]}`` as rinex.nav.records_as_dicts
    gives them (None: no ephemeris messages).
    """

    def __init__(self, sink, header, *, msm: int = 7, station_id: int = 0, navigation: Mapping | None = None,
                 ephemeris_interval_s: float = 60.0, station_interval_s: float = 10.0):
        self.header = RinexObsHeader.from_any(header)
        self.header.validate()
        for name, v in (("ephemeris_interval_s", ephemeris_interval_s), ("station_interval_s", station_interval_s)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"RtcmWriter: {name} = {v!r} must be a positive number of seconds")
        self.msm = MsmEncoder(msm=msm, station_id=station_id)
        self.station_id = int(station_id)
        self.ephemeris_interval_s = float(ephemeris_interval_s)
        self.station_interval_s = float(station_interval_s)
        self._signals = self._signal_columns(self.header.obs_types)
        self._glo = {str(k): int(v) for k, v in self.header.glonass_slots.items()}
        self.ephemerides = EphemerisSchedule(navigation or {}, ephemeris_interval_s)
        self._t_station: GnssTime | None = None
        self.t_last: GnssTime | None = None
        self.epochs_written = 0
        self.messages_written: dict[int, int] = {}
        self.path = None
        self._fd = None
        self._sink = None
        if isinstance(sink, (str, os.PathLike)):
            self.path = Path(sink)
            try:
                self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            except OSError as exc:
                raise ValueError(f"{self.path}: cannot open for writing ({exc.strerror})") from None
        elif hasattr(sink, "write"):
            self._sink = sink
        else:
            raise ValueError(f"RtcmWriter: sink must be a file path or an object with write(), not "
                             f"{type(sink).__name__}")

    # --------------------------------------------------------------------------------------
    @staticmethod
    def _signal_columns(obs_types) -> dict[str, list[str]]:
        """{system: [band+attribute]} of the header's code observations, each with an MSM signal ID."""
        out = {}
        for s, codes in obs_types.items():
            if s not in MSM_BASE:
                raise ValueError(f"RtcmWriter: header obs_types system {s!r} has no RTCM MSM "
                                 f"(known: {''.join(MSM_BASE)})")
            sigs = list(dict.fromkeys(c[1:] for c in codes if c[0] in "CLDS"))
            bad = [c for c in sigs if c not in SIGNAL_ID[s]]
            if bad:
                raise ValueError(f"RtcmWriter: header obs_types {s}: signal(s) {bad} have no RTCM MSM signal ID "
                                 f"(known for {s}: {sorted(SIGNAL_ID[s])})")
            out[s] = sigs
        return out

    def _emit(self, payloads: list[bytes]) -> bytes:
        data = b"".join(frame(p) for p in payloads)
        for p in payloads:
            n = (p[0] << 4) | (p[1] >> 4)
            self.messages_written[n] = self.messages_written.get(n, 0) + 1
        if self._fd is not None:
            view = memoryview(data)
            while view:
                view = view[os.write(self._fd, view):]
        else:
            self._sink.write(data)
        return data

    def _sats(self, observations) -> dict[str, dict[str, list[SignalObs]]]:
        """{system: {sv: [SignalObs]}} of one epoch (EpochArrays or the RINEX writer's dict form)."""
        out: dict[str, dict[str, list[SignalObs]]] = {}
        if isinstance(observations, EpochArrays):
            value = np.asarray(observations.value, dtype=np.float64)
            lli = None if observations.lli is None else np.asarray(observations.lli)
            ssi = None if observations.ssi is None else np.asarray(observations.ssi)
            per_sys = isinstance(observations.codes, Mapping)
            for r, sv in enumerate(observations.sv):
                s = sv[0]
                codes = observations.codes[s] if per_sys else observations.codes
                col = {c: j for j, c in enumerate(codes)}
                out.setdefault(s, {})[sv] = self._signal_list(sv, lambda c, r=r, col=col: (
                    (value[r, col[c]], None if lli is None else lli[r, col[c]],
                     None if ssi is None else ssi[r, col[c]]) if c in col else None))
        elif isinstance(observations, Mapping):
            for sv, obs in observations.items():
                def get(c, obs=obs):
                    item = obs.get(c)
                    if item is None:
                        return None
                    return tuple(item) + (None,) * (3 - len(item)) if isinstance(item, tuple) else (item, None, None)
                out.setdefault(str(sv)[0], {})[str(sv)] = self._signal_list(str(sv), get)
        else:
            raise ValueError(f"RtcmWriter.write_epoch: observations must be EpochArrays or a dict, not "
                             f"{type(observations).__name__}")
        return out

    def _signal_list(self, sv: str, get) -> list[SignalObs]:
        s = sv[0]
        if s not in self._signals:
            raise ValueError(f"RtcmWriter.write_epoch: satellite {sv!r} of a system not in the header obs_types "
                             f"({list(self._signals)})")
        nan = float("nan")
        res = []
        for code in self._signals[s]:
            vals = {}
            for kind in "CLDS":
                item = get(kind + code)
                vals[kind] = item if item is not None else (nan, None, None)
            pr = _finite(vals["C"][0])
            if not np.isfinite(pr):
                continue
            lli = vals["L"][1]
            lli = -1 if lli is None or not np.isfinite(float(lli)) or float(lli) < 0 else int(lli)
            res.append(SignalObs(code, pr, _finite(vals["L"][0]), _finite(vals["D"][0]), _finite(vals["S"][0]), lli))
        return res

    # --------------------------------------------------------------------------------------
    def add_glonass_channels(self, channels: Mapping[str, int]):
        """GLONASS frequency channels learnt after the header ({"R01": k}): a satellite whose broadcast record
        becomes valid during the run (a node has no ephemeris of its own, only each epoch's states)."""
        for sv, k in channels.items():
            self._glo.setdefault(str(sv), int(k))

    def write_epoch(self, t: GnssTime, observations, clock_offset_s: float | None = None, flag: int = 0) -> bytes:
        """Append one epoch (GPS time ``t``): station and ephemeris messages when due, then the MSMs.
        ``observations`` as for RinexObsWriter.write_epoch; ``flag`` 1 (power failure) restarts every
        track.  Returns the bytes written."""
        if self._fd is None and self._sink is None:
            raise ValueError(f"{self.path or 'RtcmWriter'}: write_epoch() after close()")
        if np.ndim(t.sec) != 0:
            raise ValueError("RtcmWriter.write_epoch: t must be a scalar GnssTime")
        if flag not in (0, 1):
            raise ValueError(f"RtcmWriter.write_epoch: flag={flag!r}; only 0 (OK) and 1 (power failure)")
        if self.t_last is not None and not (t - self.t_last) > 0:
            raise ValueError(f"RtcmWriter.write_epoch: t={t!r} is not after the previous epoch {self.t_last!r}")
        sats = self._sats(observations)
        if flag == 1:
            self.msm.forget(set())
        payloads = []
        if self._t_station is None or (t - self._t_station) >= self.station_interval_s - 1e-9:
            payloads += self.station_messages(with_glonass="R" in sats)
            self._t_station = t
        payloads += self.ephemerides.due(t, [sv for s in sats.values() for sv in s])
        seen = {(sv, o.code) for s in sats.values() for sv, lst in s.items() for o in lst}
        systems = [s for s in MSM_BASE if sats.get(s)]
        for i, s in enumerate(systems):
            payloads += self.msm.encode(t, s, sats[s], self._glo, more_follow=i < len(systems) - 1)
        self.msm.forget(seen)
        data = self._emit(payloads)
        self.t_last = t
        self.epochs_written += 1
        return data

    def station_messages(self, with_glonass: bool = True) -> list[bytes]:
        """1006 (ARP and antenna height), 1033 and, with GLONASS, 1230 payloads of the header's station."""
        h = self.header
        out = [encode_1005(self.station_id, h.approx_pos_ecef_m, "".join(self._signals),
                           antenna_height_m=float(h.antenna_delta_hen_m[0])),
               encode_1033(self.station_id, h.antenna_type, h.antenna_number, h.receiver_type, h.receiver_version,
                           h.receiver_number)]
        if with_glonass and "R" in self._signals:
            bis = h.glonass_cod_phs_bis_m or {"C1C": 0.0, "C1P": 0.0, "C2C": 0.0, "C2P": 0.0}
            out.append(encode_1230(self.station_id, dict(bis)))
        return out

    def flush(self) -> None:
        """Hand buffered bytes to the OS (file sinks are unbuffered; an object sink's own flush())."""
        if self._sink is not None and hasattr(self._sink, "flush"):
            self._sink.flush()

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        elif self._sink is not None:
            self.flush()
            self._sink = None

    def __enter__(self) -> RtcmWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _finite(v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return float("nan")
    return x


class EphemerisSchedule:
    """Which broadcast ephemeris messages are due at an epoch: per satellite the record with the latest
    toc at or before it (the nearest one where none is before; Galileo I/NAV before F/NAV of the same
    toc), sent when it changes and again every ``interval_s``, as a base station repeats them.

    ``navigation``: ``{system: [record dicts]}`` (rinex.nav.records_as_dicts).
    """

    def __init__(self, navigation: Mapping, interval_s: float = 60.0):
        self.interval_s = float(interval_s)
        self._by_sv: dict[str, tuple[list, list]] = {}
        for records in navigation.values():
            for r in records:
                self._by_sv.setdefault(str(r["sv"]), ([], []))[1].append(r)
        for sv, (_, recs) in self._by_sv.items():
            recs.sort(key=lambda r: (_toc_gps_s(sv[0], r), 0 if sv[0] == "E" and eph.galileo_is_fnav(r) else 1))
            self._by_sv[sv] = ([_toc_gps_s(sv[0], r) for r in recs], recs)
        self._sent: dict[str, tuple] = {}            # sv -> (record index, time sent)

    def svs(self) -> list[str]:
        return sorted(self._by_sv)

    def record_at(self, sv: str, t: GnssTime):
        """(index, record) in force at ``t`` for ``sv``, or None without records."""
        hit = self._by_sv.get(sv)
        if not hit:
            return None
        tocs, recs = hit
        i = max(bisect.bisect_right(tocs, float(t.sec) + float(t.frac)) - 1, 0)
        return i, recs[i]

    def due(self, t: GnssTime, svs=None) -> list[bytes]:
        """Payloads of the ephemeris messages due at ``t`` for ``svs`` (None: every satellite with records)."""
        out = []
        for sv in self.svs() if svs is None else svs:
            hit = self.record_at(sv, t)
            if hit is None:
                continue
            i, rec = hit
            sent = self._sent.get(sv)
            if sent is None or sent[0] != i or (t - sent[1]) >= self.interval_s - 1e-9:
                out.append(eph.encode_record(sv[0], rec))
                self._sent[sv] = (i, t)
        return out

    def reset(self) -> None:
        """Send everything again at the next epoch (a new receiver of the stream)."""
        self._sent.clear()


def _toc_gps_s(system: str, r: dict) -> float:
    """toc of a record as GPS seconds (its ``time`` is in the system's scale; UTC for GLONASS)."""
    scale = {"G": "GPS", "E": "GST", "J": "QZS", "C": "BDT", "I": "IRN", "R": "UTC"}[system]
    t = GnssTime.from_datetime(r["time"], scale)
    return float(t.sec) + float(t.frac)

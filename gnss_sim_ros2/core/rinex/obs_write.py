"""Streaming RINEX 3.04 observation writer (RINEX 3.04, IGS/RTCM-SC104, 2020).

The writer is opened once and fed one epoch at a time::

    hdr = RinexObsHeader(obs_types={"G": ["C1C", "L1C", "D1C", "S1C"],
                                    "E": ["C1C", "L1C", "D1C", "S1C"]},
                         marker_name="ROBOT", interval_s=1.0)
    with RinexObsWriter("robot.rnx", hdr) as w:
        w.write_epoch(t, {"G05": {"C1C": (21e6, None, 7), "L1C": (1.1e8, 0, 7)}})

Crash safety
------------
Each epoch is formatted completely in memory and handed to the kernel with one
``write()`` on an unbuffered file (``fsync=True`` also forces it to disk), so a
process killed at any time leaves the header and every epoch whose write
returned: a valid file up to the last complete epoch.  (Linux can in theory
cut a multi-page ``write()`` short when SIGKILL lands inside it; the window is
microseconds per epoch.  :func:`truncate_incomplete_epoch` removes such a
torn last epoch.)

TIME OF LAST OBS is optional in RINEX 3.04 and is not known while writing.
The header is written before the first epoch, with an 80-column *COMMENT*
line reserved where TIME OF LAST OBS belongs; :meth:`RinexObsWriter.close`
overwrites that line in place (same length, ``pwrite`` at its byte offset)
with the real TIME OF LAST OBS record.  A killed process therefore leaves a
header with a harmless COMMENT instead, which every reader accepts, and a
closed file has the full header.  Reserving (instead of rewriting the whole
file at close) keeps close O(1) and never exposes a half-rewritten file.

Observation lines: satellite id (A3) then per observation type of the header
F14.3 value, LLI digit (I1) and signal strength digit (I1), blanks where
missing (RINEX 3.04 table A13); trailing blanks are dropped.
"""
from __future__ import annotations

import datetime as _dt
import functools
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..memo import BoundedCache
from ..time import GPS_EPOCH, GnssTime, gps_minus_utc_at_gps

RINEX_VERSION = 3.04
#: systems RINEX 3.04 knows (section 3.5): GPS, GLONASS, Galileo, BeiDou, QZSS, NavIC, SBAS
SYSTEMS = "GRECJIS"
_OBS_CODE_RE = re.compile(r"^[CLDSX][0-9][A-Z]$")
#: LLI/SSI characters (ASCII codes) indexed by digit + 1 (index 0: blank)
_DIGIT_BYTES = np.frombuffer(b" 0123456789", dtype=np.uint8)


def _digit_table(n_digits: int, dot_before_last: bool = False) -> np.ndarray:
    """ASCII of the numbers 0 .. 10**n_digits - 1 with leading zeros, one row each (a "." before the last digit:
    "12.3" for 123)."""
    i = np.arange(10 ** n_digits)
    cols = [48 + (i // 10 ** k) % 10 for k in range(n_digits - 1, -1, -1)]
    if dot_before_last:
        cols.insert(n_digits - 1, np.full_like(i, 46))
    return np.ascontiguousarray(np.stack(cols, axis=1).astype(np.uint8))


#: An F14.3 field's 16 bytes (with the LLI and SSI characters) as four native 4-byte words: the integer part's
#: first 4 digits, its next 4, its last 2 with "." and the first decimal, the last 2 decimals with LLI and SSI.
#: "0000".."9999" as words; "00.0".."99.9" (index: last two digits * 10 + first decimal); "00".."99" as 2-byte
#: halves
_W4 = _digit_table(4).view(np.uint32).ravel()
_W2DOT = _digit_table(3, dot_before_last=True).view(np.uint32).ravel()
_H2 = _digit_table(2).view(np.uint16).ravel()
#: 10, 100, ..., 10**9: the number of digits of an integer i is searchsorted(_POW10, i, "right") + 1
_POW10 = 10 ** np.arange(1, 10, dtype=np.int64)
#: [negative, nb, column]: character over the 10 integer columns when there are nb leading
#: blanks (0 = keep the digit, 32 = blank, 45 = the minus sign before the first digit)
_LEAD_FILL = np.zeros((2, 11, 10), dtype=np.uint8)
for _nb in range(11):
    _LEAD_FILL[:, _nb, :_nb] = 32
    if _nb:
        _LEAD_FILL[1, _nb, _nb - 1] = 45
_LEAD_FILL = _LEAD_FILL.reshape(22, 10)
#: the same over the first three words of a field, word by word: what to keep of the digits (all-ones bytes)
#: and the blanks and sign put over them; a 23rd entry blanks the field
_LEAD_KEEP = tuple(np.ascontiguousarray(w) for w in np.vstack([
    np.pad(np.where(_LEAD_FILL == 0, 255, 0).astype(np.uint8), ((0, 0), (0, 2)), constant_values=255),
    np.zeros((1, 12), np.uint8)]).view(np.uint32).T)
_LEAD_OVER = tuple(np.ascontiguousarray(w) for w in np.vstack([
    np.pad(_LEAD_FILL, ((0, 0), (0, 2))), np.full((1, 12), 32, np.uint8)]).view(np.uint32).T)
_BLANK_FIELD = 22
#: two blanks as a half word
_BLANK_HALF = np.frombuffer(b"  ", dtype=np.uint16)[0]


def _f14_3_words(v: np.ndarray, blank: np.ndarray | None = None) -> np.ndarray:
    """Fortran F14.3 of finite values (1-D array): (n, 4) native words whose bytes are the 14 characters, then
    two bytes for the caller (the LLI and SSI characters) -- see _f14_3_chars; 14 blanks where ``blank`` (bool,
    the values there finite all the same)."""
    neg = v < 0
    a = np.abs(v)
    whole = np.floor(a)  # split so that the scaling by 1000 rounds only the (exact) fraction
    ip = whole.astype(np.int64)
    fr = np.rint((a - whole) * 1000.0).astype(np.int64)
    carry = fr >= 1000
    ip += carry
    fr -= 1000 * carry
    first4 = ip // 1_000_000  # <= 9999
    low6 = ip - first4 * 1_000_000
    next4 = low6 // 100
    last2 = low6 - next4 * 100
    dec1 = fr // 100
    n_blank = 9 - np.searchsorted(_POW10, ip, side="right")  # 10 columns minus the digit count
    if np.any(neg & (n_blank == 0)):
        raise ValueError("a negative value below -999999999.999 does not fit F14.3")
    lead = n_blank + 11 * neg
    decimals23 = _H2.take(fr - dec1 * 100)
    if blank is not None:
        lead[blank] = _BLANK_FIELD
        decimals23[blank] = _BLANK_HALF
    out = np.empty((v.size, 4), dtype=np.uint32)
    for k, w in enumerate((_W4.take(first4), _W4.take(next4), _W2DOT.take(last2 * 10 + dec1))):
        w &= _LEAD_KEEP[k].take(lead)
        w |= _LEAD_OVER[k].take(lead)
        out[:, k] = w
    out.view(np.uint16)[:, 6] = decimals23
    return out


def _f14_3_chars(v: np.ndarray) -> np.ndarray:
    """Fortran F14.3 of finite values (1-D array) as ASCII codes, shape (n, 14).

    Vectorised equivalent of ``f"{v:14.3f}"`` for |v| <= 9999999999.999
    (negative: |v| <= 999999999.999): same digits except within ~1e-13 of a
    rounding tie, and -0.0 prints as 0.000.  Much faster than formatting value
    by value in Python (bench/bench_rinex_obs.py).
    """
    return _f14_3_words(v).view(np.uint8)[:, :14]


#: largest magnitude an F14.3 field holds
_F14_MAX = 9999999999.999
_F14_NEG_MAX = 999999999.999
_LAST_OBS_PLACEHOLDER = "TIME OF LAST OBS: written when the file is closed"
_DEFAULT_GLO_COD_PHS_BIS = {"C1C": 0.0, "C1P": 0.0, "C2C": 0.0, "C2P": 0.0}


def ssi_from_cn0(cn0_dbhz):
    """RINEX signal strength indicator 1-9 from C/N0 [dB-Hz] (RINEX 3.04 section 5.7).

    ``min(max(int(cn0/6), 1), 9)``; non-finite C/N0 gives 0 ("not known").
    Scalar in -> int out; array in -> int array out.
    """
    c = np.asarray(cn0_dbhz, dtype=np.float64)
    ok = np.isfinite(c)
    ssi = np.where(ok, np.clip(np.floor(np.where(ok, c, 0.0) / 6.0), 1, 9), 0).astype(np.int64)
    return int(ssi) if ssi.ndim == 0 else ssi


@dataclass
class RinexObsHeader:
    """Header content of an observation file (RINEX 3.04 table A2).

    ``obs_types``: {system letter: [observation codes]} in the column order of
    the file, e.g. ``{"G": ["C1C", "L1C", "D1C", "S1C"]}``.
    ``glonass_slots``: {"R01": frequency channel k}; ``phase_shifts_cycles``:
    {system: {code: shift}} (default: 0.0 for every phase observation type).
    """

    obs_types: Mapping[str, Sequence[str]]
    marker_name: str = "GNSS_SIM"
    marker_number: str = ""
    marker_type: str = "GROUND_CRAFT"
    observer: str = ""
    agency: str = ""
    receiver_number: str = ""
    receiver_type: str = "GNSS_SIM"
    receiver_version: str = ""
    antenna_number: str = ""
    antenna_type: str = ""
    approx_pos_ecef_m: Sequence[float] = (0.0, 0.0, 0.0)
    antenna_delta_hen_m: Sequence[float] = (0.0, 0.0, 0.0)
    interval_s: float | None = None
    glonass_slots: Mapping[str, int] = field(default_factory=dict)
    glonass_cod_phs_bis_m: Mapping[str, float] | None = None
    phase_shifts_cycles: Mapping[str, Mapping[str, float]] | None = None
    rcv_clock_offset_applied: bool | None = None
    program: str = "gnss_sim"
    run_by: str = ""
    comments: Sequence[str] = ()
    #: write LEAP SECONDS (GPS-UTC at the first epoch)
    leap_seconds: bool = True
    #: reserve TIME OF LAST OBS and fill it in on close()
    time_of_last_obs: bool = True

    @classmethod
    def from_any(cls, info) -> RinexObsHeader:
        if isinstance(info, cls):
            return info
        if isinstance(info, Mapping):
            try:
                return cls(**info)
            except TypeError as exc:
                raise ValueError(f"header_info: {exc}") from exc
        raise ValueError(f"header_info must be a RinexObsHeader or a dict, not {type(info).__name__}")

    def validate(self) -> None:
        if not self.obs_types:
            raise ValueError("header_info.obs_types is empty: give {system: [codes]}")
        for sys_, codes in self.obs_types.items():
            if sys_ not in SYSTEMS or len(sys_) != 1:
                raise ValueError(f"header_info.obs_types: unknown system {sys_!r} (expected one of {SYSTEMS})")
            if not codes:
                raise ValueError(f"header_info.obs_types[{sys_!r}] is empty")
            if len(set(codes)) != len(codes):
                raise ValueError(f"header_info.obs_types[{sys_!r}] has duplicate codes: {list(codes)}")
            for c in codes:
                if not isinstance(c, str) or not _OBS_CODE_RE.match(c):
                    raise ValueError(
                        f"header_info.obs_types[{sys_!r}]: bad observation code {c!r} (expected e.g. 'C1C')"
                    )
        for name, width in (("marker_name", 60), ("marker_number", 20), ("marker_type", 20), ("observer", 20),
                            ("agency", 40), ("receiver_number", 20), ("receiver_type", 20),
                            ("receiver_version", 20), ("antenna_number", 20), ("antenna_type", 20),
                            ("program", 20), ("run_by", 20)):
            v = getattr(self, name)
            if not isinstance(v, str) or len(v) > width or not v.isascii():
                raise ValueError(f"header_info.{name}={v!r}: must be ASCII text of at most {width} characters")
        for c in self.comments:
            if len(c) > 60 or not c.isascii():
                raise ValueError(f"header_info.comments: {c!r} is longer than 60 characters or not ASCII")
        for name in ("approx_pos_ecef_m", "antenna_delta_hen_m"):
            v = np.asarray(getattr(self, name), dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(np.abs(v) >= 1e9):
                raise ValueError(f"header_info.{name}: need 3 finite values below 1e9 m, got {v!r}")
        if self.interval_s is not None and not (0 < self.interval_s < 1e6):
            raise ValueError(f"header_info.interval_s={self.interval_s}: must be in (0, 1e6) s")
        for sv, k in self.glonass_slots.items():
            if not re.fullmatch(r"R\d\d", sv) or not -7 <= int(k) <= 13:
                raise ValueError(f"header_info.glonass_slots: bad entry {sv!r}: {k!r} (expected 'R01': -7..13)")


def _hline(content: str, label: str) -> str:
    """One header line: 60 columns of content + 20 columns of label, newline."""
    return f"{content:<60.60s}{label:<20s}\n"


def _time_fields(t: GnssTime) -> tuple[int, int, int, int, int, int, int]:
    """(y, mo, d, h, mi, s, fraction in 1e-7 s) of a scalar GnssTime in GPS time."""
    sec = int(t.sec)
    q = round(float(t.frac) * 1e7)
    if q >= 10_000_000:
        sec, q = sec + 1, q - 10_000_000
    day, second_of_day = divmod(sec, 86400)        # GPS_EPOCH is a midnight
    minutes, s = divmod(second_of_day, 60)
    return (*_date_of_gps_day(day), minutes // 60, minutes % 60, s, q)


@functools.lru_cache(maxsize=64)
def _date_of_gps_day(day: int) -> tuple[int, int, int]:
    """(year, month, day) of the GPS day number ``day`` (days from GPS_EPOCH)."""
    d = GPS_EPOCH + _dt.timedelta(days=day)
    return d.year, d.month, d.day


def _time_of_obs_line(t: GnssTime, label: str) -> str:
    # TIME OF FIRST/LAST OBS: 5I6,F13.7,5X,A3 (RINEX 3.04 table A2)
    y, mo, d, h, mi, s, q = _time_fields(t)
    return _hline(f"{y:6d}{mo:6d}{d:6d}{h:6d}{mi:6d}{s:5d}.{q:07d}     GPS", label)


@dataclass
class EpochArrays:
    """Array form of one epoch: rows = satellites, columns = ``codes``.

    ``codes``: one list for every row, or {system: list} (all of length M) when
    the systems track different signals (column j = ``codes[sv[0]][j]``).
    ``value``: (N, M) float, NaN where missing; ``lli``/``ssi``: (N, M) int or
    float with NaN, or None (negative or NaN = blank).
    """

    sv: Sequence[str]
    codes: Sequence[str] | Mapping[str, Sequence[str]]
    value: np.ndarray
    lli: np.ndarray | None = None
    ssi: np.ndarray | None = None


@dataclass(frozen=True)
class FormattedEpoch:
    """An epoch's satellite lines formatted ahead of writing (EpochFormatter.format_arrays): RinexObsWriter.write_epochs
    takes it in place of the EpochArrays it was made of, for a header with the same obs_types (``key``)."""

    key: tuple
    n_sv: int
    lines: bytes


class EpochFormatter:
    """The satellite lines of observation epochs for a header's ``obs_types`` ({system: [codes]}), checked and
    formatted as RinexObsWriter writes them, without a file: the epochs of several files with the same obs_types
    (a fleet's receivers) formatted in one vectorised pass (:meth:`format_arrays`)."""

    def __init__(self, obs_types: Mapping[str, Sequence[str]]):
        self.obs_types = obs_types
        self.key = tuple((s, tuple(c)) for s, c in obs_types.items())
        self._code_index = {s: {c: i for i, c in enumerate(codes)} for s, codes in obs_types.items()}
        self._n_codes = {s: len(codes) for s, codes in obs_types.items()}
        self._array_maps: dict[tuple, list] = {}
        self._flat_cache = BoundedCache(256)

    def format_arrays(self, epochs) -> list[FormattedEpoch]:
        """Each EpochArrays of ``epochs`` as a FormattedEpoch, all of them checked and formatted in one pass (the
        bytes RinexObsWriter.write_epochs writes for each); raises ValueError as write_epochs does."""
        parts = [self._array_parts(ep) for ep in epochs]
        if not parts:
            return []
        return self.format_flat([len(p[0]) for p in parts], [sv for p in parts for sv in p[0]],
                                *self._arrays_flat(parts))

    def format_flat(self, n_sv, svs, value, lli, ssi) -> list[FormattedEpoch]:
        """FormattedEpoch of epochs given flat: ``n_sv`` satellites per epoch, ``svs`` all of them epoch after
        epoch, ``value``/``lli``/``ssi`` their cells (satellite after satellite, each with its system's codes in
        header order; NaN value / negative indicator = blank), as RinexObsWriter formats them."""
        for n in n_sv:
            if n > 999:
                raise ValueError(f"write_epoch: {n} satellites; the epoch record holds at most 999")
        text, offsets = self._format_rows(svs, value, lli, ssi)
        offsets = offsets.tolist()
        out, pos = [], 0
        for n in n_sv:
            out.append(FormattedEpoch(self.key, n, text[offsets[pos]:offsets[pos + n]]))
            pos += n
        return out

    # ----- epoch formatting ----------------------------------------------
    def _format_rows(self, svs: list[str], v, lli, ssi) -> tuple[bytes, np.ndarray]:
        """Satellite lines from flat arrays of the epoch: satellite after satellite, each with
        the codes of its system in header order (NaN value / negative indicator = blank).
        All values of the epochs are formatted in one vectorised pass: (the lines, each ended by a newline, one
        after another; the offset of each satellite's line in them and the end, len(svs) + 1)."""
        v = np.asarray(v, dtype=np.float64)
        try:
            lli = _int_or_blank(np.asarray(lli, dtype=np.float64))
            ssi = _int_or_blank(np.asarray(ssi, dtype=np.float64))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"observations: LLI/SSI must be integers or None ({exc})") from exc
        nan = np.isnan(v)
        bad = ~nan & ~((v <= _F14_MAX) & (v >= -_F14_NEG_MAX))
        bad_l, bad_s = lli > 7, ssi > 9
        if bad.any() or bad_l.any() or bad_s.any():
            for mask, what in ((bad, "value does not fit F14.3 (-1e9 < v < 1e10)"), (bad_l, "LLI out of range 0-7"),
                               (bad_s, "SSI out of range 0-9")):
                if mask.any():
                    i = int(np.flatnonzero(mask)[0])
                    sv, code = self._locate(svs, i)
                    raise ValueError(f"observations[{sv!r}][{code!r}]: {what} "
                                     f"(value {v[i]!r}, LLI {lli[i]}, SSI {ssi[i]})")
        fields = _f14_3_words(np.where(nan, 0.0, v), nan)
        chars = fields.view(np.uint8)
        lli_char = _DIGIT_BYTES.take(np.where(nan, -1, np.maximum(lli, -1)) + 1)
        ssi_char = _DIGIT_BYTES.take(np.where(nan, -1, np.maximum(ssi, -1)) + 1)
        chars[:, 14] = lli_char
        chars[:, 15] = ssi_char
        # one row per satellite: its id, its fields (blank up to the widest system's), a column for the newline;
        # trailing blanks dropped: a line ends with its last field with a value (a field without one is blank
        # throughout), at its SSI, LLI or last decimal; a line without a value at its id, as bytes.rstrip ends it
        n_sv = len(svs)
        counts = np.array([self._n_codes[sv[0]] for sv in svs], dtype=np.int64)
        width = 16 * int(counts.max(initial=0))
        rows = np.empty((n_sv, 3 + width + 1), dtype=np.uint8)
        rows[:, :3] = np.frombuffer("".join(svs).encode("ascii"), dtype=np.uint8).reshape(n_sv, 3)
        field_end = np.where(ssi_char != 32, 15, np.where(lli_char != 32, 14, 13))
        uniform = bool(n_sv) and bool((counts == counts[0]).all())
        if uniform:
            rows[:, 3:3 + width] = chars.reshape(n_sv, width)
            has = ~nan.reshape(n_sv, -1)
            j = has.shape[1] - 1 - np.argmax(has[:, ::-1], axis=1)          # each row's last field with a value
            last = np.where(has.any(axis=1), 3 + 16 * j + field_end.reshape(n_sv, -1)[np.arange(n_sv), j], -1)
        else:
            rows[:, 3:] = 32
            first = np.repeat(np.cumsum(counts) - counts, counts)
            r = np.repeat(np.arange(n_sv), counts)
            col = 3 + 16 * (np.arange(len(r)) - first)
            rows[r[:, None], col[:, None] + np.arange(16)] = chars
            last = np.full(n_sv, -1, dtype=np.int64)
            np.maximum.at(last, r[~nan], (col + field_end)[~nan])
        for i in np.flatnonzero(last < 0).tolist():
            last[i] = len(svs[i].encode("ascii").rstrip()) - 1
        rows[np.arange(n_sv), last + 1] = 10
        raw = rows.tobytes()
        starts = np.arange(n_sv) * rows.shape[1]
        text = b"".join([raw[a:b] for a, b in zip(starts.tolist(), (starts + last + 2).tolist())])
        offsets = np.zeros(n_sv + 1, dtype=np.int64)
        np.cumsum(last + 2, out=offsets[1:])
        return text, offsets

    def _locate(self, svs: list[str], i: int) -> tuple[str, str]:
        """(sv, code) of flat index i."""
        for sv in svs:
            n = self._n_codes[sv[0]]
            if i < n:
                return sv, self.obs_types[sv[0]][i]
            i -= n
        return "?", "?"

    def _check_sv(self, sv, where: str) -> None:
        if not isinstance(sv, str) or len(sv) != 3 or sv[0] not in self._code_index:
            raise ValueError(f"{where}: satellite {sv!r} is not an id like 'G05' of a system in the header "
                             f"obs_types ({list(self.obs_types)})")

    def _dict_flat(self, observations: Mapping):
        flat_v, flat_l, flat_s = [], [], []
        svs = list(observations)
        nan = math.nan
        for sv in svs:
            self._check_sv(sv, "observations")
            idx = self._code_index[sv[0]]
            n = self._n_codes[sv[0]]
            base = len(flat_v)
            flat_v.extend([nan] * n)
            flat_l.extend([-1] * n)
            flat_s.extend([-1] * n)
            for code, item in observations[sv].items():
                i = idx.get(code)
                if i is None:
                    raise ValueError(f"observations[{sv!r}]: code {code!r} is not in the header obs_types for "
                                     f"{sv[0]}: {list(idx)}")
                i += base
                if type(item) is tuple:
                    x, a, b = item if len(item) == 3 else (item + (None, None))[:3]
                    if x is not None:
                        flat_v[i] = x
                    if a is not None:
                        flat_l[i] = a
                    if b is not None:
                        flat_s[i] = b
                elif item is not None:
                    flat_v[i] = item
        try:
            v = np.array(flat_v, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"observations: values must be numbers or None ({exc})") from exc
        return svs, v, flat_l, flat_s

    def _array_parts(self, ep: EpochArrays) -> tuple:
        """(satellites, values (N, M), LLI, SSI, layout, ep) of an EpochArrays, its shapes and satellites checked
        against the header; its values are checked and flattened by _arrays_flat."""
        value = np.asarray(ep.value, dtype=np.float64)
        per_sys = isinstance(ep.codes, Mapping)
        svs = list(ep.sv)
        n = len(svs)
        m = len(next(iter(ep.codes.values()))) if per_sys else len(ep.codes)
        if per_sys and any(len(c) != m for c in ep.codes.values()):
            raise ValueError(f"observations.codes: every system needs {m} codes, got {ep.codes!r}")
        if value.shape != (n, m):
            raise ValueError(f"observations.value: shape {value.shape}, expected ({n}, {m}) = (sv, codes)")
        lli = np.full((n, m), -1, np.int64) if ep.lli is None else _int_or_blank(ep.lli)
        ssi = np.full((n, m), -1, np.int64) if ep.ssi is None else _int_or_blank(ep.ssi)
        for name, arr in (("lli", lli), ("ssi", ssi)):
            if arr.shape != (n, m):
                raise ValueError(f"observations.{name}: shape {arr.shape}, expected ({n}, {m})")
        key = (tuple(svs), tuple((s, tuple(c)) for s, c in ep.codes.items()) if per_sys else tuple(ep.codes))
        hit = self._flat_cache.get(key)
        if hit is None:
            hit = self._flat_layout(ep, svs, per_sys, n, m)
            self._flat_cache.put(key, hit)
        return svs, value, lli, ssi, hit, ep

    def _arrays_flat(self, parts: list[tuple]) -> tuple:
        """(flat values, LLI, SSI) of consecutive epochs' _array_parts, one epoch after the other, in one pass;
        a value under a code the header lacks raises naming the first such epoch's satellite and code."""
        value = np.concatenate([p[1].reshape(-1) for p in parts])
        known = np.concatenate([p[4][0].reshape(-1) for p in parts])
        if (~known & ~np.isnan(value)).any():
            for svs, v, _, _, (kn, _, _), ep in parts:
                unknown = ~kn & ~np.isnan(v)
                if unknown.any():
                    sys_rows = [sv[0] for sv in svs]
                    r, j = np.argwhere(unknown)[0]
                    code = ep.codes[sys_rows[r]][j] if isinstance(ep.codes, Mapping) else ep.codes[j]
                    raise ValueError(f"observations: {svs[r]} has a value for {code!r}, not in the header obs_types "
                                     f"for {sys_rows[r]}: {list(self.obs_types[sys_rows[r]])}")
        totals = np.array([p[4][2] for p in parts], dtype=np.int64)
        pos = np.concatenate([p[4][1] for p in parts]) + np.repeat(np.cumsum(totals) - totals,
                                                                   [p[4][1].size for p in parts])
        total = int(totals.sum())
        fv = np.empty(total)               # np.empty + fill: less overhead than np.full
        fv.fill(np.nan)
        fl = np.empty(total, np.int64)
        fl.fill(-1)
        fs = fl.copy()
        fv[pos] = value[known]
        fl[pos] = np.concatenate([p[2].reshape(-1) for p in parts])[known]
        fs[pos] = np.concatenate([p[3].reshape(-1) for p in parts])[known]
        return fv, fl, fs

    def _flat_layout(self, ep: EpochArrays, svs, per_sys: bool, n: int, m: int):
        """(cells with a header code (n, m), their flat positions, flat length) of an epoch's layout."""
        for r, sv in enumerate(svs):
            self._check_sv(sv, f"observations.sv[{r}]")
        sys_rows = [sv[0] for sv in svs]
        counts = np.array([self._n_codes[s] for s in sys_rows], dtype=np.int64)
        offsets = np.cumsum(counts) - counts
        cm = np.empty((n, m), dtype=np.int64)
        sys_arr = np.array(sys_rows)
        for s in dict.fromkeys(sys_rows):
            codes = tuple(ep.codes[s]) if per_sys and s in ep.codes else (None if per_sys else tuple(ep.codes))
            if codes is None:
                raise ValueError(f"observations.codes has no entry for system {s!r}")
            key = (s, codes)
            cmap = self._array_maps.get(key)
            if cmap is None:
                idx = self._code_index[s]
                cmap = np.array([idx.get(c, -1) for c in codes], dtype=np.int64)
                self._array_maps[key] = cmap
            cm[sys_arr == s] = cmap
        known = cm >= 0
        return known, (offsets[:, None] + cm)[known], int(counts.sum())



class RinexObsWriter(EpochFormatter):
    """Write a RINEX 3.04 observation file epoch by epoch (see the module docstring).

    ``path``: output file (overwritten); ``header_info``: a
    :class:`RinexObsHeader` or a dict of its fields; ``fsync``: call
    ``os.fsync`` after each epoch (slower, survives power loss too).
    """

    def __init__(self, path, header_info, fsync: bool = False):
        self.header = RinexObsHeader.from_any(header_info)
        self.header.validate()
        self.path = os.fspath(path)
        self.fsync = bool(fsync)
        super().__init__(self.header.obs_types)
        self._fd: int | None = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._header_written = False
        self._last_obs_offset: int | None = None
        self.t_first: GnssTime | None = None
        self.t_last: GnssTime | None = None
        self.epochs_written = 0

    # ----- context manager ----------------------------------------------
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    # ----- low level -------------------------------------------------------
    def _write_all(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        if self.fsync:
            os.fsync(self._fd)

    def _header_text(self, t_first: GnssTime) -> tuple[str, int | None]:
        h = self.header
        systems = list(h.obs_types)
        sys_char = systems[0] if len(systems) == 1 else "M"
        sys_name = {"G": "GPS", "R": "GLONASS", "E": "Galileo", "C": "BeiDou", "J": "QZSS", "I": "NavIC",
                    "S": "SBAS", "M": "Mixed"}[sys_char]
        now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d %H%M%S UTC")
        lines = [
            _hline(f"{RINEX_VERSION:9.2f}{'':11s}{'OBSERVATION DATA':<20s}{sys_char}: {sys_name}",
                   "RINEX VERSION / TYPE"),
            _hline(f"{h.program:<20s}{h.run_by:<20s}{now:<20s}", "PGM / RUN BY / DATE"),
        ]
        lines += [_hline(c, "COMMENT") for c in h.comments]
        lines.append(_hline(h.marker_name, "MARKER NAME"))
        if h.marker_number:
            lines.append(_hline(h.marker_number, "MARKER NUMBER"))
        lines.append(_hline(h.marker_type, "MARKER TYPE"))
        lines.append(_hline(f"{h.observer:<20s}{h.agency:<40s}", "OBSERVER / AGENCY"))
        lines.append(_hline(f"{h.receiver_number:<20s}{h.receiver_type:<20s}{h.receiver_version:<20s}",
                            "REC # / TYPE / VERS"))
        lines.append(_hline(f"{h.antenna_number:<20s}{h.antenna_type:<20s}", "ANT # / TYPE"))
        x, y, z = (float(v) for v in h.approx_pos_ecef_m)
        lines.append(_hline(f"{x:14.4f}{y:14.4f}{z:14.4f}", "APPROX POSITION XYZ"))
        dh, de, dn = (float(v) for v in h.antenna_delta_hen_m)
        lines.append(_hline(f"{dh:14.4f}{de:14.4f}{dn:14.4f}", "ANTENNA: DELTA H/E/N"))
        # SYS / # / OBS TYPES: A1,2X,I3,13(1X,A3); continuation 6X,13(1X,A3)
        for s, codes in h.obs_types.items():
            for k in range(0, len(codes), 13):
                chunk = "".join(f" {c}" for c in codes[k:k + 13])
                head = f"{s}  {len(codes):3d}" if k == 0 else " " * 6
                lines.append(_hline(head + chunk, "SYS / # / OBS TYPES"))
        if any(c[0] == "S" for codes in h.obs_types.values() for c in codes):
            lines.append(_hline("DBHZ", "SIGNAL STRENGTH UNIT"))
        if h.interval_s is not None:
            lines.append(_hline(f"{h.interval_s:10.3f}", "INTERVAL"))
        lines.append(_time_of_obs_line(t_first, "TIME OF FIRST OBS"))
        last_obs_index = None
        if h.time_of_last_obs:
            last_obs_index = len(lines)
            lines.append(_hline(_LAST_OBS_PLACEHOLDER, "COMMENT"))
        if h.rcv_clock_offset_applied is not None:
            lines.append(_hline(f"{int(bool(h.rcv_clock_offset_applied)):6d}", "RCV CLOCK OFFS APPL"))
        # SYS / PHASE SHIFT: A1,1X,A3,1X,F8.5 (no satellite list: all satellites)
        shifts = h.phase_shifts_cycles
        for s, codes in h.obs_types.items():
            for c in codes:
                if c[0] != "L":
                    continue
                val = 0.0 if shifts is None else shifts.get(s, {}).get(c)
                lines.append(_hline(f"{s} {c}" + ("" if val is None else f" {val:8.5f}"), "SYS / PHASE SHIFT"))
        if "R" in h.obs_types:
            # GLONASS SLOT / FRQ #: I3,1X,8(A3,1X,I2,1X); continuation 4X,8(A3,1X,I2,1X)
            slots = sorted(h.glonass_slots.items())
            if not slots:
                lines.append(_hline(f"{0:3d}", "GLONASS SLOT / FRQ #"))
            for k in range(0, len(slots), 8):
                head = f"{len(slots):3d} " if k == 0 else " " * 4
                body = "".join(f"{sv} {int(ch):2d} " for sv, ch in slots[k:k + 8])
                lines.append(_hline(head + body, "GLONASS SLOT / FRQ #"))
            # GLONASS COD/PHS/BIS: 4(1X,A3,1X,F8.3)
            bis = h.glonass_cod_phs_bis_m or _DEFAULT_GLO_COD_PHS_BIS
            lines.append(_hline("".join(f" {c} {float(v):8.3f}" for c, v in bis.items()), "GLONASS COD/PHS/BIS"))
        if h.leap_seconds:
            lines.append(_hline(f"{gps_minus_utc_at_gps(int(t_first.sec)):6d}", "LEAP SECONDS"))
        lines.append(_hline("", "END OF HEADER"))
        offset = None
        if last_obs_index is not None:
            offset = sum(len(ln) for ln in lines[:last_obs_index])  # ASCII: chars == bytes
        return "".join(lines), offset

    def write_epoch(self, t: GnssTime, observations, clock_offset_s: float | None = None, flag: int = 0) -> None:
        """Append one epoch (time ``t`` in GPS time) and hand it to the OS at once.

        ``observations``: ``{sv: {code: value | (value, lli, ssi)}}`` (lli, ssi
        ints 0-9 or None for blank; value None/NaN for blank), an
        :class:`EpochArrays`, or the :class:`FormattedEpoch` of one (its lines as they are).
        Satellites are written in the given order.
        ``clock_offset_s``: receiver clock offset (F15.12) or None; ``flag``:
        epoch flag 0 (OK) or 1 (power failure since the previous epoch).
        """
        self.write_epochs([t], [observations], None if clock_offset_s is None else [clock_offset_s], flag)

    def write_epochs(self, ts, observations, clock_offsets_s=None, flag: int = 0) -> None:
        """Append several epochs (:meth:`write_epoch` each, in order) and hand them to the OS at once: the
        values of all of them formatted in one vectorised pass.  Nothing is written when one is invalid."""
        if self._fd is None:
            raise ValueError(f"{self.path}: write_epoch() after close()")
        if flag not in (0, 1):
            raise ValueError(f"write_epoch: flag={flag!r}; only 0 (OK) and 1 (power failure) carry observations")
        t_prev = self.t_last
        items = []          # per epoch: its _array_parts (an EpochArrays) or its _dict_flat
        failure = None
        try:
            for t, obs in zip(ts, observations):
                if np.ndim(t.sec) != 0:
                    raise ValueError("write_epoch: t must be a scalar GnssTime")
                if t_prev is not None and not (t - t_prev) > 0:
                    raise ValueError(f"write_epoch: t={t!r} is not after the previous epoch {t_prev!r}")
                t_prev = t
                if isinstance(obs, EpochArrays):
                    items.append(self._array_parts(obs))
                elif isinstance(obs, FormattedEpoch):
                    if obs.key != self.key:
                        raise ValueError(f"write_epoch: a FormattedEpoch of obs_types {obs.key!r}, not the header's")
                    items.append((obs.n_sv, obs))
                elif isinstance(obs, Mapping):
                    items.append(self._dict_flat(obs))
                else:
                    raise ValueError(f"write_epoch: observations must be a dict or EpochArrays, not "
                                     f"{type(obs).__name__}")
                if len(items[-1]) != 2 and len(items[-1][0]) > 999:
                    raise ValueError(f"write_epoch: {len(items[-1][0])} satellites; the epoch record holds at most "
                                     f"999")
        except Exception as exc:        # raised after the values of the epochs before it are checked (below)
            failure = exc
        # the values: runs of EpochArrays flattened together, in epoch order
        # (a FormattedEpoch's item: (satellites, it), its lines formatted already)
        to_format = [it for it in items if len(it) != 2]
        chunks, run = [], []
        for it in to_format + [None]:
            if it is not None and len(it) == 6:     # _array_parts (a _dict_flat has 4 items)
                run.append(it)
                continue
            if run:
                chunks.append(self._arrays_flat(run))
                run = []
            if it is not None:
                chunks.append(it[1:])
        if failure is not None:
            raise failure
        if not items:
            return
        if to_format:
            text, offsets = self._format_rows([sv for it in to_format for sv in it[0]],
                                              *(np.concatenate([c[k] for c in chunks]) for k in (0, 1, 2)))
            offsets = offsets.tolist()
        parts, pos = [], 0
        for k, (t, it) in enumerate(zip(ts, items)):
            formatted = len(it) == 2
            n = it[0] if formatted else len(it[0])
            # Epoch record: A1,1X,I4,4(1X,I2.2),F11.7,2X,I1,I3,6X,F15.12 (RINEX 3.04 table A13)
            y, mo, d, h, mi, s, q = _time_fields(t)
            head = f"> {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d} {s:02d}.{q:07d}  {flag:1d}{n:3d}"
            if clock_offsets_s is not None and clock_offsets_s[k] is not None:
                c = float(clock_offsets_s[k])
                if not (math.isfinite(c) and abs(c) < 1000.0):
                    raise ValueError(f"write_epoch: clock_offset_s={clock_offsets_s[k]!r} does not fit F15.12")
                head += f"      {c:15.12f}"
            parts.append((head + "\n").encode("ascii"))
            if formatted:
                parts.append(it[1].lines)
                continue
            if n:
                parts.append(text[offsets[pos]:offsets[pos + n]])
            pos += n
        if not self._header_written:
            header, self._last_obs_offset = self._header_text(ts[0])
            self._write_all(header.encode("ascii"))
            self._header_written = True
            self.t_first = ts[0]
        self._write_all(b"".join(parts))
        self.t_last = ts[len(items) - 1]
        self.epochs_written += len(items)

    def close(self) -> None:
        """Fill in TIME OF LAST OBS (over the reserved COMMENT line) and close the file.

        A file closed before any epoch holds no header (TIME OF FIRST OBS is
        mandatory and unknown): it stays empty.
        """
        if self._fd is None:
            return
        try:
            if self._last_obs_offset is not None and self.t_last is not None:
                line = _time_of_obs_line(self.t_last, "TIME OF LAST OBS").encode("ascii")
                os.pwrite(self._fd, line, self._last_obs_offset)
                if self.fsync:
                    os.fsync(self._fd)
        finally:
            os.close(self._fd)
            self._fd = None


def _int_or_blank(a) -> np.ndarray:
    """Integer array with -1 (blank) where the input is NaN."""
    a = np.asarray(a)
    if a.dtype.kind == "f":
        a = np.where(np.isfinite(a), a, -1)
    return a.astype(np.int64, copy=False)


def truncate_incomplete_epoch(path) -> int:
    """Cut a torn last epoch (fewer satellite lines than its record announces, or
    no final newline) from an observation file; returns the bytes removed."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"END OF HEADER")
    if end < 0:
        return 0
    body_start = data.find(b"\n", end) + 1
    keep = len(data)
    if not data.endswith(b"\n"):
        keep = data.rfind(b"\n") + 1
    last = data.rfind(b"\n>", body_start - 1, keep)
    start = last + 1 if last >= 0 else (body_start if data[body_start:body_start + 1] == b">" else -1)
    if start >= body_start:
        rec = data[start:keep]
        lines = rec.split(b"\n")[:-1]
        try:
            n = int(lines[0][32:35])
        except (ValueError, IndexError):
            n = -1
        if len(lines) - 1 != n:
            keep = start
    if keep < len(data):
        with open(path, "r+b") as f:
            f.truncate(keep)
    return len(data) - keep

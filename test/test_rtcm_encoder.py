"""RTCM3 encoder (core/rtcm) checked with pyrtcm's independent parser.

pyrtcm decodes every message we write (CRC, field layout, scale factors);
the values it reads back equal ours within the resolution of each data field
(RTCM 10403.3).  RTKLIB's reading of whole simulated runs is in
test_rtcm_rtklib.py.
"""
from __future__ import annotations

import io
import math

import numpy as np
import pytest
from pyrtcm import RTCMReader
from pyrtcm.rtcmhelpers import parse_msm

from gnss_sim_ros2.core import signals as sig
from gnss_sim_ros2.core.rinex.obs_write import EpochArrays, RinexObsHeader
from gnss_sim_ros2.core.rtcm import ephemeris as eph
from gnss_sim_ros2.core.rtcm.frame import BitWriter, RtcmFieldError, frame, message_number, split_frames
from gnss_sim_ros2.core.rtcm.msm import epoch_time_field, lock_indicator_msm4, lock_indicator_msm7
from gnss_sim_ros2.core.rtcm.station import encode_1005
from gnss_sim_ros2.core.rtcm.writer import RtcmWriter
from gnss_sim_ros2.core.time import GnssTime

C_MS = 299792.458            # metres per millisecond of light
T0 = GnssTime.from_iso("2022-01-01T01:00:00")
OBS = {"G": ["C1C", "L1C", "D1C", "S1C", "C2W", "L2W", "D2W", "S2W"],
       "R": ["C1C", "L1C", "D1C", "S1C"],
       "C": ["C2I", "L2I", "D2I", "S2I", "C1P", "L1P", "D1P", "S1P"]}
GLO = {"R07": -3}
POS = (3149785.9652, 598260.8822, 5495348.4927)


def parse_all(data: bytes) -> list:
    return [msg for _, msg in RTCMReader(io.BytesIO(data), quitonerror=2)]


def epoch(k: int, lli_first: int = 1) -> tuple[GnssTime, EpochArrays, dict]:
    """A hand-made epoch k (1 s apart): G05 (L1 C/A, L2 P(Y)), R07 (channel -3), C20 (B1I, B1C).
    Returns (t, arrays, truth {(sv, code): (P, L, D, S)})."""
    t = T0 + float(k)
    truth = {}
    rows = []
    for sv, pr0, dop in (("G05", 21_234_567.891, -1234.5), ("R07", 19_876_543.219, 2345.25),
                         ("C20", 23_456_789.012, 567.75)):
        codes = [c[1:] for c in OBS[sv[0]] if c[0] == "C"]
        row = []
        for j, code in enumerate(codes):
            lam = float(sig.wavelength_m(sv[0], code, GLO.get(sv, 0)))
            pr = pr0 + 3.1 * j + 0.7 * k - dop * lam * k       # inter-signal offset, slow divergence
            phase = (pr - 1.9 * j) / lam + 12345.0               # an arbitrary ambiguity
            d = dop * (sig.frequency_hz(sv[0], code, GLO.get(sv, 0)) / 1575.42e6) + 0.03 * j   # same range rate
            s = 45.3 - 2.2 * j
            truth[(sv, code)] = (pr, phase, d, s)
            row += [pr, phase, d, s]
        rows.append((sv, row))
    width = max(len(r) for _, r in rows)
    value = np.full((3, width), np.nan)
    lli = np.full((3, width), -1)
    for i, (_, r) in enumerate(rows):
        value[i, :len(r)] = r
        lli[i, 1:len(r):4] = lli_first if k == 0 else 0
    codes = {s: list(c) + [f"X{i}Z" for i in range(width - len(c))] for s, c in OBS.items()}
    return t, EpochArrays([sv for sv, _ in rows], codes, value, lli, None), truth


def header(**kw) -> RinexObsHeader:
    return RinexObsHeader(obs_types=OBS, marker_name="TEST", approx_pos_ecef_m=POS, glonass_slots=GLO,
                          antenna_delta_hen_m=(1.234, 0, 0), **kw)


def test_frame_crc_is_what_pyrtcm_checks_and_split_resynchronises():
    w = BitWriter().u(12, 1005).u(12, 7)
    f = frame(w.payload() + bytes(16))
    (msg,) = parse_all(f)
    assert msg.identity == "1005" and message_number(f) == 1005
    bad = bytearray(f)
    bad[5] ^= 0x40
    frames, rest = split_frames(b"\x00\x13garbage" + bytes(bad) + f + f[:7])
    assert frames == [f] and rest == f[:7]
    with pytest.raises(RtcmFieldError, match="DF003"):
        BitWriter().u(12, 4096, "DF003")
    with pytest.raises(RtcmFieldError, match="int8"):
        BitWriter().s(8, 128)
    assert BitWriter().sm(5, -3).payload() == bytes([0b10011000])      # sign-magnitude: 1 0011


def test_lock_time_indicators_follow_rtcm_tables():
    # RTCM 10403.3 table 3.5-76 (DF407): minimum lock time of indicator i
    for i, t_ms in ((0, 0), (63, 63), (64, 64), (95, 126), (96, 128), (128, 256), (160, 512), (704, 67108864)):
        assert lock_indicator_msm7(t_ms) == i, (t_ms, i)
    assert lock_indicator_msm7(127) == 95 and lock_indicator_msm7(10 ** 9) == 704
    # table 3.5-74 (DF402): 0 below 32 ms, 1 from 32 ms, ..., 15 from 524288 ms
    for i, t_ms in ((0, 31), (1, 32), (2, 64), (10, 16384), (15, 524288), (15, 10 ** 8)):
        assert lock_indicator_msm4(t_ms) == i, (t_ms, i)
    ind = [lock_indicator_msm7(t) for t in range(0, 3_000_000, 997)]
    assert ind == sorted(ind)


def test_epoch_time_fields():
    _, tow = T0.week_tow("GPS")
    assert epoch_time_field("G", T0) == round(tow * 1000)
    assert epoch_time_field("C", T0) == round((tow - 14) * 1000)      # BDT = GPS - 14 s
    # 2022-01-01 01:00:00 GPS = 00:59:42 UTC = 03:59:42 Moscow, a Saturday (day 6)
    assert epoch_time_field("R", T0) == (6 << 27) | ((3 * 3600 + 59 * 60 + 42) * 1000)


@pytest.mark.parametrize("msm", [7, 4])
def test_msm_decodes_to_our_observations(msm):
    sink = io.BytesIO()
    w = RtcmWriter(sink, header(), msm=msm, station_id=17)
    decoded = []
    for k in range(3):
        t, arrays, truth = epoch(k)
        data = w.write_epoch(t, arrays)
        decoded.append((truth, [m for m in parse_all(data) if m.ismsm]))
    assert sink.getvalue().endswith(data)
    pr_tol = 0.5 * 2 ** (-29 if msm == 7 else -24) * C_MS * 1.001
    cp_tol = 0.5 * 2 ** (-31 if msm == 7 else -29) * C_MS * 1.001
    offsets = {}
    for k, (truth, msgs) in enumerate(decoded):
        assert [m.identity for m in msgs] == [f"10{7 + j}{msm}" for j in (0, 1)] + [f"112{msm}"]
        assert [m.DF393 for m in msgs] == [1, 1, 0]        # more messages of the epoch follow
        assert all(m.DF003 == 17 for m in msgs)
        seen = set()
        for m in msgs:
            meta, sats, cells = parse_msm(m)
            system = {"GPS": "G", "GLONASS": "R", "BEIDOU": "C"}[meta["gnss"]]
            rough = {s["PRN"]: s for s in sats}
            for c in cells:
                sv = f"{system}{int(c['CELLPRN']):02d}"
                code = c["CELLSIG"]
                pr, phase, dop, cn0 = truth[(sv, code)]
                s = rough[c["CELLPRN"]]
                base_ms = s["DF397"] + s["DF398"]
                lam = float(sig.wavelength_m(system, code, GLO.get(sv, 0)))
                fine_pr = c["DF405"] if msm == 7 else c["DF400"]
                fine_cp = c["DF406"] if msm == 7 else c["DF401"]
                assert abs((base_ms + fine_pr) * C_MS - pr) <= pr_tol, (sv, code)
                cyc = (base_ms + fine_cp) * C_MS / lam
                off = phase - cyc
                assert abs(off - round(off)) * lam <= cp_tol, (sv, code, off)
                offsets.setdefault((sv, code), set()).add(round(off))
                if msm == 7:
                    assert abs(-(s["DF399"] + c["DF404"]) / lam - dop) <= 0.5e-4 / lam * 1.001
                    assert abs(c["DF408"] - cn0) <= 1 / 32 + 1e-9
                    assert c["DF407"] == lock_indicator_msm7(1000 * k)
                    if system == "R":
                        assert s["DF419"] == GLO[sv] + 7
                else:
                    assert abs(c["DF403"] - cn0) <= 0.5
                    assert c["DF402"] == lock_indicator_msm4(1000 * k)
                seen.add((sv, code))
        assert seen == set(truth)
    assert all(len(v) == 1 for v in offsets.values())      # one integer per continuous track


def test_loss_of_lock_restarts_the_lock_time_and_the_phase_offset():
    w = RtcmWriter(io.BytesIO(), header())
    for k in range(4):
        t, arrays, _ = epoch(k)
        if k == 3:
            arrays.lli[0, 1] = 1            # G05 L1: loss of lock
            arrays.value[0, 1] += 17.0      # with a jump of 17 cycles
        msgs = [m for m in parse_all(w.write_epoch(t, arrays)) if m.identity == "1077"]
    _, sats, cells = parse_msm(msgs[0])
    locks = {c["CELLSIG"]: c["DF407"] for c in cells}
    assert locks["1C"] == 0 and locks["2W"] == lock_indicator_msm7(3000)


def test_cells_beyond_64_go_into_several_messages():
    obs = {"C": ["C2I", "C7I", "C6I", "C1P", "C5P"]}
    hdr = RinexObsHeader(obs_types=obs, approx_pos_ecef_m=POS)
    svs = [f"C{p:02d}" for p in range(1, 16)]                 # 15 satellites x 5 signals = 75 cells
    value = 2.2e7 + np.arange(75, dtype=float).reshape(15, 5)
    data = RtcmWriter(io.BytesIO(), hdr).write_epoch(T0, EpochArrays(svs, obs["C"], value))
    msgs = [m for m in parse_all(data) if m.ismsm]
    assert len(msgs) == 2 and [m.DF393 for m in msgs] == [1, 0]
    assert all(m.NSat * len({c["CELLSIG"] for c in parse_msm(m)[2]}) <= 64 for m in msgs)
    got = sorted(int(c["CELLPRN"]) for m in msgs for c in parse_msm(m)[2])
    assert got == sorted(list(range(1, 16)) * 5)


def test_station_message_decodes_to_the_header_position():
    (m,) = parse_all(frame(encode_1005(5, POS, "GRE", antenna_height_m=1.234)))
    assert m.identity == "1006" and m.DF003 == 5
    assert abs(m.DF025 - POS[0]) < 1e-4 and abs(m.DF026 - POS[1]) < 1e-4 and abs(m.DF027 - POS[2]) < 1e-4
    assert abs(m.DF028 - 1.234) < 1e-4


def test_writer_sends_station_messages_then_observations():
    data = RtcmWriter(io.BytesIO(), header()).write_epoch(*epoch(0)[:2])
    ids = [m.identity for m in parse_all(data)]
    assert ids == ["1006", "1033", "1230", "1077", "1087", "1127"]


GPS_RECORD = {"sv": "G05", "time": T0.to_datetime("GPS"), "SVclockBias": -1.2345e-4, "SVclockDrift": 2.1e-12,
              "SVclockDriftRate": 0.0, "IODE": 77, "Crs": -55.4375, "DeltaN": 4.5e-9, "M0": -2.5, "Cuc": -2.9e-6,
              "Eccentricity": 0.0123, "Cus": 8.1e-6, "sqrtA": 5153.65, "Toe": 522000.0, "Cic": 1.1e-7,
              "Omega0": 1.9, "Cis": -5.2e-8, "Io": 0.96, "Crc": 231.5, "omega": 0.7, "OmegaDot": -8.1e-9,
              "IDOT": 3.0e-10, "CodesL2": 1, "GPSWeek": 2190, "L2Pflag": 0, "SVacc": 2.0, "health": 0,
              "TGD": -1.1e-8, "IODC": 77, "TransTime": 518400, "FitIntvl": 4}


def test_gps_ephemeris_decodes_to_the_record():
    (m,) = parse_all(frame(eph.encode_1019(GPS_RECORD)))
    r = GPS_RECORD
    pi = eph.GPS_PI
    assert (m.DF009, m.DF076, m.DF071, m.DF085, m.DF077) == (5, 2190 % 1024, 77, 77, 0)
    assert m.DF081 == 522000 and m.DF093 == 522000
    for df, v, lsb in (("DF092", r["sqrtA"], 2 ** -19), ("DF090", r["Eccentricity"], 2 ** -33),
                       ("DF086", r["Crs"], 2 ** -5), ("DF084", r["SVclockBias"], 2 ** -31),
                       ("DF101", r["TGD"], 2 ** -31), ("DF089", r["Cuc"], 2 ** -29)):
        assert abs(getattr(m, df) - v) <= lsb / 2 * 1.001, df
    for df, v, lsb in (("DF088", r["M0"], 2 ** -31), ("DF095", r["Omega0"], 2 ** -31),
                       ("DF097", r["Io"], 2 ** -31), ("DF100", r["OmegaDot"], 2 ** -43)):
        assert abs(getattr(m, df) * pi - v) <= lsb * pi / 2 * 1.001, df     # pyrtcm: semicircles


def test_accuracy_indices():
    assert [eph.ura_index(v) for v in (2.0, 2.4, 2.5, 6000.0, 7000.0)] == [0, 0, 1, 14, 15]
    assert [eph.sisa_index(v) for v in (0.3, 0.6, 1.2, 3.12, 7.0, -1.0)] == [30, 55, 80, 107, 255, 255]


def test_bad_input_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="9A"):
        RtcmWriter(io.BytesIO(), RinexObsHeader(obs_types={"I": ["C9A"]}))
    with pytest.raises(ValueError, match="MSM4 or MSM7"):
        RtcmWriter(io.BytesIO(), header(), msm=5)
    with pytest.raises(ValueError, match="station_id"):
        RtcmWriter(io.BytesIO(), header(), station_id=5000)
    with pytest.raises(ValueError, match="sink"):
        RtcmWriter(42, header())
    with pytest.raises(ValueError, match="cannot open"):
        RtcmWriter(tmp_path / "no" / "such" / "dir.rtcm3", header())
    w = RtcmWriter(tmp_path / "a.rtcm3", header())
    t, arrays, _ = epoch(0)
    w.write_epoch(t, arrays)
    with pytest.raises(ValueError, match="not after"):
        w.write_epoch(t, arrays)
    w.close()
    with pytest.raises(ValueError, match="after close"):
        w.write_epoch(t + 1.0, arrays)
    assert (tmp_path / "a.rtcm3").stat().st_size > 0
    w = RtcmWriter(io.BytesIO(), RinexObsHeader(obs_types={"R": ["C1C", "L1C"]}))
    with pytest.raises(ValueError, match="R07 has no frequency channel"):
        w.write_epoch(T0, {"R07": {"C1C": 2.0e7, "L1C": 1.0e8}})
    with pytest.raises(ValueError, match="does not fit"):
        eph.encode_1019({**GPS_RECORD, "IODE": 300})
    with pytest.raises(ValueError, match="field 'sqrtA' missing"):
        eph.encode_record("G", {k: v for k, v in GPS_RECORD.items() if k != "sqrtA"})


def test_dict_observations_as_the_rinex_writer_takes_them():
    w = RtcmWriter(io.BytesIO(), header())
    data = w.write_epoch(T0, {"G05": {"C1C": (21e6, None, 7), "L1C": (1.1e8, 1, 7), "S1C": 44.0}})
    (m,) = [m for m in parse_all(data) if m.ismsm]
    meta, sats, cells = parse_msm(m)
    assert [c["CELLSIG"] for c in cells] == ["1C"] and math.isclose(cells[0]["DF408"], 44.0)
    assert abs((sats[0]["DF397"] + sats[0]["DF398"] + cells[0]["DF405"]) * C_MS - 21e6) < 1e-3

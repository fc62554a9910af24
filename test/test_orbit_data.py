"""Unusable or damaged orbit data (issue 14, items 4 and 5): a clear error before anything is written, a
warning naming file:line for each dropped record, warnings naming satellites and spans for SP3 gaps and
missing satellites, and consecutive broadcast records checked against each other."""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris
from gnss_sim_ros2.core.ephemeris.coverage import EphemerisCoverageError, EphemerisCoverageWarning
from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
from gnss_sim_ros2.core.ephemeris.synthetic import write_synthetic_nav
from gnss_sim_ros2.core.rinex.nav import NavDataWarning, header_dict, read_nav_file, records_as_dicts
from gnss_sim_ros2.core.rinex.nav_write import write_rinex3_nav
from gnss_sim_ros2.core.time import GnssTime

T0 = GnssTime.from_iso("2025-06-01T00:00:00")
SP3_NAME = "COD0MGXFIN_20220010000_01D_05M_ORB.SP3"
OPEC_T0 = GnssTime.from_iso("2022-01-01T01:00:00")


@pytest.fixture
def nav_g(tmp_path):
    """A synthetic GPS navigation file covering T0 .. T0 + 6 h (records every 2 h)."""
    return write_synthetic_nav(tmp_path / "synthetic_gps.rnx", T0 - 7200.0, 8 * 3600.0, systems="G")


def _rewrite(nav_path, out, edit):
    """Copy of a navigation file with ``edit(system, record dict)`` applied to every record."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nav = read_nav_file(nav_path)
    recs = records_as_dicts(nav)
    for s, lst in recs.items():
        for d in lst:
            edit(s, d)
    return write_rinex3_nav(out, recs, header_dict(nav))


def _record_lines(path):
    """(line number, sv, epoch text) of each record's first line."""
    out = []
    for n, ln in enumerate(path.read_text().splitlines(), start=1):
        m = re.match(r"^([GRECJI]\d\d) (\d{4} \d\d \d\d \d\d \d\d \d\d)", ln)
        if m:
            out.append((n, m.group(1), m.group(2)))
    return out


# ------------------------------------------------------------------------------------------ item 4
def test_all_unhealthy_is_an_error_naming_file_and_span(nav_g, tmp_path):
    bad = _rewrite(nav_g, tmp_path / "unhealthy.rnx", lambda s, d: d.__setitem__("health", 63.0))
    with pytest.raises(EphemerisCoverageError) as exc:
        open_ephemeris("broadcast", T0, 600.0, "G", nav_files=[bad])
    msg = str(exc.value)
    assert str(bad) in msg and "2025-06-01 00:00:00 .. 2025-06-01 00:10:00" in msg
    assert "unhealthy" in msg
    # the same file healthy serves the span
    prov, _ = open_ephemeris("broadcast", T0, 600.0, "G", nav_files=[nav_g])
    assert len(prov.states(T0)) >= 4


def test_span_outside_the_records_is_an_error(nav_g):
    with pytest.raises(ValueError, match=r"no usable ephemeris for 2025-06-03 00:00:00 .. 2025-06-03 01:00:00") as exc:
        open_ephemeris("broadcast", T0 + 2 * 86400.0, 3600.0, "G", nav_files=[nav_g])
    assert str(nav_g) in str(exc.value) and "no record of systems G within hours of the span" in str(exc.value)


def test_system_absent_from_the_file_is_an_error(nav_g):
    with pytest.raises(EphemerisCoverageError, match="systems E"):
        open_ephemeris("broadcast", T0, 600.0, "E", nav_files=[nav_g])


def test_non_numeric_field_drops_the_record_with_file_and_line(nav_g, tmp_path):
    lines = nav_g.read_text().splitlines(keepends=True)
    firsts = _record_lines(nav_g)
    for n, _, _ in firsts:                         # the Crs field (line 2 of the record, 2nd field) of each record
        ln = lines[n]                              # 0-based index n = the record's second line
        lines[n] = ln[:23] + "  not-a-number     " + ln[42:]
    bad = tmp_path / "letters.rnx"
    bad.write_text("".join(lines))
    with pytest.warns(NavDataWarning) as rec:
        with pytest.raises(EphemerisCoverageError, match="no usable ephemeris"):
            open_ephemeris("broadcast", T0, 600.0, "G", nav_files=[bad])
    msgs = [str(w.message) for w in rec if issubclass(w.category, NavDataWarning)]
    assert len(msgs) == len(firsts)
    n, sv, ep = firsts[0]
    expect = f"{bad}:{n + 1}: {sv} record {ep[:4]}-{ep[5:7]}-{ep[8:10]} {ep[11:13]}:{ep[14:16]}:{ep[17:19]} dropped"
    assert any(m.startswith(expect) and "'not-a-number' is not a number" in m for m in msgs), msgs[:2]


def test_one_bad_field_drops_only_that_record(nav_g, tmp_path):
    lines = nav_g.read_text().splitlines(keepends=True)
    n, sv, _ = _record_lines(nav_g)[3]
    lines[n + 2] = lines[n + 2][:4] + "        1.2.3      " + lines[n + 2][23:]
    bad = tmp_path / "one_bad.rnx"
    bad.write_text("".join(lines))
    with pytest.warns(NavDataWarning, match=rf"{re.escape(str(bad))}:{n + 3}: {sv} record .* dropped"):
        nav = read_nav_file(bad)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        good = read_nav_file(nav_g)
    assert len(nav.tables["G"]) == len(good.tables["G"]) - 1


def _opec_sp3_copy(opec_dir, tmp_path, drop_epochs=(), drop_sv=None):
    """Copy of the CODE SP3 without some epoch blocks and/or without one satellite's P lines."""
    src = opec_dir / SP3_NAME
    out, skip, n_epoch = [], False, -1
    for ln in src.read_text().splitlines(keepends=True):
        if ln.startswith("* "):
            n_epoch += 1
            skip = n_epoch in drop_epochs
        if skip and (ln.startswith("* ") or ln.startswith("P") or ln.startswith("V")):
            continue
        if drop_sv and ln.startswith("P" + drop_sv):
            continue
        out.append(ln)
    path = tmp_path / "gap.sp3"
    path.write_text("".join(out))
    return path


def test_sp3_gap_is_a_warning_naming_satellites_and_span(opec_dir, tmp_path):
    # epochs 13..17 (01:05 .. 01:25, 5 min spacing) removed: a 30 min hole between 01:00 and 01:30
    path = _opec_sp3_copy(opec_dir, tmp_path, drop_epochs=range(13, 18))
    with pytest.warns(EphemerisCoverageWarning) as rec:
        open_ephemeris("sp3", OPEC_T0, 3600.0, "GE", sp3_files=[path])
    msgs = [str(w.message) for w in rec if issubclass(w.category, EphemerisCoverageWarning)]
    gap = [m for m in msgs if "no satellite has an ephemeris" in m or "without ephemeris over part" in m]
    assert gap, msgs
    assert any(str(path) in m and "G01" in m + " ".join(msgs) for m in gap)
    span = re.search(r"(2022-01-01 \d\d:\d\d:\d\d) \.\. (2022-01-01 \d\d:\d\d:\d\d) GPST", gap[0])
    assert span, gap[0]
    a, b = GnssTime.from_iso(span.group(1).replace(" ", "T")), GnssTime.from_iso(span.group(2).replace(" ", "T"))
    assert a.to_gps_seconds() <= GnssTime.from_iso("2022-01-01T01:05:00").to_gps_seconds()
    assert b.to_gps_seconds() >= GnssTime.from_iso("2022-01-01T01:25:00").to_gps_seconds()
    assert (b - a) <= 45 * 60


def test_sp3_missing_satellite_is_a_warning(opec_dir, tmp_path):
    path = _opec_sp3_copy(opec_dir, tmp_path, drop_sv="G07")
    nav = [opec_dir / "OPEC00NOR_S_20220010000_01D_GN.rnx"]
    with pytest.warns(EphemerisCoverageWarning) as rec:
        prov, _ = open_ephemeris("sp3", OPEC_T0, 600.0, "G", sp3_files=[path], nav_files=nav)
    msgs = [str(w.message) for w in rec if issubclass(w.category, EphemerisCoverageWarning)]
    assert any("listed without any position: G07" in m for m in msgs), msgs
    assert any("not in the SP3 files" in m and "G07" in m for m in msgs), msgs
    assert "G07" not in prov.svs("G")


def test_sp3_with_leading_blank_lines_reads(opec_dir, tmp_path):
    from gnss_sim_ros2.core.ephemeris.sp3 import read_sp3

    src = opec_dir / SP3_NAME
    path = tmp_path / "blank_first.sp3"
    path.write_text("\n\n" + src.read_text())
    t, svs, pos, _ = read_sp3(path)
    t_ref, svs_ref, pos_ref, _ = read_sp3(src)
    assert svs == svs_ref and np.array_equal(np.isnan(pos), np.isnan(pos_ref))
    empty = tmp_path / "empty.sp3"
    empty.write_text("\n\n")
    with pytest.raises(ValueError, match="empty.sp3: empty file"):
        read_sp3(empty)


# ------------------------------------------------------------------------------------------ item 5
def _corrupt_one(nav_g, tmp_path, field, value, health=0.0):
    """Copy with the 3rd record of G01 changed (and given ``health``); returns (path, sv, epoch text)."""
    target = {}

    def edit(s, d):
        if d["sv"] == "G01":
            target["k"] = target.get("k", -1) + 1
            if target["k"] == 2:
                d[field] = value(d[field])
                d["health"] = health
                target["time"] = d["time"]

    out = _rewrite(nav_g, tmp_path / f"corrupt_{field}.rnx", edit)
    return out, "G01", target["time"].strftime("%Y-%m-%d %H:%M:%S")


def test_outlier_record_dropped_whatever_its_health(nav_g, tmp_path):
    # M0 + 0.3 rad: the record puts G01 about 8,000 km along its orbit from where its neighbours put it
    path, sv, when = _corrupt_one(nav_g, tmp_path, "M0", lambda v: v + 0.3)
    line = next(n for n, s, e in _record_lines(path) if s == sv and e == re.sub(r"[-:]", " ", when))
    with pytest.warns(NavDataWarning, match=rf"{re.escape(str(path))}:{line}: G01 record {when} dropped: its orbit is "
                      r"\d+\.\d km from"):
        eph = BroadcastEphemeris.from_files([path])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = BroadcastEphemeris.from_files([nav_g])
    assert len(eph.records("G")) == len(ref.records("G")) - 1
    # at the corrupted record's toe the satellite is where the good file puts it (a neighbouring record)
    t = GnssTime.from_iso(when.replace(" ", "T"))
    a, b = eph.states(t, svs=["G01"]), ref.states(t, svs=["G01"])
    assert len(a) == 1 and np.linalg.norm(a.pos_ecef_m - b.pos_ecef_m) < 50.0


def test_impossible_orbit_dropped_with_warning(nav_g, tmp_path):
    path, sv, when = _corrupt_one(nav_g, tmp_path, "sqrtA", lambda v: 1000.0)
    with pytest.warns(NavDataWarning, match=rf"G01 record {when} dropped: impossible orbit"):
        eph = BroadcastEphemeris.from_files([path])
    assert 1000.0 not in eph.records("G")["sqrt_a"]


def test_consistent_records_are_all_kept(nav_g):
    with warnings.catch_warnings():
        warnings.simplefilter("error", NavDataWarning)
        eph = BroadcastEphemeris.from_files([nav_g])
    assert not eph.nav.dropped


def test_real_broadcast_files_trigger_only_the_bad_records(shared_data):
    """OPEC 2022-001 (four systems), HK 2019-118 (GPS, BeiDou), 2012-305 (GPS, GLONASS): no record dropped.
    VILL00ESP 2018-170 (georinex test data): four BeiDou-3 test satellites' records (C20, C27, C29; flagged
    unhealthy in 2018) tens of thousands of km from their neighbours; ELKO00USA 2018-210: C16 records with
    sqrtA ~1,000 m^0.5 (an orbit of 1,000 km)."""
    clean = sorted((shared_data / "opec-2022-001").glob("*N.rnx")) + [
        shared_data / "hk-tst-2019-118-urban-drive" / "hksc1180.19n",
        shared_data / "hk-tst-2019-118-urban-drive" / "hksc1180.19b",
        shared_data / "tle-2012-305" / "brdc3050.12n", shared_data / "tle-2012-305" / "brdc3050.12g"]
    for p in clean:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            eph = BroadcastEphemeris.from_files([p])
        assert not eph.nav.dropped, (p, eph.nav.dropped[:3])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vill = BroadcastEphemeris.from_files([shared_data / "nav-formats-georinex"
                                              / "VILL00ESP_R_20181700000_01D_MN.rnx.gz"])
        elko = BroadcastEphemeris.from_files([shared_data / "nav-formats-georinex"
                                              / "ELKO00USA_R_20182100000_01D_MN.rnx.gz"])
    assert len(vill.nav.dropped) == 4
    assert sorted(m.split(": ")[1].split()[0] for m in vill.nav.dropped) == ["C20", "C20", "C27", "C29"]
    assert all("km from" in m for m in vill.nav.dropped)
    assert len(elko.nav.dropped) == 4 and all("C16" in m and "impossible orbit" in m for m in elko.nav.dropped)

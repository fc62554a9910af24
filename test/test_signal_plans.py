"""Signal plans per satellite and date (core/signal_plans) and QZSS health per signal (core/ephemeris/health.py).

Expectations come from public metadata and the ICDs, not from running the code: GPS IIR satellites transmit
no L2C and no L5, IIF ones both (IS-GPS-200N, IS-GPS-705J); G18 / G23 were reassigned from IIR/IIA satellites
to GPS III ones in 2020 (IGS satellite metadata); B2I is a BeiDou-2 signal, B1C/B2a BeiDou-3 ones (BDS-OS-PS
3.0); a QZS whose health is 1 (the L1C/B bit, IS-QZSS-PNT-005 5.4.1) stays usable on L1C/A, L2C and L5.
"""
from __future__ import annotations

import gzip
import shutil

import numpy as np
import pytest

from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris
from gnss_sim_ros2.core.ephemeris.health import record_usable, signal_usable
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.signal_plans import PLANS_PATH, SignalPlanError, default_plans, gps_day, load_plans, parse_plans
from gnss_sim_ros2.core.time import GnssTime

ESBC_ECEF_M = np.array([3582105.2910, 532589.7313, 5232754.8054])
#: GPS satellites on 2020-06-25 by block (IGS metadata: PRIDE table/sat_parameters, plans.yaml's source)
GPS_IIR_2020 = {"G02", "G11", "G13", "G14", "G16", "G19", "G20", "G21", "G22", "G28"}
GPS_IIF_2020 = {"G01", "G03", "G06", "G08", "G09", "G10", "G24", "G25", "G26", "G27", "G30", "G32"}


def _day(iso: str) -> int:
    return gps_day(GnssTime.from_iso(iso, scale="GPS").sec)


def test_gps_blocks_and_reassigned_prns_by_date():
    p = default_plans()
    d = _day("2020-06-25T12:00:00")
    for sv in GPS_IIR_2020:
        assert p.codes(sv, ("1C", "2W", "2L", "5Q"), d) == ["1C", "2W"], sv
    for sv in GPS_IIF_2020:
        assert p.codes(sv, ("1C", "2W", "2L", "5Q", "1L"), d) == ["1C", "2W", "2L", "5Q"], sv
    # G18: IIA SVN34 until 2020-03-09, GPS III SVN75 from 2020-03-13; G23: IIR-B SVN60 until 2020-06-09, GPS III
    # SVN76 from 2020-07-14; G14: IIR-A SVN41 until 2020-07-27, GPS III SVN77 from 2020-11-05
    assert p.codes("G18", ("1C", "2L", "5Q", "1L"), _day("2019-06-01T00:00:00")) == ["1C"]
    assert p.codes("G18", ("1C", "2L", "5Q", "1L"), _day("2020-06-25T00:00:00")) == ["1C", "2L", "5Q", "1L"]
    assert p.generation("G23", _day("2020-06-01T00:00:00")) == "GPS-IIR-B"
    assert p.generation("G23", _day("2020-08-01T00:00:00")) == "GPS-IIIA"
    assert p.generation("G14", _day("2020-06-25T00:00:00")) == "GPS-IIR-A"
    assert p.generation("G14", _day("2021-01-01T00:00:00")) == "GPS-IIIA"
    # vectorised over rows, one instant or one per row
    t = float(GnssTime.from_iso("2020-06-25T00:00:00", scale="GPS").sec)
    np.testing.assert_array_equal(p.mask(["G14", "G01", "G01", "G14"], ["2L", "2L", "5Q", "1C"], t),
                                  [False, True, True, True])
    t2 = np.array([t, t + 200 * 86400.0])
    np.testing.assert_array_equal(p.mask(["G14", "G14"], ["2L", "2L"], t2), [False, True])


def test_beidou_2_and_3_glonass_cdma_galileo_e20():
    p = default_plans()
    d = _day("2020-06-25T00:00:00")
    bds = ("2I", "7I", "6I", "1P", "5P", "7D")
    for sv in ("C01", "C05", "C06", "C11", "C14", "C16"):      # BeiDou-2 GEO, IGSO, MEO
        assert p.codes(sv, bds, d) == ["2I", "7I", "6I"], sv
    for sv in ("C19", "C23", "C38", "C46"):                    # BeiDou-3 MEO, IGSO
        assert p.codes(sv, bds, d) == ["2I", "6I", "1P", "5P", "7D"], sv
    assert p.codes("C59", bds, d) == ["2I", "6I", "7D"]        # BeiDou-3 GEO: no B1C/B2a, no B2I
    glo = ("1C", "2C", "3Q")
    assert p.codes("R01", glo, d) == ["1C", "2C"]              # GLONASS-M: FDMA only
    assert p.codes("R09", glo, d) == ["1C", "2C", "3Q"]        # GLONASS-K1B (R802): L3OC
    assert p.codes("R21", glo, d) == ["1C", "2C", "3Q"]        # GLONASS-M+ (R855): L3OC
    assert p.codes("R15", glo, d) == ["1C", "2C"]              # R857: a GLONASS-M without L3
    assert p.codes("E20", ("1C", "5Q", "7Q", "6C"), d) == ["1C"]    # IOV FM4 lost E5/E6 in 2014
    assert p.codes("E20", ("1C", "5Q"), _day("2013-06-01T00:00:00")) == ["1C", "5Q"]


def test_unknown_satellites_take_the_documented_default():
    p = default_plans()
    d = _day("2020-06-25T00:00:00")
    assert p.generation("G23", d) == "GPS-IIIA"     # G23 unassigned on that day (between SVN60 and SVN76)
    assert p.generation("G40", d) == "GPS-IIIA"
    assert p.generation("C17", d) == "BDS-2I"       # BeiDou PRN plan: C01-C18 BeiDou-2
    assert p.generation("C55", d) == "BDS-3M-CAST"
    assert p.generation("C63", d) == "BDS-3G"
    assert p.generation("R30", d) == "GLO-M"
    assert p.codes("I03", ("5A", "9A"), d) == ["5A", "9A"]


def _plans_doc():
    return {"gnss_sim_signal_plans": 1,
            "generations": {s: {"X": {"signals": [n]}} for s, n in
                            (("G", "L1 C/A"), ("R", "G1 C/A"), ("E", "E1 OS"), ("C", "B1I"), ("J", "L1 C/A"),
                             ("I", "L5 SPS"))},
            "defaults": {s: [{"prns": [1, 63], "generation": "X"}] for s in "GRECJI"},
            "satellites": {"G01": [["2020-01-01", None, "G063", "X"]]}}


def test_malformed_plan_files_give_a_clear_error(tmp_path):
    parse_plans(_plans_doc(), "ok.yaml")         # the minimal document is valid
    cases = [
        (("generations", "G", "X", "signals"), ["L9 Z"], r"bad\.yaml: key 'generations\.G\.X\.signals': 'L9 Z'"),
        (("defaults", "C"), None, r"key 'defaults\.C': missing"),
        (("satellites", "G01"), [["2020-13-01", None, "G063", "X"]], r"key 'satellites\.G01\[0\]': '2020-13-01'"),
        (("satellites", "G01"), [["2020-01-01", None, "G063", "IIZ"]], r"key 'satellites\.G01\[0\]': generation"),
        (("gnss_sim_signal_plans",), 2, r"key 'gnss_sim_signal_plans': expected 1"),
    ]
    for path, value, msg in cases:
        doc = _plans_doc()
        node = doc
        for k in path[:-1]:
            node = node[k]
        if value is None:
            del node[path[-1]]
        else:
            node[path[-1]] = value
        with pytest.raises(SignalPlanError, match=msg):
            parse_plans(doc, "bad.yaml")
    bad = tmp_path / "plans.yaml"
    bad.write_text("gnss_sim_signal_plans: 1\ngenerations: [\n")
    with pytest.raises(SignalPlanError, match=r"plans\.yaml: not valid YAML"):
        load_plans(bad)
    with pytest.raises(SignalPlanError, match="cannot read"):
        load_plans(tmp_path / "absent.yaml")
    assert load_plans(PLANS_PATH) is default_plans()        # loaded once


def test_qzss_health_bits():
    # IS-QZSS-PNT-005 5.4.1: 0x20 L1, 0x10 L1C/A, 0x08 L2C, 0x04 L5, 0x02 L1C, 0x01 L1C/B
    np.testing.assert_array_equal(record_usable(["J", "G", "E", "J", "J"], [1, 1, 0, 0x3E, 0x20]),
                                  [True, False, True, False, True])
    assert signal_usable("J", 1, "1C") and signal_usable("J", 1, "2L") and signal_usable("J", 1, "5Q")
    assert not signal_usable("J", 0x10, "1C") and signal_usable("J", 0x10, "2L")
    assert not signal_usable("J", 0x20, "1C") and not signal_usable("J", 0x20, "1L")
    assert signal_usable("J", 0x20, "5Q") and not signal_usable("J", 0x04, "5Q")
    assert not signal_usable("G", 1, "1C")


@pytest.fixture(scope="module")
def esbc_nav(shared_data, tmp_path_factory):
    """The ESBC mixed navigation file of 2020-06-25 (IGS), decompressed, with J02's health set to 1."""
    src = shared_data / "esbc-2020-177-polarx5" / "ESBC00DNK_R_20201770000_01D_MN.rnx.gz"
    if not src.is_file():
        pytest.skip(f"{src} is absent")
    d = tmp_path_factory.mktemp("esbc")
    plain = d / "ESBC_MN.rnx"
    with gzip.open(src, "rb") as f, open(plain, "wb") as g:
        shutil.copyfileobj(f, g)
    lines = plain.read_text().splitlines(keepends=True)
    out, n_j02, k = [], 0, None
    for line in lines:
        if line.startswith("J02 "):
            k = 0
        elif k is not None:
            k += 1
            if k == 6:     # broadcast orbit 6: SV accuracy, health, TGD, IODC (RINEX 3.05 A9)
                line = line[:23] + f"{1.0:19.12E}" + line[42:]
                n_j02 += 1
                k = None
        out.append(line)
    assert n_j02 > 0
    (d / "ESBC_J02_health1.rnx").write_text("".join(out))
    return plain, d / "ESBC_J02_health1.rnx"


def _tracked_pairs(nav, iso="2020-06-25T00:00:00", n_epochs=20, **config):
    t0 = GnssTime.from_iso(iso, scale="GPS")
    prov = BroadcastEphemeris.from_files([nav], start=t0 - 3600.0, end=t0 + 3600.0)
    # an explicit signal list (the shipped profiles may change): L2C, L5, B2I, B1C where the plans allow them
    profile = {"G": ["1C", "2L", "5Q"], "R": ["1C"], "E": ["1C"], "C": ["2I", "7I", "1P"], "J": ["1C", "2L", "5Q"]}
    rcv = Receiver(ReceiverConfig(systems="GRECJ", profile=profile, noise=False, elevation_mask_deg=0.0, **config),
                   prov, prov.iono)
    pairs = set()
    for i in range(n_epochs):
        t = t0 + 1.0 * i
        obs = rcv.epoch(t, ESBC_ECEF_M, prov.states(t, systems="GRECJ"))
        pairs |= set(zip(obs.sv.tolist(), obs.code.tolist()))
    return prov, pairs


def test_receiver_builds_rows_only_for_transmitted_signals(esbc_nav):
    plain, _ = esbc_nav
    _, pairs = _tracked_pairs(plain)
    tracked = {sv for sv, _ in pairs}
    iir = GPS_IIR_2020 & tracked
    iif = GPS_IIF_2020 & tracked
    assert iir and iif
    assert not {(sv, c) for sv, c in pairs if sv in iir and c in ("2L", "5Q")}
    assert all((sv, "2L") in pairs and (sv, "5Q") in pairs for sv in iif)
    bds2 = {sv for sv in tracked if sv[0] == "C" and int(sv[1:]) <= 16}
    bds3 = {sv for sv in tracked if sv[0] == "C" and 19 <= int(sv[1:]) <= 46}
    assert bds2 and bds3
    assert not {(sv, c) for sv, c in pairs if sv in bds2 and c in ("1P", "5P")}
    assert not {(sv, c) for sv, c in pairs if sv in bds3 and c == "7I"}
    assert all((sv, "7I") in pairs for sv in bds2) and all((sv, "1P") in pairs for sv in bds3)


def test_qzss_health_1_is_kept(esbc_nav):
    _, patched = esbc_nav
    # QZSS is low seen from Denmark: J02 at 8.7 deg at 20:00 GPST
    prov, pairs = _tracked_pairs(patched, "2020-06-25T20:00:00")
    t0 = GnssTime.from_iso("2020-06-25T20:00:00", scale="GPS")
    st = prov.states(t0, systems="J")
    assert "J02" in st.sv.tolist() and int(st.health[st.index_of("J02")]) == 1
    assert {("J02", "1C"), ("J02", "2L"), ("J02", "5Q")} <= pairs


def test_a_profiles_excluded_signals_drop_only_those_satellite_signals(esbc_nav):
    """excluded_signals (a profile's, e.g. fitted by calibrate: a receiver skipping B3I or L2C on some
    satellites) removes exactly the (satellite, signal) pairs its expressions match; other signals of those
    satellites and the signal on other satellites stay."""
    plain, _ = esbc_nav
    _, pairs = _tracked_pairs(plain)
    bds2 = sorted({sv for sv, c in pairs if c == "7I"})
    iif = sorted({sv for sv, c in pairs if c == "5Q" and sv[0] == "G"})
    assert len(bds2) >= 2 and len(iif) >= 2
    _, fewer = _tracked_pairs(plain, excluded_signals={"C7I": bds2[0], "G5Q": "|".join(iif[:2])})
    assert pairs - fewer == {(bds2[0], "7I"), (iif[0], "5Q"), (iif[1], "5Q")}
    assert fewer <= pairs


@pytest.mark.parametrize("value, says", [({"C9Z": "C20"}, "C9Z"), ({"C6I": "C(20"}, "C6I"), ("C20", "mapping")])
def test_bad_excluded_signals_are_named(value, says):
    with pytest.raises(ValueError, match="excluded_signals") as err:
        ReceiverConfig(excluded_signals=value)
    assert says in str(err.value)

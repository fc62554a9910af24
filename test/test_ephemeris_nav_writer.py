"""write_rinex3_nav: round trip of the OPEC broadcast files through georinex, format
rules of RINEX 3.04, and an end-to-end check with RTKLIB (rnx2rtkp) on real observations.

georinex 1.16 turns a record with a blank field inside it into NaN (every Galileo
and BeiDou record of the OPEC files: their spare fields are blank), so the test
reads a copy whose blank inner fields are written as zeros (text-level only).
"""
from __future__ import annotations

import datetime as dt
import re
import shutil
import subprocess
import warnings

import georinex  # noqa: E402
import numpy as np
import pytest

from gnss_sim_ros2.core.rinex.nav_write import FIELDS, d19, records_from_georinex, write_rinex3_nav

STATION_ECEF_M = np.array([3149785.9652, 598260.8822, 5495348.4927])  # OPEC header / data README
NAV = "OPEC00NOR_S_20220010000_01D_{}N.rnx"
OBS = "OPEC00NOR_S_20220010000_0340_30S_MO.rnx"


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return georinex.load(path)


def _fill_blank_fields(src, dst):
    """Copy of a RINEX 3 nav file with blank 19-character fields (before the last value of a line) set to 0."""
    out, in_header = [], True
    for ln in src.read_text().splitlines():
        if in_header:
            out.append(ln)
            in_header = "END OF HEADER" not in ln
            continue
        start = 23 if ln[:1].strip() else 4
        body = ln[start:].rstrip()
        fields = [body[k:k + 19] for k in range(0, len(body), 19)]
        out.append(ln[:start] + "".join(f if f.strip() else " 0.000000000000E+00" for f in fields))
    dst.write_text("\n".join(out) + "\n")
    return dst


@pytest.fixture(scope="module")
def loaded(opec_dir, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("navin")
    return {s: _load(_fill_blank_fields(opec_dir / NAV.format(s), tmp / f"{s}.rnx")) for s in "GECR"}


@pytest.mark.parametrize("system", list("GECR"))
def test_round_trip_through_georinex(loaded, tmp_path, system):
    ds = loaded[system]
    recs = records_from_georinex(ds)
    n_in = int(np.isfinite(ds["SVclockBias"].values).sum())
    assert n_in > 0 and len(recs[system]) == n_in
    header = {k: v for k, v in ds.attrs.items() if k.startswith("ionospheric_corr")}
    out = write_rinex3_nav(tmp_path / f"{system}.rnx", recs, {**header, "LEAP SECONDS": 18})
    ds2 = _load(out)
    assert sorted(ds2.sv.values) == sorted(ds.sv.values)
    ds2 = ds2.sel(time=ds.time, sv=ds.sv)
    for name in FIELDS[system]:
        if name.startswith("spare"):
            continue
        a, b = ds[name].values, ds2[name].values
        # every value exact: the written 13 significant digits are those of the file
        assert np.array_equal(a, b, equal_nan=True), f"{system} {name}: max diff {np.nanmax(np.abs(a - b))}"
    for k, v in header.items():
        np.testing.assert_array_equal(np.ravel(ds2.attrs[k]), np.ravel(v))


def test_rinex304_layout(loaded, tmp_path):
    recs = {}
    for s in "GECR":
        recs.update(records_from_georinex(loaded[s]))
    hdr = {"IONOSPHERIC CORR": {"GPSA": [1.2107e-08, -7.4506e-09, -5.9605e-08, 1.1921e-07],
                                "GPSB": [1.1674e05, -2.4576e05, -6.5536e04, 1.1141e06],
                                "GAL": [87.75, 0.41797, -0.010742],
                                "BDSA": [1.0e-08, 2.0e-08, -1.0e-07, 1.0e-07],
                                "BDSB": [1.0e05, 0.0, -1.0e05, 2.0e05]},
           "TIME SYSTEM CORR": {"GPUT": [2.7939677238e-09, 7.993605777e-15, 147456, 2191]},
           "LEAP SECONDS": 18, "comments": ["synthetic test"]}
    p = write_rinex3_nav(tmp_path / "mixed.rnx", recs, hdr)
    lines = p.read_text().splitlines()
    assert lines[0][:9] == "     3.04" and lines[0][20] == "N" and lines[0][40] == "M"
    assert lines[0][60:] == "RINEX VERSION / TYPE"
    end = next(i for i, ln in enumerate(lines) if ln[60:] == "END OF HEADER")
    for ln in lines[:end + 1]:
        assert len(ln) <= 80 and ln[60:].strip(), ln
    from georinex.nav3 import navheader3

    hdr_read = navheader3(p)
    assert hdr_read["IONOSPHERIC CORR"]["BDSA"] == pytest.approx([1.0e-08, 2.0e-08, -1.0e-07, 1.0e-07])
    assert hdr_read["IONOSPHERIC CORR"]["GAL"] == pytest.approx([87.75, 0.41797, -0.010742])
    a0, a1, tref, week = hdr_read["TIME SYSTEM CORR"]["GPUT"]
    assert (a0, a1, tref, week) == (pytest.approx(2.7939677238e-09), pytest.approx(7.993605777e-15), 147456, 2191)
    assert int(hdr_read["LEAP SECONDS"]) == 18
    epoch = re.compile(r"^[GRECJI]\d\d \d{4}( \d\d){5}(( |-)\d\.\d{12}E[+-]\d\d){3}$")
    cont = re.compile(r"^    (( |-)\d\.\d{12}E[+-]\d\d){1,4}$")
    i, counts = end + 1, {}
    while i < len(lines):
        assert epoch.match(lines[i]), lines[i]
        s = lines[i][0]
        n = 3 if s == "R" else 7
        for ln in lines[i + 1:i + 1 + n]:
            assert cont.match(ln), ln
        counts[s] = counts.get(s, 0) + 1
        i += 1 + n
    assert counts == {s: len(recs[s]) for s in "GECR"}


def test_qzss_navic_glonass_records(tmp_path):
    """Hand-made records of every system read back by georinex (QZSS like GPS; NavIC; GLONASS in m -> km)."""
    t = dt.datetime(2022, 1, 1, 2, 0, 0)
    kepler = dict(SVclockBias=-5.035293288529e-04, SVclockDrift=-2.728484105319e-12, SVclockDriftRate=0.0,
                  Crs=-8.65625, DeltaN=5.173786937564e-09, M0=-2.315157581206e-01, Cuc=-4.135072231293e-07,
                  Eccentricity=7.5e-02, Cus=8.381903171539e-06, sqrtA=6.493275e03, Toe=525600.0,
                  Cic=4.284083843231e-08, Omega0=2.113095554454, Cis=1.154839992523e-07, Io=7.155849933176e-01,
                  Crc=204.5625, omega=-1.570796326795, OmegaDot=-8.298917111780e-09, IDOT=-5.953819429049e-10,
                  TGD=3.725290298462e-09, TransTime=518418.0, health=0.0)
    recs = {
        "J": [dict(kepler, sv="J02", time=t, IODE=94.0, IODC=94.0, CodesL2=1.0, GPSWeek=2190.0, L2Pflag=0.0,
                   SVacc=2.0, FitIntvl=2.0)],
        "I": [dict(kepler, sv="I03", time=t, IODEC=12.0, IRNWeek=1166.0, URA=4.0, Eccentricity=2.0e-3)],
        "R": [dict(sv="R07", time=t.replace(minute=15), SVclockBias=-6.282329559326e-05, SVrelFreqBias=0.0,
                   MessageFrameTime=518418.0, X=7423335.449219, dX=-2488.239288330, dX2=1.862645149231e-06,
                   health=0.0, Y=13748865.72266, dY=-1186.802864075, dY2=-2.793967723846e-06, FreqNum=5.0,
                   Z=20222990.23438, dZ=1721.749305725, dZ2=-9.313225746155e-07, AgeOpInfo=0.0)],
    }
    p = write_rinex3_nav(tmp_path / "jir.rnx", recs, {})
    ds = _load(p)
    for s, (sv, rec) in {"J": ("J02", recs["J"][0]), "I": ("I03", recs["I"][0]), "R": ("R07", recs["R"][0])}.items():
        got = ds.sel(sv=sv).dropna("time", how="all")
        assert got.time.values[0] == np.datetime64(rec["time"])
        for name in FIELDS[s]:
            if name.startswith("spare"):
                continue
            want = rec.get(name, rec.get("IRNWeek") if name == "BDTWeek" else 0.0)
            assert float(got[name].values[0]) == pytest.approx(want, rel=1e-12, abs=1e-300), f"{sv} {name}"


def test_d19_field():
    assert d19(-5.035293288529e-04) == "-5.035293288529E-04"
    assert d19(2190) == " 2.190000000000E+03"
    assert d19(float("nan")) == " 0.000000000000E+00"
    assert d19(1e-120) == " 0.000000000000E+00"  # 3-digit exponents do not fit D19.12


def test_bad_records_are_named(tmp_path):
    t = dt.datetime(2022, 1, 1)
    with pytest.raises(ValueError, match=r"records_by_system\['G'\]\[1\].*G5"):
        write_rinex3_nav(tmp_path / "x.rnx", {"G": [{"sv": "G05", "time": t}, {"sv": "G5", "time": t}]}, {})
    with pytest.raises(ValueError, match="unsupported system"):
        write_rinex3_nav(tmp_path / "x.rnx", {"S": [{"sv": "S20", "time": t}]}, {})
    with pytest.raises(ValueError, match="Crs"):
        write_rinex3_nav(tmp_path / "x.rnx", {"G": [{"sv": "G05", "time": t, "Crs": "abc"}]}, {})
    with pytest.raises(ValueError, match="GPSA"):
        write_rinex3_nav(tmp_path / "x.rnx", {"G": [{"sv": "G05", "time": t}]},
                         {"IONOSPHERIC CORR": {"GPSA": [1.0, 2.0]}})


def _rnx2rtkp(tmp_path, obs, navs, navsys):
    conf = tmp_path / f"single_{navsys}.conf"
    # single point, 10 deg mask, broadcast Klobuchar (header of the nav file), Saastamoinen
    conf.write_text(f"pos1-navsys ={navsys}\npos1-posmode =single\npos1-elmask =10\n"
                    "pos1-ionoopt =brdc\npos1-tropopt =saas\n")
    out = tmp_path / f"sol_{navsys}_{len(navs)}.pos"
    subprocess.run(["rnx2rtkp", "-k", str(conf), "-ti", "300", "-e", "-o", str(out), str(obs), *map(str, navs)],
                   check=True, capture_output=True, timeout=120)
    rows = [ln.split() for ln in out.read_text().splitlines() if ln and not ln.startswith("%")]
    return rows


@pytest.mark.skipif(shutil.which("rnx2rtkp") is None, reason="RTKLIB rnx2rtkp is not installed")
def test_rtklib_single_point_with_merged_file(loaded, opec_dir, tmp_path):
    """RTKLIB reads our merged GPS+Galileo+BeiDou file and computes the same solution as from the
    station's own three files; the solution is within a few metres of the marker.

    BeiDou is read but not used (navsys G+E): RTKLIB 2.4.3 b34 gives no BeiDou solution on these
    observations even with the station's own files."""
    recs, header = {}, {}
    for s in "GEC":
        recs.update(records_from_georinex(loaded[s]))
        header.update({k: v for k, v in loaded[s].attrs.items() if k.startswith("ionospheric_corr")})
    merged = write_rinex3_nav(tmp_path / "GEC.rnx", recs, {**header, "LEAP SECONDS": 18})
    obs = opec_dir / OBS
    for navsys in (1, 8, 9):  # GPS, Galileo, GPS+Galileo (RTKLIB SYS_* bits)
        ours = _rnx2rtkp(tmp_path, obs, [merged], navsys)
        theirs = _rnx2rtkp(tmp_path, obs, [opec_dir / NAV.format(s) for s in "GEC"], navsys)
        assert len(ours) == 44  # 00:00 .. 03:35 every 300 s
        assert [r[:5] for r in ours] == [r[:5] for r in theirs]  # identical to the printed 0.1 mm
        xyz = np.array([[float(v) for v in r[2:5]] for r in ours])
        err = np.linalg.norm(xyz - STATION_ECEF_M, axis=1)
        print(f"navsys {navsys}: mean offset {np.linalg.norm(xyz.mean(axis=0) - STATION_ECEF_M):.2f} m, "
              f"max {err.max():.2f} m")
        assert np.linalg.norm(xyz.mean(axis=0) - STATION_ECEF_M) < 5.0
        assert err.max() < 15.0

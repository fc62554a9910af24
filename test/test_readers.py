"""Readers meet every file they may be given (issue 14, item 6): the georinex test files, Galileo RINEX 2,
SBAS-only and blank files, SP3 with leading blank lines, RINEX 2 observation files in ``compare``, and
.gz / .Z / Hatanaka compressed files read directly."""
from __future__ import annotations

import gzip
import warnings

import hatanaka  # a declared dependency (requirements/python.txt): an import error fails
import ncompress  # installed with georinex; the readers use it for .Z files
import numpy as np
import pytest

from gnss_sim_ros2.core.comparison import compare, load_observations
from gnss_sim_ros2.core.ephemeris.sp3 import Sp3Ephemeris
from gnss_sim_ros2.core.rinex.nav import NavDataWarning, read_nav_file

OPEC_OBS = "OPEC00NOR_S_20220010000_0340_30S_MO.rnx"


@pytest.fixture(scope="module")
def formats_dir(shared_data):
    d = shared_data / "nav-formats-georinex"
    if not d.is_dir():
        pytest.skip(f"{d} is absent")
    return d


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if "sp3" in path.name.lower():
            return Sp3Ephemeris.from_files([path], require_clock=False)
        return read_nav_file(path)


def test_every_georinex_file_loads_or_fails_clearly(formats_dir):
    files = sorted(p for p in formats_dir.iterdir() if p.name != "LICENSE.georinex")
    assert len(files) >= 25
    loaded, failed = [], {}
    for p in files:
        try:
            _load(p)
            loaded.append(p.name)
        except ValueError as exc:
            assert str(p) in str(exc), (p.name, str(exc))     # the message names the file
            failed[p.name] = str(exc)
    # the failures are the files with nothing to simulate: blank, or SP3 too short to interpolate
    assert set(failed) == {"blank.10n", "blank3.10n", "example1.sp3a", "minimal.sp3c", "minimal.sp3d",
                           "truncated.sp3"}, failed
    assert "blank file" in failed["blank.10n"] and "blank file" in failed["blank3.10n"]
    assert all("fewer than the 11 interpolation points" in failed[n] for n in
               ("example1.sp3a", "minimal.sp3c", "minimal.sp3d", "truncated.sp3"))
    assert len(loaded) == len(files) - 6


def test_galileo_rinex2(formats_dir):
    nav = _load(formats_dir / "ceda2100.18e")
    assert nav.versions == [2.12] and len(nav.tables["E"]) > 20
    assert set(nav.tables) == {"E"}


def test_sbas_records_skipped_with_a_note(formats_dir):
    with pytest.warns(NavDataWarning, match=r"demo_nav3.10n: 2 SBAS records skipped \(SBAS is not simulated\)"):
        nav = read_nav_file(formats_dir / "demo_nav3.10n")
    assert not nav.tables and sum(nav.skipped.values()) == 2
    with pytest.warns(NavDataWarning, match="SBAS records skipped"):
        mixed = read_nav_file(formats_dir / "VILL00ESP_R_20181700000_01D_MN.rnx.gz")
    assert {"G", "R", "E", "C"} <= set(mixed.tables)


def test_sp3_starting_with_a_blank_line(formats_dir):
    path = formats_dir / "igs19362.sp3c"
    assert not path.read_text().splitlines()[0].strip()
    eph = _load(path)
    assert len(eph.svs("G")) == 32


def test_navigation_z_and_gz_read_directly(opec_dir, tmp_path):
    src = opec_dir / "OPEC00NOR_S_20220010000_01D_GN.rnx"
    (tmp_path / "n.rnx.gz").write_bytes(gzip.compress(src.read_bytes()))
    (tmp_path / "n.rnx.Z").write_bytes(ncompress.compress(src.read_bytes()))
    ref = _load(src)
    for name in ("n.rnx.gz", "n.rnx.Z"):
        nav = _load(tmp_path / name)
        assert np.array_equal(nav.tables["G"].raw, ref.tables["G"].raw), name


# ------------------------------------------------------------------------------------------ observations
def _rinex2_copy(tab, path, n_epochs=6):
    """The GPS C1C/L1C/C2W/L2W observations of ``tab`` as a RINEX 2.11 file (C1 L1 P2 L2)."""
    codes = [("C1", "C1C"), ("L1", "L1C"), ("P2", "C2W"), ("L2", "L2W")]
    gps = [j for j, s in enumerate(tab.sv.tolist()) if s[0] == "G"]
    x, y, z = tab.approx_pos_ecef_m
    t0 = tab.time[0].astype("datetime64[s]").astype(object)
    lines = ["     2.11           OBSERVATION DATA    G (GPS)             RINEX VERSION / TYPE",
             f"{x:14.4f}{y:14.4f}{z:14.4f}                  APPROX POSITION XYZ",
             f"{len(codes):6d}" + "".join(f"    {c}" for c, _ in codes) + " " * (54 - 6 * len(codes))
             + "# / TYPES OF OBSERV",
             f"{t0.year:6d}{t0.month:6d}{t0.day:6d}{t0.hour:6d}{t0.minute:6d}{t0.second:13.7f}     GPS         "
             "TIME OF FIRST OBS",
             " " * 60 + "END OF HEADER"]
    for e in range(n_epochs):
        t = tab.time[e].astype("datetime64[s]").astype(object)
        sats = [j for j in gps if np.isfinite(tab.values["C1C"][e, j])]
        names = "".join(tab.sv[j] for j in sats)
        head = f" {t.year % 100:02d} {t.month:2d} {t.day:2d} {t.hour:2d} {t.minute:2d}{t.second:11.7f}  0{len(sats):3d}"
        lines.append(head + names[:36])
        for k in range(36, len(names), 36):
            lines.append(" " * 32 + names[k:k + 36])
        for j in sats:
            vals = [tab.values[c3][e, j] if c3 in tab.values else np.nan for _, c3 in codes]
            lines.append("".join(f"{v:14.3f}  " if np.isfinite(v) else " " * 16 for v in vals).rstrip())
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def opec_obs(opec_dir):
    return opec_dir / OPEC_OBS


def test_rinex2_observations_in_compare(opec_obs, tmp_path):
    tab = load_observations(opec_obs)
    r2 = _rinex2_copy(tab, tmp_path / "opec0010.22o")
    t2 = load_observations(r2)
    assert len(t2.time) == 6 and {"C1C", "L1C", "C2W", "L2W"} <= set(t2.values)
    cmp = compare(opec_obs, r2)
    labels = {p.label for p in cmp.pairs}
    assert {"G 1C", "G 2W"} <= labels
    code = cmp.kinds["code"]
    d = np.concatenate([v[np.isfinite(v)] for v in code.residuals.values()])
    assert d.size > 50 and np.abs(d).max() < 2e-3     # the same numbers, rounded to 1 mm by F14.3


@pytest.mark.slow
def test_compressed_and_hatanaka_observations(opec_obs, tmp_path):
    ref = load_observations(opec_obs)
    text = opec_obs.read_bytes()
    text += b"" if text.endswith(b"\n") else b"\r\n"      # the file's last line has no line end; RNX2CRX needs it
    files = {"gz": tmp_path / (OPEC_OBS + ".gz"), "crx": tmp_path / OPEC_OBS.replace(".rnx", ".crx"),
             "crx.gz": tmp_path / OPEC_OBS.replace(".rnx", ".crx.gz")}
    files["gz"].write_bytes(gzip.compress(text))
    crx = hatanaka.rnx2crx(text)
    files["crx"].write_bytes(crx)
    files["crx.gz"].write_bytes(gzip.compress(crx))
    r2 = _rinex2_copy(ref, tmp_path / "opec0010.22o")
    files["22d"] = tmp_path / "opec0010.22d"
    files["22d"].write_bytes(hatanaka.rnx2crx(r2.read_bytes()))
    for kind, p in files.items():
        tab = load_observations(p)
        base = load_observations(r2) if kind == "22d" else ref
        assert np.array_equal(tab.time, base.time), kind
        assert np.allclose(tab.approx_pos_ecef_m, base.approx_pos_ecef_m), kind
        for c, a in base.values.items():
            assert np.array_equal(np.isnan(tab.values[c]), np.isnan(a)) and np.allclose(
                tab.values[c][np.isfinite(a)], a[np.isfinite(a)]), (kind, c)


def test_blank_observation_file_is_an_error(tmp_path):
    p = tmp_path / "blank.rnx"
    p.write_text("\n")
    with pytest.raises(ValueError, match="blank.rnx"):
        load_observations(p)

"""RINEX 3.04 observation writer, checked with independent readers.

- georinex (an independent Python RINEX reader) reads back what was written;
- RTKLIB (Debian's rnx2rtkp/convbin, C) reads it too: the single point
  solution from our rewrite of a real receiver file equals the solution from
  the original file, and convbin reads every epoch of a file whose writer was
  SIGKILLed mid-run.
"""
from __future__ import annotations

import datetime as dt
import math
import shutil
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import georinex  # noqa: E402
import numpy as np
import pytest

from gnss_sim_ros2.core.rinex.obs_write import (
    EpochArrays,
    EpochFormatter,
    RinexObsHeader,
    RinexObsWriter,
    ssi_from_cn0,
    truncate_incomplete_epoch,
)
from gnss_sim_ros2.core.time import GnssTime

REPO_ROOT = Path(__file__).resolve().parents[1]
OPEC_OBS = "OPEC00NOR_S_20220010000_0340_30S_MO.rnx"
OPEC_NAV_G = "OPEC00NOR_S_20220010000_01D_GN.rnx"
T0 = GnssTime.from_iso("2022-01-01T00:00:00", scale="GPS")


def _load(path, **kw):
    """georinex.load with its (harmless, very chatty) xarray FutureWarnings silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        return georinex.load(path, useindicators=True, **kw)


def _obs_lines(path) -> list[str]:
    return Path(path).read_text().splitlines()


def _header_labels(path) -> list[str]:
    out = []
    for ln in _obs_lines(path):
        out.append(ln[60:].strip())
        if "END OF HEADER" in ln:
            break
    return out


# ---------------------------------------------------------------------------
# synthetic epochs (shared with the child process of the kill test)
# ---------------------------------------------------------------------------
SYN_TYPES = {"G": ["C1C", "L1C", "D1C", "S1C"], "E": ["C1C", "L1C", "D1C", "S1C"]}
SYN_SVS = [f"G{i:02d}" for i in range(1, 13)] + [f"E{i:02d}" for i in range(1, 11)]


def synthetic_epoch(k: int):
    """Deterministic observations of epoch k: {sv: {code: (value, lli, ssi)}}, and the C/N0 used."""
    obs, cn0 = {}, {}
    for j, sv in enumerate(SYN_SVS):
        c = 20.0 + ((7 * j + 3 * k) % 35)  # 20..54 dB-Hz
        rng = 2.0e7 + 1.0e5 * j + 123.456 * k + 0.001 * j
        cn0[sv] = c
        ssi = min(max(int(c / 6), 1), 9)  # RINEX 3.04 section 5.7
        obs[sv] = {
            "C1C": (rng, None, ssi),
            "L1C": (rng / 0.19029367279836487 + 0.5, (j + k) % 2, ssi),
            "D1C": (-1234.567 + 10.0 * j - 0.5 * k, None, ssi),
            "S1C": (c, None, None),
        }
        if j == 3:
            del obs[sv]["D1C"]  # a missing observation -> blanks
    return obs, cn0


CHILD = r"""
import sys, time
sys.path.insert(0, {repo!r}); sys.path.insert(0, {testdir!r})
from test_rinex_obs import synthetic_epoch, SYN_TYPES, T0
from gnss_sim_ros2.core.rinex.obs_write import RinexObsWriter, RinexObsHeader
w = RinexObsWriter({path!r}, RinexObsHeader(obs_types=SYN_TYPES, interval_s=1.0))
for k in range(100000):
    w.write_epoch(T0 + k, synthetic_epoch(k)[0], clock_offset_s=1e-6 * k)
    print(k, flush=True)
    time.sleep(0.002)
"""


def test_vectorised_f14_3_matches_python_formatting():
    from gnss_sim_ros2.core.rinex.obs_write import _f14_3_chars

    rng = np.random.default_rng(7)
    v = np.concatenate([rng.uniform(-999999999.0, 999999999.0, 20000), rng.uniform(-10, 10, 20000),
                        rng.uniform(0, 9999999999.0, 20000), np.round(rng.uniform(-1e8, 1e8, 20000), 3),
                        [0.0, 1.0, -0.0004, 2.0625, -2.0625, 0.9995, 9.9999996, 9999999999.999, -999999999.999]])
    got = [r.tobytes().decode() for r in _f14_3_chars(v)]
    exp = [f"{x:14.3f}" for x in v]  # Python's correctly rounded formatting is the reference
    assert got == exp


def test_ssi_from_cn0_spec_table():
    # RINEX 3.04 5.7: 1 <12 dB-Hz, 2 12-17, ..., 9 >=54
    assert ssi_from_cn0(5.0) == 1
    assert ssi_from_cn0(12.0) == 2
    assert ssi_from_cn0(17.99) == 2
    assert ssi_from_cn0(45.0) == 7
    assert ssi_from_cn0(54.0) == 9
    assert ssi_from_cn0(70.0) == 9
    np.testing.assert_array_equal(ssi_from_cn0([0.0, 36.0, np.nan]), [1, 6, 0])


def test_synthetic_roundtrip_georinex(tmp_path):
    path = tmp_path / "syn.rnx"
    hdr = RinexObsHeader(obs_types=SYN_TYPES, interval_s=1.0, marker_name="ROBOT1",
                         approx_pos_ecef_m=(3149785.9652, 598260.8822, 5495348.4927))
    n = 5
    with RinexObsWriter(path, hdr) as w:
        for k in range(n):
            w.write_epoch(T0 + k + 0.5, synthetic_epoch(k)[0], clock_offset_s=-2.5e-4 + 1e-7 * k)
    d = _load(path)
    assert d.sizes["time"] == n
    exp_times = [np.datetime64(dt.datetime(2022, 1, 1, 0, 0, k, 500000)) for k in range(n)]
    np.testing.assert_array_equal(d.time.values.astype("datetime64[us]"), exp_times)
    np.testing.assert_allclose(d.attrs["time_offset"], [-2.5e-4 + 1e-7 * k for k in range(n)], atol=1e-12)
    np.testing.assert_allclose(d.attrs["position"], hdr.approx_pos_ecef_m, atol=1e-4)
    for k in range(n):
        obs, _ = synthetic_epoch(k)
        for sv, o in obs.items():
            for code in SYN_TYPES[sv[0]]:
                got = float(d[code].sel(sv=sv).values[k])
                if code not in o:
                    assert math.isnan(got), (sv, code)
                    continue
                v, lli, ssi = o[code]
                assert got == pytest.approx(v, abs=0.0005 + 1e-9), (k, sv, code)  # F14.3 rounding
                got_ssi = d[code + "ssi"].sel(sv=sv).values[k]
                assert (math.isnan(got_ssi) if ssi is None else got_ssi == ssi), (k, sv, code)
            assert d["L1Clli"].sel(sv=sv).values[k] == o["L1C"][1]
    labels = _header_labels(path)
    assert "TIME OF LAST OBS" in labels
    last = [ln for ln in _obs_lines(path) if "TIME OF LAST OBS" in ln][0]
    assert [float(x) for x in last[:43].split()] == [2022, 1, 1, 0, 0, 4.5]


def test_array_input_equals_dict_input(tmp_path):
    obs, _ = synthetic_epoch(3)
    codes = ["S1C", "C1C", "L1C", "D1C"]  # a column order different from the header's
    svs = list(obs)
    val = np.full((len(svs), 4), np.nan)
    lli = np.full((len(svs), 4), -1)
    ssi = np.full((len(svs), 4), -1)
    for r, sv in enumerate(svs):
        for j, c in enumerate(codes):
            if c in obs[sv]:
                v, li, si = obs[sv][c]
                val[r, j] = v
                lli[r, j] = -1 if li is None else li
                ssi[r, j] = -1 if si is None else si
    p1, p2 = tmp_path / "a.rnx", tmp_path / "b.rnx"
    hdr = RinexObsHeader(obs_types=SYN_TYPES)
    with RinexObsWriter(p1, hdr) as w:
        w.write_epoch(T0, obs)
    with RinexObsWriter(p2, hdr, fsync=True) as w:
        w.write_epoch(T0, EpochArrays(svs, codes, val, lli, ssi))
    body = lambda p: [ln for ln in _obs_lines(p) if "PGM / RUN BY" not in ln]  # noqa: E731
    assert body(p1) == body(p2)


def _epoch_arrays(k: int, drop: int = 0) -> EpochArrays:
    """synthetic_epoch(k) as EpochArrays in header column order, its first ``drop`` satellites left out."""
    obs, _ = synthetic_epoch(k)
    svs = list(obs)[drop:]
    codes = {s: SYN_TYPES[s] for s in SYN_TYPES}
    val, lli, ssi = np.full((len(svs), 4), np.nan), np.full((len(svs), 4), -1), np.full((len(svs), 4), -1)
    for r, sv in enumerate(svs):
        for j, c in enumerate(codes[sv[0]]):
            if c in obs[sv]:
                v, li, si = obs[sv][c]
                val[r, j], lli[r, j], ssi[r, j] = v, -1 if li is None else li, -1 if si is None else si
    return EpochArrays(svs, codes, val, lli, ssi)


def test_epochs_of_several_files_formatted_together(tmp_path):
    """Three files' epochs formatted in one pass (EpochFormatter.format_arrays, as the fleet's receivers are) and
    written as FormattedEpoch give each file the bytes of its EpochArrays written alone; a FormattedEpoch of other
    obs_types and an epoch that does not fit are refused."""
    hdr = RinexObsHeader(obs_types=SYN_TYPES, interval_s=1.0)
    fmt = EpochFormatter(SYN_TYPES)
    alone = [RinexObsWriter(tmp_path / f"alone{i}.rnx", hdr) for i in range(3)]
    together = [RinexObsWriter(tmp_path / f"together{i}.rnx", hdr) for i in range(3)]
    for k in range(4):
        arrays = [_epoch_arrays(k + 10 * i, drop=i * (k + 1)) for i in range(3)]   # satellite sets differ
        for w, a in zip(alone, arrays):
            w.write_epoch(T0 + k, a, clock_offset_s=1e-6 * k)
        for w, f in zip(together, fmt.format_arrays(arrays)):
            w.write_epoch(T0 + k, f, clock_offset_s=1e-6 * k)
    for w in alone + together:
        w.close()
    body = lambda p: [ln for ln in _obs_lines(p) if "PGM / RUN BY" not in ln]  # noqa: E731
    for i in range(3):
        assert body(tmp_path / f"alone{i}.rnx") == body(tmp_path / f"together{i}.rnx")
    other = EpochFormatter({"G": SYN_TYPES["G"]})
    gps = _epoch_arrays(0)
    gps = EpochArrays(gps.sv[:12], {"G": SYN_TYPES["G"]}, gps.value[:12], gps.lli[:12], gps.ssi[:12])
    with RinexObsWriter(tmp_path / "other.rnx", hdr) as w, pytest.raises(ValueError, match="obs_types"):
        w.write_epoch(T0, other.format_arrays([gps])[0])
    bad = _epoch_arrays(0)
    bad.value[0, 0] = 1e12
    with pytest.raises(ValueError, match="does not fit F14.3"):
        fmt.format_arrays([_epoch_arrays(1), bad])


def test_epoch_time_rounding_carry(tmp_path):
    path = tmp_path / "t.rnx"
    with RinexObsWriter(path, RinexObsHeader(obs_types={"G": ["C1C"]})) as w:
        # 23:59:59.99999999 rounds (7 decimals) to the next day 00:00:00.0000000
        w.write_epoch(GnssTime.from_iso("2021-12-31T23:59:59") + 0.99999999, {"G01": {"C1C": 2e7}})
    ep = [ln for ln in _obs_lines(path) if ln.startswith(">")]
    assert ep == ["> 2022 01 01 00 00 00.0000000  0  1"]


def test_bad_input_errors(tmp_path):
    with pytest.raises(ValueError, match="obs_types"):
        RinexObsWriter(tmp_path / "x.rnx", {"obs_types": {"G": ["C1"]}})
    with pytest.raises(ValueError, match="unknown system"):
        RinexObsWriter(tmp_path / "x.rnx", {"obs_types": {"Z": ["C1C"]}})
    with pytest.raises(ValueError, match="marker_name"):
        RinexObsWriter(tmp_path / "x.rnx", {"obs_types": {"G": ["C1C"]}, "marker_name": "x" * 61})
    w = RinexObsWriter(tmp_path / "x.rnx", {"obs_types": {"G": ["C1C"]}})
    with pytest.raises(ValueError, match="'E01'"):
        w.write_epoch(T0, {"E01": {"C1C": 2e7}})
    with pytest.raises(ValueError, match="'L1C'"):
        w.write_epoch(T0, {"G01": {"L1C": 2e7}})
    with pytest.raises(ValueError, match="F14.3"):
        w.write_epoch(T0, {"G01": {"C1C": 1e11}})
    with pytest.raises(ValueError, match="LLI"):
        w.write_epoch(T0, {"G01": {"C1C": (2e7, 8, None)}})
    w.write_epoch(T0, {"G01": {"C1C": 2e7}})
    with pytest.raises(ValueError, match="not after"):
        w.write_epoch(T0, {"G01": {"C1C": 2e7}})
    w.close()
    with pytest.raises(ValueError, match="after close"):
        w.write_epoch(T0 + 1, {"G01": {"C1C": 2e7}})


def test_truncate_incomplete_epoch(tmp_path):
    path = tmp_path / "torn.rnx"
    with RinexObsWriter(path, RinexObsHeader(obs_types=SYN_TYPES)) as w:
        for k in range(3):
            w.write_epoch(T0 + k, synthetic_epoch(k)[0])
    full = path.read_bytes()
    assert truncate_incomplete_epoch(path) == 0
    cut = full.rfind(b"\n>") + 200  # inside the last epoch's satellite lines
    path.write_bytes(full[:cut])
    removed = truncate_incomplete_epoch(path)
    assert removed == cut - (full.rfind(b"\n>") + 1)
    assert _load(path).sizes["time"] == 2


@pytest.mark.skipif(shutil.which("convbin") is None, reason="RTKLIB convbin is not installed")
def test_sigkill_mid_run_leaves_valid_file(tmp_path):
    path = tmp_path / "killed.rnx"
    code = CHILD.format(repo=str(REPO_ROOT), testdir=str(Path(__file__).parent), path=str(path))
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        for line in proc.stdout:
            if int(line) >= 20:
                break
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    n_rec = sum(1 for ln in _obs_lines(path) if ln.startswith(">"))
    assert n_rec >= 21
    assert truncate_incomplete_epoch(path) == 0  # no torn epoch
    labels = _header_labels(path)
    assert "TIME OF FIRST OBS" in labels and "TIME OF LAST OBS" not in labels  # placeholder is a COMMENT
    # georinex reads every complete epoch, with the values written
    d = _load(path)
    assert d.sizes["time"] == n_rec
    for k in (0, n_rec - 1):
        obs, _ = synthetic_epoch(k)
        for sv in ("G01", "E10"):
            assert float(d["C1C"].sel(sv=sv).values[k]) == pytest.approx(obs[sv]["C1C"][0], abs=5e-4)
            assert float(d["D1C"].sel(sv=sv).values[k]) == pytest.approx(obs[sv]["D1C"][0], abs=5e-4)
    # RTKLIB reads it: convbin RINEX -> RINEX keeps every epoch
    out = tmp_path / "rtklib.obs"
    r = subprocess.run(["convbin", "-r", "rinex", str(path), "-o", str(out), "-v", "3.04"],
                       capture_output=True, text=True, timeout=60)
    assert out.is_file(), r.stderr
    n_rtk = sum(1 for ln in _obs_lines(out) if ln.startswith(">"))
    assert n_rtk == n_rec


# ---------------------------------------------------------------------------
# real receiver file: georinex reads back the same values, RTKLIB the same SPP
# ---------------------------------------------------------------------------
N_EPOCHS = 60


def _opec_header(path: Path) -> RinexObsHeader:
    hdr = georinex.rinexheader(path)
    slots = {}
    for ln in _obs_lines(path):
        if "GLONASS SLOT / FRQ #" in ln:
            toks = ln[4:60].split()
            slots.update({toks[i]: int(toks[i + 1]) for i in range(0, len(toks) - 1, 2)})
        if "END OF HEADER" in ln:
            break
    return RinexObsHeader(
        obs_types=hdr["fields"], marker_name="OPEC", receiver_number="5423R48819",
        receiver_type="TRIMBLE NETR9", antenna_number="31050604", antenna_type="TRM55971.00",
        approx_pos_ecef_m=hdr["position"], interval_s=30.0, glonass_slots=slots,
        comments=["rewritten by gnss_sim test_rinex_obs from OPEC00NOR"])


@pytest.fixture(scope="module")
def opec_rewrite(opec_dir, tmp_path_factory):
    src = opec_dir / OPEC_OBS
    t_end = dt.datetime(2022, 1, 1) + dt.timedelta(seconds=30 * (N_EPOCHS - 1))
    orig = _load(src, tlim=(dt.datetime(2022, 1, 1), t_end))
    assert orig.sizes["time"] == N_EPOCHS
    hdr = _opec_header(src)
    out = tmp_path_factory.mktemp("opec") / "OPEC_rewrite.rnx"
    svs = orig.sv.values.tolist()
    with RinexObsWriter(out, hdr) as w:
        for k, t64 in enumerate(orig.time.values):
            t = GnssTime.from_datetime(t64.astype("datetime64[us]").astype(dt.datetime), scale="GPS")
            epoch = {}
            for sv in svs:
                o = {}
                for code in hdr.obs_types[sv[0]]:
                    v = float(orig[code].sel(sv=sv).values[k])
                    if math.isnan(v):
                        continue
                    lli = orig[code + "lli"].sel(sv=sv).values[k] if code + "lli" in orig else np.nan
                    ssi = orig[code + "ssi"].sel(sv=sv).values[k]
                    o[code] = (v, None if np.isnan(lli) else int(lli), None if np.isnan(ssi) else int(ssi))
                if o:
                    epoch[sv] = o
            w.write_epoch(t, epoch)
    return orig, out, t_end


def test_opec_rewrite_georinex_identical(opec_rewrite):
    orig, out, _ = opec_rewrite
    back = _load(out)
    assert back.sizes["time"] == N_EPOCHS
    np.testing.assert_array_equal(back.time.values, orig.time.values)
    assert sorted(back.sv.values.tolist()) == sorted(orig.sv.values.tolist())
    assert set(back.data_vars) == set(orig.data_vars)
    n_values = 0
    for var in orig.data_vars:
        a = orig[var].sel(sv=back.sv).values
        b = back[var].values
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=var)
        if var.endswith(("lli", "ssi")):
            np.testing.assert_array_equal(a, b, err_msg=var)  # exact indicators
        else:
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-3, err_msg=var)  # 1 mm
            n_values += int(np.sum(~np.isnan(a)))
    assert n_values > 10000  # 60 epochs x ~36 satellites x 6-9 types
    assert np.nansum(orig["L1Clli"].values) > 0  # the data do carry LLI flags


def _rnx2rtkp_positions(obs: Path, nav: Path, out: Path) -> dict[str, np.ndarray]:
    r = subprocess.run(["rnx2rtkp", "-p", "0", "-sys", "G", "-e", "-t", "-o", str(out), str(obs), str(nav)],
                       capture_output=True, text=True, timeout=120)
    assert out.is_file(), r.stderr
    sol = {}
    for ln in out.read_text().splitlines():
        if ln.startswith("%") or not ln.strip():
            continue
        f = ln.split()
        sol[f[0] + " " + f[1]] = np.array([float(x) for x in f[2:5]])
    return sol


@pytest.mark.skipif(shutil.which("rnx2rtkp") is None, reason="RTKLIB rnx2rtkp is not installed")
def test_opec_rewrite_rtklib_same_spp(opec_rewrite, opec_dir, tmp_path):
    _, out, t_end = opec_rewrite
    nav = opec_dir / OPEC_NAV_G
    # the original, cut to the same epochs with RTKLIB's own -te
    r = subprocess.run(["rnx2rtkp", "-p", "0", "-sys", "G", "-e", "-t", "-te", "2022/01/01",
                        t_end.strftime("%H:%M:%S"), "-o", str(tmp_path / "orig.pos"),
                        str(opec_dir / OPEC_OBS), str(nav)], capture_output=True, text=True, timeout=120)
    assert (tmp_path / "orig.pos").is_file(), r.stderr
    ref = {}
    for ln in (tmp_path / "orig.pos").read_text().splitlines():
        if not ln.startswith("%") and ln.strip():
            f = ln.split()
            ref[f[0] + " " + f[1]] = np.array([float(x) for x in f[2:5]])
    ours = _rnx2rtkp_positions(out, nav, tmp_path / "ours.pos")
    assert len(ref) >= N_EPOCHS - 1
    assert sorted(ours) == sorted(ref)
    for k in ref:
        np.testing.assert_allclose(ours[k], ref[k], atol=1e-3, rtol=0, err_msg=k)
    # and the solutions are real ones: within 30 m of the published marker position
    marker = np.array([3149785.9652, 598260.8822, 5495348.4927])
    assert max(np.linalg.norm(p - marker) for p in ours.values()) < 30.0

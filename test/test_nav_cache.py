"""The parsed-navigation cache (core/rinex/nav/cache.py): a hit gives what a parse gives (down to the simulated
RINEX and fix.csv bytes), a changed file misses, a corrupt entry is ignored with a warning and written again,
GNSS_SIM_NAV_CACHE=off parses every time.  (conftest gives the session a cache folder of its own.)"""
from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.rinex.nav import NavDataWarning, read_nav_file
from gnss_sim_ros2.core.rinex.nav import cache as nav_cache
from gnss_sim_ros2.core.rinex.nav import read as nav_read
from gnss_sim_ros2.core.time import GnssTime

GN = "OPEC00NOR_S_20220010000_01D_GN.rnx"


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("GNSS_SIM_CACHE", str(d))
    monkeypatch.delenv(nav_cache.CACHE_SWITCH_ENV, raising=False)
    return d / "nav"


@pytest.fixture
def parses(monkeypatch):
    """How many times the text of a file is parsed."""
    count = []
    real = nav_read.parse_nav_text

    def counting(*a, **k):
        count.append(1)
        return real(*a, **k)

    monkeypatch.setattr(nav_read, "parse_nav_text", counting)
    return count


def assert_same_nav(a, b):
    assert set(a.tables) == set(b.tables)
    for s in a.tables:
        ta, tb = a.tables[s], b.tables[s]
        assert ta.rec.dtype == tb.rec.dtype and ta.rec.tobytes() == tb.rec.tobytes()
        assert ta.raw.tobytes() == tb.raw.tobytes() and ta.fields == tb.fields
        assert np.array_equal(ta.epoch, tb.epoch) and ta.epoch.dtype == tb.epoch.dtype
    for f in ("iono", "leap_seconds", "versions", "paths", "skipped", "notes", "dropped", "origin"):
        assert getattr(a, f) == getattr(b, f), f


def test_a_hit_is_the_parse_without_parsing(opec_dir, cache_dir, parses):
    start = GnssTime.from_iso("2022-01-01T12:00:00")
    first = read_nav_file(opec_dir / GN, start, start + 3600.0, "G")
    second = read_nav_file(opec_dir / GN, start, start + 3600.0, "G")
    assert len(parses) == 1 and len(list(cache_dir.glob("*.npz"))) == 1
    assert_same_nav(first, second)
    read_nav_file(opec_dir / GN, start + 86400.0, None, "G")        # another window: another entry
    assert len(parses) == 2 and len(list(cache_dir.glob("*.npz"))) == 2


def test_a_changed_file_misses(opec_dir, cache_dir, parses, tmp_path):
    nav = tmp_path / GN
    shutil.copy(opec_dir / GN, nav)
    before = read_nav_file(nav)
    lines = nav.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    lines[k] = lines[k][:23] + "-9.000000000000D-04" + lines[k][42:]    # af0 of the first record
    nav.write_text("".join(lines))
    after = read_nav_file(nav)
    assert len(parses) == 2 and len(list(cache_dir.glob("*.npz"))) == 2
    sv = lines[k][:3]
    first_b = before.tables["G"].rec[before.tables["G"].rec["sv"] == sv]["af0"]
    first_a = after.tables["G"].rec[after.tables["G"].rec["sv"] == sv]["af0"]
    assert -9.0e-4 in first_a and -9.0e-4 not in first_b


def test_a_corrupt_entry_is_ignored_with_a_warning_and_written_again(opec_dir, cache_dir, parses):
    good = read_nav_file(opec_dir / GN)
    (entry,) = cache_dir.glob("*.npz")
    entry.write_bytes(entry.read_bytes()[: entry.stat().st_size // 2])     # a half-written file
    with pytest.warns(nav_cache.NavCacheWarning, match=r"cannot be read .* written again"):
        again = read_nav_file(opec_dir / GN)
    assert len(parses) == 2
    assert_same_nav(good, again)
    with warnings.catch_warnings():
        warnings.simplefilter("error", nav_cache.NavCacheWarning)
        assert_same_nav(good, read_nav_file(opec_dir / GN))          # the rewritten entry reads
    assert len(parses) == 2


def test_off_parses_every_time_and_writes_nothing(opec_dir, cache_dir, parses, monkeypatch):
    monkeypatch.setenv(nav_cache.CACHE_SWITCH_ENV, "off")
    read_nav_file(opec_dir / GN)
    read_nav_file(opec_dir / GN)
    assert len(parses) == 2 and not cache_dir.exists()


def test_a_hit_says_again_what_the_parse_said(shared_data, cache_dir, parses):
    sbas = shared_data / "nav-formats-georinex" / "demo_nav3.10n"
    for _ in range(2):
        with pytest.warns(NavDataWarning, match=r"demo_nav3.10n: 2 SBAS records skipped"):
            nav = read_nav_file(sbas)
        assert sum(nav.skipped.values()) == 2
    assert len(parses) == 1


def _outputs(out):
    (obs,) = out.glob("*_MO.rnx")
    lines = [ln for ln in obs.read_bytes().splitlines(keepends=True) if b"PGM / RUN BY / DATE" not in ln]
    return b"".join(lines), (out / "fix.csv").read_bytes()


def test_simulate_from_a_hit_writes_the_same_files_as_from_a_parse(opec_dir, cache_dir, parses, tmp_path,
                                                                   monkeypatch):
    args = ["simulate", "--nav", str(opec_dir / GN), "--systems", "G", "--position-ecef",
            "3149785.9652,598260.8822,5495348.4927", "--start", "2022-01-01T12:00:00", "--duration", "120",
            "--quiet"]
    assert main(args + ["--out", str(tmp_path / "miss")]) == 0
    assert main(args + ["--out", str(tmp_path / "hit")]) == 0
    assert len(parses) == 1
    monkeypatch.setenv(nav_cache.CACHE_SWITCH_ENV, "off")
    assert main(args + ["--out", str(tmp_path / "off")]) == 0
    assert len(parses) == 2
    miss = _outputs(tmp_path / "miss")
    assert len(miss[1].splitlines()) > 100
    assert _outputs(tmp_path / "hit") == miss == _outputs(tmp_path / "off")

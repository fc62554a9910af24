"""``compare`` warns when its two inputs are not one site or not one day (issue 14, item 9)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.comparison import compare, write_report
from gnss_sim_ros2.core.comparison.compare import CompareWarning
from gnss_sim_ros2.core.frames import ecef_to_geodetic, geodetic_to_ecef


@pytest.fixture(scope="module")
def syn(tmp_path_factory):
    """A synthetic GPS run, 6 epochs of 10 s, its observation and navigation files."""
    out = tmp_path_factory.mktemp("sites") / "sim"
    assert main(["simulate", "--out", str(out), "--quiet", "--synthetic", "--position", "59.9,10.75,60",
                 "--duration", "50", "--interval", "10", "--systems", "G"]) == 0
    (obs,) = out.glob("*_MO.rnx")
    (nav,) = out.glob("*_MN.rnx")
    return obs, nav


def _header_edit(src, dst, label, content):
    lines = src.read_text().splitlines(keepends=True)
    for i, ln in enumerate(lines):
        if ln[60:].strip() == label:
            lines[i] = f"{content:<60}{label:<20}".rstrip() + "\n"
            break
    else:
        raise AssertionError(f"{src} has no {label}")
    dst.write_text("".join(lines))
    return dst


def test_files_far_apart_warn(syn, tmp_path):
    obs, nav = syn
    # the same observations labelled 10 degrees of latitude further south (1,113 km)
    x = np.array(geodetic_to_ecef(49.9, 10.75, 60.0))
    far = _header_edit(obs, tmp_path / "far.rnx", "APPROX POSITION XYZ", f"{x[0]:14.4f}{x[1]:14.4f}{x[2]:14.4f}")
    with pytest.warns(CompareWarning, match=r"APPROX POSITION XYZ 111\d\.\d km apart: not one site") as rec:
        cmp = compare(obs, far, nav_paths=[nav])
    assert len([w for w in rec if issubclass(w.category, CompareWarning)]) == 1
    report = write_report(cmp, tmp_path / "report").read_text()
    assert "**Warning**" in report and "km apart" in report


def test_files_of_different_days_warn(syn, tmp_path):
    obs, _ = syn
    later = _header_edit(obs, tmp_path / "later.rnx", "TIME OF FIRST OBS",
                         "  2025     6     2     0     0    0.0000000     GPS")
    with pytest.warns(CompareWarning, match=r"starts on 2025-06-01, .*later.rnx on 2025-06-02: files of different"):
        compare(obs, later)


def test_one_site_one_day_no_warning(syn):
    obs, nav = syn
    with warnings.catch_warnings():
        warnings.simplefilter("error", CompareWarning)
        cmp = compare(obs, obs, nav_paths=[nav])
    assert cmp.warnings == []
    lat, lon, _ = ecef_to_geodetic(*cmp.real.approx_pos_ecef_m)
    assert abs(lat - 59.9) < 0.01 and abs(lon - 10.75) < 0.01

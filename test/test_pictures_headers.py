"""Right pictures and headers (issue 25): below-mask satellites in the sky plot, the skyline of `gnss-sim skyplot`
(PNG outline + skyline.csv), every GLONASS satellite of the nav data in SLOT / FRQ #, ANT # / TYPE from the
profile's antenna, and `sweep` on the cores its help promises."""
from __future__ import annotations

import argparse
import csv
import warnings
from pathlib import Path

import numpy as np
import pytest

from gnss_sim_ros2.cli import main

REPO_ROOT = Path(__file__).resolve().parents[1]
COURTYARD = REPO_ROOT / "worlds" / "courtyard.sdf"


# ----------------------------------------------------------------------------- sky plot
def test_below_mask_satellites_are_drawn_as_below_mask(tmp_path):
    """A satellite under the mask is a hollow grey "below mask" marker, whatever state it comes with (a name, the
    int8 code -1, or 255 as a uint8 message field carries it); the others keep their markers."""
    from gnss_sim_ros2.core.skyplot import BELOW_MASK_COLOR, plot_skyplot

    sv = ["G01", "G02", "G03", "G04", "E05"]
    az = [10.0, 100.0, 200.0, 300.0, 45.0]
    el = [5.0, 8.0, 3.0, 40.0, 60.0]
    for states in (["visible", "below_mask", "blocked", "visible", "blocked"],
                   np.array([0, 255, 1, 0, 1], dtype=np.uint8), np.array([0, -1, 1, 0, 1], dtype=np.int8)):
        art = plot_skyplot(tmp_path / "sky.png", sv, az, el, states, mask_deg=10.0)
        assert (tmp_path / "sky.png").stat().st_size > 0
        drawn = {s: name for s, (name, _) in art["satellites"].items()}
        assert drawn == {"G01": "below_mask", "G02": "below_mask", "G03": "below_mask", "G04": "visible",
                         "E05": "blocked"}, states
        for s in ("G01", "G02", "G03"):
            line = art["satellites"][s][1]
            assert line.get_markerfacecolor() == "none", f"{s} below the mask is drawn filled"
            assert line.get_color() == BELOW_MASK_COLOR
        assert art["satellites"]["G04"][1].get_markerfacecolor() != "none"   # visible: filled
        assert "below mask" in art["legend"]


def test_plot_refuses_an_unknown_state(tmp_path):
    from gnss_sim_ros2.core.skyplot import plot_skyplot

    with pytest.raises(ValueError, match="state codes \\[7\\]"):
        plot_skyplot(tmp_path / "s.png", ["G01"], [1.0], [30.0], np.array([7], dtype=np.uint8))
    with pytest.raises(ValueError, match="G01: state 'hidden'"):
        plot_skyplot(tmp_path / "s.png", ["G01"], [1.0], [30.0], ["hidden"])


def _direct_opaque_hit(scene, antenna_world_m, az_deg, el_deg) -> bool:
    """One ray cast with Open3D on the scene's opaque triangles, built here (not through core/scene/raycast)."""
    import open3d as o3d

    w = scene.world
    opaque_class = np.array([c.opaque for c in w.materials.classes])
    tri = np.asarray(w.triangles)[opaque_class[np.asarray(w.material, dtype=np.int64)]]
    rs = o3d.t.geometry.RaycastingScene()
    rs.add_triangles(o3d.core.Tensor(np.asarray(w.vertices_m, dtype=np.float32)),
                     o3d.core.Tensor(tri.astype(np.uint32)))
    a, e = np.radians(az_deg), np.radians(el_deg)
    d_enu = np.array([np.cos(e) * np.sin(a), np.cos(e) * np.cos(a), np.sin(e)])
    d_world = scene.world_from_local_enu(antenna_world_m)[0] @ d_enu
    ray = np.concatenate([np.asarray(antenna_world_m, float), d_world]).astype(np.float32)[None, :]
    return bool(np.isfinite(rs.cast_rays(o3d.core.Tensor(ray))["t_hit"].numpy()[0]))


def test_skyplot_command_draws_and_writes_the_skyline(tmp_path):
    """`gnss-sim skyplot` from the courtyard's centre: skyline.csv beside the PNG, one row per degree, walls above
    the horizon; at a few azimuths a direct Open3D cast finds the wall just under the skyline and open sky just
    over it."""
    from gnss_sim_ros2.core.scene.visibility import Scene

    png = tmp_path / "sky.png"
    at = "0,0,1"
    assert main(["skyplot", "--world", str(COURTYARD), "--at", at, "--time", "2025-06-01T10:00:00", "--synthetic",
                 "--mask-deg", "10", "--csv", str(tmp_path / "sky.csv"), "--png", str(png)]) == 0
    assert png.stat().st_size > 0
    rows = list(csv.DictReader((tmp_path / "skyline.csv").open()))
    assert list(rows[0]) == ["azimuth_deg", "elevation_deg", "foliage_elevation_deg"]
    az = np.array([float(r["azimuth_deg"]) for r in rows])
    el = np.array([float(r["elevation_deg"]) for r in rows])
    fol = np.array([float(r["foliage_elevation_deg"]) for r in rows])
    assert np.array_equal(az, np.arange(360.0))
    assert np.all((el >= 0) & (el <= 90)) and np.all((fol >= 0) & (fol <= 90))
    assert np.mean(el > 5.0) > 0.7, "the courtyard's walls stand above most of the horizon"
    assert fol.max() > 5.0, "the courtyard's trees are in the foliage skyline"
    scene = Scene.from_sdf(COURTYARD)
    antenna = np.array([0.0, 0.0, 1.0])
    checked = 0
    for a in range(0, 360, 15):
        e = el[a]
        if not 2.0 < e < 88.0:
            continue
        assert _direct_opaque_hit(scene, antenna, a, e - 0.3), f"az {a}: nothing under the skyline {e:.2f} deg"
        assert not _direct_opaque_hit(scene, antenna, a, e + 0.3), f"az {a}: blocked over the skyline {e:.2f} deg"
        checked += 1
    assert checked >= 10


def test_skyplot_skyline_csv_option(tmp_path):
    out = tmp_path / "mask.csv"
    assert main(["skyplot", "--world", str(COURTYARD), "--at", "0,0,1", "--time", "2025-06-01T10:00:00",
                 "--synthetic", "--csv", str(tmp_path / "sky.csv"), "--skyline-csv", str(out)]) == 0
    assert len(out.read_text().splitlines()) == 361
    assert not (tmp_path / "skyline.csv").exists()


# ----------------------------------------------------------------------------- RINEX header
def _header_records(obs: Path, label: str) -> list[str]:
    lines = []
    for line in obs.read_text().splitlines():
        if line[60:].strip() == label:
            lines.append(line[:60])
        if "END OF HEADER" in line:
            break
    return lines


def _glonass_slots(obs: Path) -> dict[str, int]:
    lines = _header_records(obs, "GLONASS SLOT / FRQ #")
    n = int(lines[0][:3])
    slots = {}
    for line in lines:
        body = line[4:]
        for k in range(8):
            item = body[7 * k: 7 * k + 7]
            if item.strip():
                slots[item[:3]] = int(item[4:6])
    assert len(slots) == n, f"SLOT / FRQ # announces {n} satellites, lists {len(slots)}"
    return slots


def _simulate(out: Path, *extra) -> Path:
    assert main(["simulate", "--out", str(out), "--quiet", *extra]) == 0
    (obs,) = out.glob("*_MO.rnx")
    return obs


def test_glonass_slots_list_every_satellite_of_the_nav_data(opec_dir, tmp_path):
    """A day over the OPEC GLONASS navigation file: SLOT / FRQ # lists every satellite georinex finds in it, with
    its channel (FreqNum), and every GLONASS satellite of the observations (was: those of the first epoch only)."""
    import georinex

    rn = opec_dir / "OPEC00NOR_S_20220010000_01D_RN.rnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        nav = georinex.load(rn)
    expected = {}
    for name in nav.sv.values.tolist():
        k = nav["FreqNum"].sel(sv=name).values
        k = k[np.isfinite(k)]
        if len(k):
            expected.setdefault(str(name)[:3], int(k[0]))
    obs = _simulate(tmp_path / "o", "--nav", str(rn), str(opec_dir / "OPEC00NOR_S_20220010000_01D_GN.rnx"),
                    "--position-ecef", "3149785.9652,598260.8822,5495348.4927", "--start", "2022-01-01T00:30:00",
                    "--duration", "82800", "--interval", "900", "--systems", "GR")
    slots = _glonass_slots(obs)
    assert slots == expected
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        tracked = {str(s) for s in georinex.load(obs, use="R").sv.values.tolist()}
    assert tracked and tracked <= set(slots), sorted(tracked - set(slots))


def test_glonass_slots_over_the_run_not_the_first_epoch():
    """glonass_slots samples the whole run: a satellite whose record starts later is listed (synthetic sky)."""
    from gnss_sim_ros2.core.simulation import glonass_slots

    class Provider:              # R01 served from the start, R02 only after 2 h
        def states(self, t, systems="GRECJI"):
            from types import SimpleNamespace

            later = t - t0 >= 7200.0
            return SimpleNamespace(sv=np.array(["R01", "R02"] if later else ["R01"]),
                                   glo_channel=np.array([1, -4] if later else [1]))

    from gnss_sim_ros2.core.time import GnssTime

    t0 = GnssTime.from_iso("2025-06-01T10:00:00", scale="GPS")
    assert glonass_slots(Provider(), t0, 3 * 3600.0, "GR") == {"R01": 1, "R02": -4}
    assert glonass_slots(Provider(), t0, 3600.0, "GR") == {"R01": 1}
    assert glonass_slots(Provider(), t0, 3 * 3600.0, "GE") == {}


@pytest.mark.parametrize("profile", ["geodetic", "single_frequency", "ublox_f9p"])
def test_antenna_type_comes_from_the_profile(tmp_path, profile):
    """ANT # / TYPE names the profile's antenna (gnss_sim_ros2/profiles/*.yaml: geodetic has a choke ring, was
    written as the patch); the header also reaches RTCM 1033 through the same RinexObsHeader."""
    from gnss_sim_ros2.core.multipath.antenna import RINEX_ANTENNA_TYPE
    from gnss_sim_ros2.core.receiver.profiles import load_profile

    obs = _simulate(tmp_path / profile, "--synthetic", "--duration", "2", "--profile", profile, "--systems", "G")
    (ant,) = _header_records(obs, "ANT # / TYPE")
    antenna = load_profile(profile).fields["antenna"]
    assert ant[20:40] == f"{RINEX_ANTENNA_TYPE[antenna]:<20s}"
    if profile == "geodetic":
        assert antenna != "patch" and "PATCH" not in ant[20:40], ant


# ----------------------------------------------------------------------------- sweep
def test_sweep_without_workers_uses_the_cores(tmp_path, monkeypatch, capsys):
    """`sweep` without --workers starts a local cluster of os.cpu_count() workers, as its help says (was 1):
    the worker count handed to the driver, without starting a cluster."""
    import os

    import gnss_sim_ros2.core.sweep.driver as driver
    from gnss_sim_ros2.commands import sweep

    seen = {}

    def fake_run_sweep(tasks, out, workers=None, scheduler=None, **kw):
        seen["workers"], seen["scheduler"] = workers, scheduler
        raise ValueError("stopped by the test")

    monkeypatch.setattr(driver, "run_sweep", fake_run_sweep)
    monkeypatch.setattr(driver, "start_local_workers", lambda: "fork")
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    base = ["sweep", "--seeds", "1-2", "--duration", "2", "--synthetic", "--out", str(tmp_path / "s")]
    assert main(base) == 2
    assert seen == {"workers": 7, "scheduler": None}
    assert main([*base, "--workers", "3"]) == 2
    assert seen["workers"] == 3
    parser = argparse.ArgumentParser()
    sweep.add_arguments(parser)
    assert "(default: the cores, 7)" in " ".join(parser.format_help().split())

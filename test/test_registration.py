"""Registration (issue 27): a scene's georeference error estimated from a real recording, with its uncertainty
(core/comparison/registration.py, ``gnss-sim compare --fit-offset``).

The synthetic "real" receiver tracks what the SHIFTED scene leaves in its line of sight (the model's walls are
where the recording's surroundings are, moved by the georeference error), with a share of its labels flipped at
random (what a model lacks); the fit on the unshifted scene must find the shift (as the antenna's offset in the
model: minus the walls' shift) within its reported uncertainty.
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from multipath_scenes import _box

from gnss_sim_ros2.core.comparison.registration import SightEpochs, fit_offset, registration_markdown
from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
from gnss_sim_ros2.core.scene.materials import MaterialTable
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.scene.world_mesh import WorldMesh
from gnss_sim_ros2.core.visibility.line_of_sight import line_of_sight

MASK_DEG = 10.0
ORIGIN = SphericalCoordinates(22.2982, 114.1788, 0.0)


def _street(shift_en_m=(0.0, 0.0)) -> Scene:
    """A street along north (walls at x = -7 (25 m high) and x = +7 (15 m)) closed by two cross blocks at
    y = +-28 (20 m), moved by ``shift_en_m`` [m] in the world frame."""
    parts = [_box(-8, -6, -200, 200, 0, 25), _box(6, 8, -200, 200, 0, 15),
             _box(-40, 40, 27, 32, 0, 20), _box(-40, 40, -32, -27, 0, 20)]
    verts, tris, n = [], [], 0
    for v, f in parts:
        tris.append(f + n)
        verts.append(v)
        n += len(v)
    v = np.vstack(verts) + np.array([shift_en_m[0], shift_en_m[1], 0.0])
    world = WorldMesh(v, np.vstack(tris), np.zeros(sum(len(t) for t in tris), np.int16), MaterialTable())
    return Scene(dataclasses.replace(world, spherical_coordinates=ORIGIN))


def _recording(shift_en_m, n_epochs=40, n_sats=30, flip=0.05, seed=1):
    """(model scene, SightEpochs): the antenna along the street's axis (y -22 .. +22 m, 1.5 m high), random
    satellites, tracked = in the line of sight of the shifted scene, ``flip`` of the labels flipped."""
    rng = np.random.default_rng(seed)
    model, real = _street(), _street(shift_en_m)
    ant = np.column_stack([np.zeros(n_epochs), np.linspace(-22, 22, n_epochs), np.full(n_epochs, 1.5)])
    sats, trk = [], []
    for a in ant:
        az = rng.uniform(0, 2 * np.pi, n_sats)
        el = np.arcsin(rng.uniform(np.sin(np.radians(MASK_DEG + 1)), 1.0, n_sats))
        d = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
        sat = model.spherical.world_to_ecef(a + 2.0e7 * d)
        los, _ = line_of_sight(real, a, sat, MASK_DEG)
        los ^= rng.random(n_sats) < flip
        sats.append(sat)
        trk.append(los)
    return model, SightEpochs(np.arange(n_epochs), ant, sats, trk, [t.copy() for t in trk])


@pytest.mark.parametrize("shift", [(-3.0, 2.5), (2.0, -4.0)])
def test_a_known_shift_is_recovered_within_its_uncertainty(shift):
    model, sight = _recording(shift)
    reg = fit_offset(model, sight, mask_deg=MASK_DEG, n_bootstrap=100)
    # the recording's walls are the model's moved by +shift: seen from them, the antenna sits at -shift in the model
    err = np.add(reg.offset_en_m, shift)
    assert np.all(np.abs(err) <= 3.0 * np.array(reg.sigma_en_m)), (reg, err)
    assert max(reg.sigma_en_m) < 1.5             # the data pin it down: not an uncertainty that covers anything
    assert reg.criterion_best < reg.criterion_zero - 0.1
    assert reg.epochs == 40 and reg.sat_epochs == reg.strong_sat_epochs + reg.untracked_sat_epochs
    assert not reg.at_edge


def test_without_resampling_the_estimate_is_the_same_and_only_its_own_spread_remains():
    """n_bootstrap=0 (drive_check.model_offset_m asks for no replicates): the same estimate as with resampling, an
    uncertainty from the flat minimum and the grid alone, no replicate correlation (it failed reshaping an empty
    resample)."""
    model, sight = _recording((-3.0, 2.5))
    with_boot = fit_offset(model, sight, mask_deg=MASK_DEG, n_bootstrap=20)
    plain = fit_offset(model, sight, mask_deg=MASK_DEG, n_bootstrap=0)
    assert plain.offset_en_m == with_boot.offset_en_m
    assert plain.criterion_best == with_boot.criterion_best
    assert np.all(np.array(plain.sigma_en_m) <= np.array(with_boot.sigma_en_m)) and plain.sigma_en_m[0] > 0
    assert plain.corr_en == 0.0


def test_no_shift_gives_about_zero():
    model, sight = _recording((0.0, 0.0))
    reg = fit_offset(model, sight, mask_deg=MASK_DEG, n_bootstrap=100)
    assert np.all(np.abs(reg.offset_en_m) <= 3.0 * np.array(reg.sigma_en_m)), reg
    assert reg.offset_m <= 1.0
    assert reg.criterion_best <= reg.criterion_zero


def test_the_fitted_offset_applied_as_world_offset_leaves_about_zero_to_fit():
    """Issue 27: fit on a recording, apply the estimate explicitly (world_offset_enu_m = [-e, -n, 0]: the model's
    georeference moved; the truth, in ECEF, placed again in the moved world), fit again: about zero within the
    reported uncertainty, and the agreement as good as at the first estimate."""
    from gnss_sim_ros2.core.visibility.world_offset import shifted_scene

    model, sight = _recording((-3.0, 2.5))
    reg = fit_offset(model, sight, mask_deg=MASK_DEG, n_bootstrap=50)
    e, n = reg.offset_en_m
    moved = shifted_scene(model, [-e, -n, 0.0])
    assert moved is not model and model.spherical == ORIGIN          # the loaded scene itself is left alone
    truth_ecef = model.spherical.world_to_ecef(sight.antenna_world_m)
    again = fit_offset(moved, dataclasses.replace(sight, antenna_world_m=moved.spherical.ecef_to_world(truth_ecef)),
                       mask_deg=MASK_DEG, n_bootstrap=50)
    assert np.all(np.abs(again.offset_en_m) <= 3.0 * np.array(reg.sigma_en_m) + 0.25), (reg, again)
    assert again.criterion_zero <= reg.criterion_best + 0.01
    assert shifted_scene(model, []) is model and shifted_scene(model, [0.0, 0.0, 0.0]) is model


@pytest.mark.parametrize("value, words", [([1.0, 2.0], "needs 3 numbers"), ([0.0, 0.0, 5000.0], "within +-1000"),
                                          ([float("nan"), 0.0, 0.0], "must be finite")])
def test_bad_world_offset_is_an_error_naming_the_parameter(value, words):
    from gnss_sim_ros2.parameters import validate_node

    with pytest.raises(ValueError, match=rf"node x: parameter .world_offset_enu_m. = .*{re.escape(words)}"):
        validate_node("visibility", {"world_offset_enu_m": value}, "node x")


def test_a_shift_beyond_the_search_is_flagged_not_hidden():
    model, sight = _recording((9.0, 0.0))
    reg = fit_offset(model, sight, mask_deg=MASK_DEG, span_m=4.0, n_bootstrap=20)
    assert reg.at_edge
    assert "border of the search" in registration_markdown(reg, "--mesh x", "hint")


def test_the_report_section_says_it_is_not_applied():
    model, sight = _recording((-3.0, 2.5), n_epochs=10)
    reg = fit_offset(model, sight, mask_deg=MASK_DEG, n_bootstrap=20)
    md = registration_markdown(reg, "--mesh city.ply", "move the model")
    assert md.startswith("## Registration") and "not applied" in md and "+-" in md


def _cli(*argv):
    from gnss_sim_ros2 import cli

    return cli.main(["compare", *argv])


@pytest.mark.parametrize("extra, message", [
    (["--fit-offset"], "needs the scene"),
    (["--fit-offset", "--mesh", "m.ply"], "needs --nav"),
    (["--antenna-height-m", "1.8"], "only used with --world / --mesh"),
])
def test_bad_fit_offset_options_are_one_line_rc_2(tmp_path, capsys, extra, message):
    rc = _cli("--sim", str(tmp_path / "s.obs"), "--real", str(tmp_path / "r.obs"), "--out", str(tmp_path / "o"),
              *extra)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0], err


@pytest.mark.slow
def test_compare_fit_offset_finds_the_shift_of_a_simulated_recording(tmp_path):
    """End to end: ``gnss-sim simulate`` walks the street of a model moved by SHIFT (the recording's surroundings),
    ``gnss-sim compare --mesh <unmoved model> --fit-offset`` reports the antenna's offset -SHIFT within its
    uncertainty, in report.md and registration.json, and applies it to nothing."""
    import json

    from gnss_sim_ros2.core.scene.mesh_io import write_scene
    from gnss_sim_ros2.core.time import GnssTime

    shift = (2.0, -2.5)
    meshes = {}
    for name, s in (("model", (0.0, 0.0)), ("recording", shift)):
        meshes[name] = tmp_path / f"{name}.ply"
        write_scene(meshes[name], _street(s).world)
    t_s = np.arange(0.0, 121.0, 1.0)
    world = np.column_stack([np.zeros_like(t_s), np.linspace(-22, 22, len(t_s)), np.full(len(t_s), 1.5)])
    traj = tmp_path / "walk.csv"
    traj.write_text("t_s,e_m,n_m,u_m\n" + "".join(f"{t:g},{p[0]:g},{p[1]:g},{p[2]:g}\n" for t, p in zip(t_s, world)))
    start = "2019-04-28T05:00:00"
    rc = _cli_any("simulate", "--synthetic", "--start", start, "--duration", "120", "--interval", "1",
                  "--systems", "GEC", "--seed", "3", "--mask-deg", str(MASK_DEG), "--mesh", str(meshes["recording"]),
                  "--trajectory", str(traj), "--out", str(tmp_path / "sim"), "--quiet")
    assert rc == 0
    obs = next((tmp_path / "sim").glob("*_MO.rnx"))
    nav = next((tmp_path / "sim").glob("*_MN.rnx"))
    ecef = _street().spherical.world_to_ecef(world)
    t0 = GnssTime.from_iso(start, scale="GPS")
    truth = tmp_path / "truth.csv"
    truth.write_text("time,x_m,y_m,z_m\n" + "".join(f"{(t0 + float(t)).isoformat('GPS', 3)},{p[0]:.4f},{p[1]:.4f},"
                                                      f"{p[2]:.4f}\n" for t, p in zip(t_s, ecef)))
    rc = _cli("--sim", str(obs), "--real", str(obs), "--nav", str(nav), "--truth-csv", str(truth),
              "--mesh", str(meshes["model"]), "--mask-deg", str(MASK_DEG), "--fit-offset", "--out", str(tmp_path / "c"))
    assert rc == 0
    reg = json.loads((tmp_path / "c" / "registration.json").read_text())
    err = np.add(reg["offset_en_m"], shift)
    print(f"registration of a {shift} m shift: {reg['offset_en_m']} +- {reg['sigma_en_m']} m "
          f"({reg['sat_epochs']} satellite-epochs, {reg['wall_s']:.1f} s)")
    assert np.all(np.abs(err) <= 3.0 * np.array(reg["sigma_en_m"])), reg
    assert max(reg["sigma_en_m"]) < 1.5 and reg["applied"] is False
    assert reg["criterion_best"] < reg["criterion_zero"]
    assert "## Registration" in (tmp_path / "c" / "report.md").read_text()


def _cli_any(*argv):
    from gnss_sim_ros2 import cli

    return cli.main(list(argv))

"""The planner's good-satellite prediction against a real receiver: the Hong Kong drive (u-blox M8T, 485 epochs,
GPS + BeiDou; about a minute).  Issue 30: predicted 'good' satellites (in line of sight of the city model at the
drive's positions and times: core/planning path_quality, the planner's own casts) against the real receiver's
good ones (tracked with C/N0 >= a threshold) per satellite-epoch above the 15 deg mask, with the skill over the
base rate (core/planning/skill.py: accuracy vs always the majority class, Heidke skill score).  Figures in
docs/PLANNING.md ("Validation")."""
from __future__ import annotations

import numpy as np
import pytest
from test_urban_hk_drive import hk  # noqa: F401  (the drive, its city model, ephemeris and real file: one loader)

from gnss_sim_ros2.core.comparison import drive_check
from gnss_sim_ros2.core.frames import az_el_from_ecef
from gnss_sim_ros2.core.planning.predicted_cn0 import predictor_from_profile
from gnss_sim_ros2.core.planning.quality import PlanInputs, path_quality
from gnss_sim_ros2.core.planning.ranging import budget_from_profile
from gnss_sim_ros2.core.planning.skill import count_agreement, feature_ceiling, skill
from gnss_sim_ros2.core.planning.sky import plan_sky
from gnss_sim_ros2.core.visibility import VisibilityOptions

#: the city model's georeference offset (east, north) [m] that drive_check.model_offset_m estimates from the real
#: receiver's signals (test_urban_hk_drive, docs/VALIDATION.md; 2 parameters fitted on the same drive)
PLACED_OFFSET_M = (-3.0, -5.0)
MASK_DEG = 15.0
THRESHOLDS_DBHZ = (30.0, 35.0, 40.0)


@pytest.fixture(scope="module")
def scored(hk):  # noqa: F811
    drive0, scene, prov, _, real_obs, _, drive_dir = hk
    real = drive_check.file_view(real_obs, drive0, drive0.truth_ecef_m, prov, scene, mask_deg=MASK_DEG)
    out, by_cn0, counts, told = {}, {}, {}, {}
    for name, offset in (("as given", (0.0, 0.0)), ("placed", PLACED_OFFSET_M)):
        drive = drive_check.load_drive(drive_dir / "groundTruth_TST.csv", scene, offset_m=offset)
        sky = plan_sky(prov, drive.t, "GC")
        inp = PlanInputs(sky.pos_ecef_m, sky.system, budget_from_profile("ublox_m8t", "GC"))
        states = np.full(sky.pos_ecef_m.shape[:2], -1, np.int8)
        path_quality(scene, VisibilityOptions(mask_deg=MASK_DEG), drive.antenna_world_m, sky.pos_ecef_m,
                     sky.system, inp, states_out=states)
        pred = {}                                        # C/N0 predicted from each profile's link budget
        for profile in ("ublox_m8t_hk", "ublox_m8t"):
            inp.cn0 = predictor_from_profile(profile, "GC")
            pred[profile] = np.full(states.shape, np.nan)
            path_quality(scene, VisibilityOptions(mask_deg=MASK_DEG), drive.antenna_world_m, sky.pos_ecef_m,
                         sky.system, inp, cn0_out=pred[profile])
        col = {s: j for j, s in enumerate(real.sv.tolist())}
        cn0 = np.zeros(states.shape)                     # C/N0 of the real receiver's tracked signals, 0 elsewhere
        for j, s in enumerate(sky.sv.tolist()):
            if s in col:
                cn0[:, j] = np.where(real.tracked[:, col[s]], np.nan_to_num(real.cn0_dbhz[:, col[s]]), 0.0)
        # satellite-epochs above the mask (planner) at the epochs the real receiver recorded
        considered = (states >= 0) & real.tracked.any(axis=1)[:, None]
        out[name] = {thr: skill(states == 0, cn0 >= thr, considered) for thr in THRESHOLDS_DBHZ}
        counts[(name, "line of sight")] = {thr: count_agreement(states == 0, cn0 >= thr, considered)
                                           for thr in THRESHOLDS_DBHZ}
        for profile, c in pred.items():
            with np.errstate(invalid="ignore"):
                by_cn0[(name, profile)] = {thr: skill(c >= thr, cn0 >= thr, considered) for thr in THRESHOLDS_DBHZ}
                counts[(name, profile)] = {thr: count_agreement(c >= thr, cn0 >= thr, considered)
                                           for thr in THRESHOLDS_DBHZ}
        if name == "placed":
            told.update(_what_a_planner_knows(scene, drive, sky, states), cn0=cn0, considered=considered,
                        fitted=pred["ublox_m8t_hk"])
    return out, by_cn0, counts, told


def _what_a_planner_knows(scene, drive, sky, states) -> dict:
    """Per satellite-epoch, integer features a planner has before the drive: the model's state, the satellite,
    its elevation in 5-deg bins and its margin above the model's skyline at its azimuth in 5-deg bins
    (Scene.horizon_profile at the antenna, 1 deg azimuth steps)."""
    az, el, _ = az_el_from_ecef(drive.truth_ecef_m[:, None, :], sky.pos_ecef_m)     # NaN where absent
    skyline = np.array([scene.horizon_profile(a, 1.0, iterations=4)[1] for a in drive.antenna_world_m])
    az_i = np.floor(np.nan_to_num(az)).astype(int) % 360
    margin = np.nan_to_num(el) - np.take_along_axis(skyline, az_i, axis=1)
    return {"state": states.astype(np.int64),
            "sv": np.broadcast_to(np.arange(states.shape[1]), states.shape),
            "el_bin": np.floor(np.nan_to_num(el) / 5.0).astype(np.int64),
            "margin_bin": np.clip(np.floor(margin / 5.0), -4, 4).astype(np.int64),
            "system": np.broadcast_to((sky.system == "G").astype(np.int64), states.shape),
            "epoch": np.broadcast_to(np.arange(states.shape[0])[:, None], states.shape)}


def _print(label, s):
    print(f"{label}: " + ", ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in s.items()))


def test_good_satellites_against_the_real_receiver(scored):
    scored = scored[0]
    for name, by_thr in scored.items():
        for thr, s in by_thr.items():
            print(f"{name}, C/N0 >= {thr:g} dB-Hz: " + ", ".join(
                f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in s.items()))
    placed = scored["placed"]
    # measured 2026-12-03: placed, 35 dB-Hz: accuracy 0.647 against a base rate of 0.695, HSS 0.359, hit rate 0.952
    # (as given: 0.621, HSS 0.310); placed, 30 dB-Hz: accuracy 0.748 over a base rate of 0.528 (HSS 0.502).
    # Margins below the figures.
    assert placed[35.0]["n"] > 5000
    assert placed[35.0]["hss"] >= 0.25                     # real skill over chance, not the 0.88
    assert placed[35.0]["hit_rate"] >= 0.85                # a real good satellite is predicted in sight
    assert placed[30.0]["accuracy"] >= placed[30.0]["base_rate"] + 0.1
    assert placed[35.0]["hss"] > scored["as given"][35.0]["hss"]     # the georeference fitted helps


def test_predicted_cn0_good_against_the_real_receiver(scored):
    """'Good' = C/N0 predicted from the profile's link budget >= the threshold (core/planning/predicted_cn0.py).
    ublox_m8t_hk was fitted on this drive's line-of-sight samples (its C/N0 table): its agreement is in-sample
    for the profile; ublox_m8t is the data-sheet profile."""
    by_cn0 = scored[1]
    for (name, profile), by_thr in by_cn0.items():
        for thr, s in by_thr.items():
            _print(f"predicted C/N0, {profile}, {name}, >= {thr:g} dB-Hz", s)
    los = scored[0]["placed"][35.0]
    fit, sheet = by_cn0[("placed", "ublox_m8t_hk")], by_cn0[("placed", "ublox_m8t")]
    # measured 2026-12-03 (placed): ublox_m8t_hk >= 35 dB-Hz accuracy 0.743 against a base rate of 0.695, HSS 0.347
    # (line of sight alone 0.647, HSS 0.359); >= 30 dB-Hz 0.784, HSS 0.572 (line of sight 0.748, HSS 0.502);
    # ublox_m8t (data sheet, 49 dB-Hz in line of sight) = line of sight.  Margins below the figures.
    assert fit[35.0]["n"] == los["n"]
    assert fit[35.0]["accuracy"] >= fit[35.0]["base_rate"] + 0.02   # beats always "not good" (line of sight: not)
    assert fit[35.0]["hss"] >= 0.3
    assert fit[30.0]["hss"] >= scored[0]["placed"][30.0]["hss"] + 0.03
    assert sheet[35.0]["p_pred"] > fit[35.0]["p_pred"]   # the data sheet is optimistic here


def test_good_satellite_counts_per_epoch(scored):
    """Furukawa, Kubo and El-Mowafy (ION ITM 2020) score the NUMBER of good satellites per epoch (predicted and
    measured counts "in agreement at least 87.8 % of the time"), not each satellite-epoch: the same drive scored
    their way (core/planning/skill.count_agreement), against the base rate of always answering the real median
    count.  Issue 30's acceptance stays the per satellite-epoch 0.88 (the tests above)."""
    counts = scored[2]
    for (name, good), by_thr in counts.items():
        for thr, c in by_thr.items():
            print(f"count of good satellites, {good}, {name}, >= {thr:g} dB-Hz: {c['n_epochs']} epochs, mean "
                  f"predicted {c['mean_predicted']:.2f} / real {c['mean_observed']:.2f} (constant {c['constant']}); "
                  + ", ".join(f"within {k}: {c['within'][k]:.3f} (base {c['base_within'][k]:.3f}, skill "
                              f"{c['skill'][k]:.3f})" for k in c["within"]))
    los, fit = counts[("placed", "line of sight")], counts[("placed", "ublox_m8t_hk")]
    # the same satellite-epochs as the per satellite-epoch scores: the counts add up to their shares of yes
    s35 = scored[0]["placed"][35.0]
    assert los[35.0]["n_epochs"] == 485
    assert abs(los[35.0]["mean_observed"] * los[35.0]["n_epochs"] - s35["p_obs"] * s35["n"]) < 0.5
    assert abs(los[35.0]["mean_predicted"] * los[35.0]["n_epochs"] - s35["p_pred"] * s35["n"]) < 0.5
    # measured 2026-12-03 (placed, 485 epochs, about 20 satellites above the mask an epoch): ublox_m8t_hk >= 35 dB-Hz
    # equal 0.146 / within 1: 0.375 / within 2: 0.505 against the constant 5's 0.089 / 0.328 / 0.501; >= 30 dB-Hz
    # within 1: 0.315 against 0.252; line of sight >= 35 dB-Hz (12.6 predicted, 6.1 real an epoch) 0.025 / 0.089 /
    # 0.124.  Far from Furukawa et al.'s 87.8 %.  Margins below the figures.
    assert fit[35.0]["within"][0] >= fit[35.0]["base_within"][0] + 0.03
    assert fit[35.0]["within"][1] >= fit[35.0]["base_within"][1] + 0.02
    assert fit[30.0]["within"][1] >= fit[30.0]["base_within"][1] + 0.03
    assert fit[35.0]["within"][1] >= los[35.0]["within"][1] + 0.2     # the predicted C/N0 fixes the over-count


def test_what_the_models_features_can_tell_about_good_satellites(scored):
    """Issue 30's 0.88 per satellite-epoch against what the planner's information can give on this drive at best:
    skill.feature_ceiling, the accuracy of the best yes/no rule of the features (each combination answered by its
    majority), in-sample (fitted on the answers themselves: an upper bound) and fitted on one half of the drive,
    scored on the other (both ways).  Figures in docs/PLANNING.md."""
    told = scored[3]
    m = told["considered"]
    sets = {"state": ("state",), "state, system, elevation": ("state", "system", "el_bin"),
            "state, satellite, elevation": ("state", "sv", "el_bin"),
            "state, satellite, elevation, skyline margin": ("state", "sv", "el_bin", "margin_bin")}
    first = told["epoch"] < told["epoch"].max() // 2 + 1
    ceil = {}
    for thr in (30.0, 35.0):
        good = told["cn0"] >= thr
        with np.errstate(invalid="ignore"):
            planner = skill(told["fitted"] >= thr, good, m)
        print(f">= {thr:g} dB-Hz: planner (ublox_m8t_hk) accuracy {planner['accuracy']:.3f}, base rate "
              f"{planner['base_rate']:.3f}")
        for label, keys in sets.items():
            feats = [told[k] for k in keys]
            c = feature_ceiling(feats, good, m)
            halves = [feature_ceiling(feats, good, m, fit=f)["accuracy"] for f in (first, ~first)]
            ceil[(thr, label)] = c["accuracy"]
            print(f"  best rule of {label}: in-sample {c['accuracy']:.3f} ({c['groups']} combinations); fitted on "
                  f"one half, scored on the other {halves[0]:.3f} / {halves[1]:.3f}")
    # measured 2026-12-05 (placed, n = 9700): >= 35 dB-Hz in-sample 0.695 (state), 0.754 (+ system, elevation),
    # 0.769 (+ satellite), 0.816 (+ skyline margin, 238 combinations: over-fitted, 0.687 / 0.755 on the half it did
    # not see); the planner 0.743.  Issue 30's 0.88 is above what any rule of these features scores on this drive,
    # even fitted on it.
    assert ceil[(35.0, "state, satellite, elevation")] < 0.88
    assert ceil[(35.0, "state, satellite, elevation, skyline margin")] < 0.88
    with np.errstate(invalid="ignore"):
        planner35 = skill(told["fitted"] >= 35.0, told["cn0"] >= 35.0, m)["accuracy"]
    assert planner35 >= ceil[(35.0, "state, system, elevation")] - 0.03   # the planner uses most of what they carry

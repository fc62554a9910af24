"""core/planning/skill.py on small hand-built tables whose scores are worked out by hand in the comments."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gnss_sim_ros2.core.planning.skill import count_agreement, feature_ceiling, skill


def test_skill_on_a_hand_built_table():
    # hits a = 2, false alarms b = 1, misses c = 0, correct negatives d = 2; n = 5
    # PC = 4/5; p_pred = 3/5, p_obs = 2/5; E = 3/5 * 2/5 + 2/5 * 3/5 = 12/25; HSS = (4/5 - 12/25) / (13/25) = 8/13
    s = skill([1, 1, 0, 0, 1], [1, 0, 0, 0, 1])
    assert s["n"] == 5
    assert s["accuracy"] == pytest.approx(0.8)
    assert s["base_rate"] == pytest.approx(0.6)
    assert s["hss"] == pytest.approx(8 / 13)
    assert s["hit_rate"] == pytest.approx(1.0)
    assert s["false_alarm_ratio"] == pytest.approx(1 / 3)


def test_count_agreement_on_a_hand_built_drive():
    # 6 epochs x 4 satellites.  Counts over the considered entries:
    #   e0: observed 2, predicted 2 (its 4th satellite, predicted good, is not considered)
    #   e1: 3 / 4;  e2: 3 / 1;  e3: 1 / 1 (different satellites: the COUNT agrees);  e4: 4 / 4
    #   e5: nothing considered: left out
    # |pred - obs| = 0, 1, 2, 0, 0 -> equal 3/5, within 1: 4/5, within 2: 5/5
    # observed counts 2, 3, 3, 1, 4: median 3; |3 - obs| = 1, 0, 0, 2, 1 -> base equal 2/5, within 1: 4/5, 2: 5/5
    # skill: equal (3/5 - 2/5) / (3/5) = 1/3; within 1: 0; within 2: base perfect -> nan
    observed = np.array([[1, 1, 0, 0], [1, 1, 1, 0], [1, 1, 1, 0], [1, 0, 0, 0], [1, 1, 1, 1], [1, 1, 1, 1]], bool)
    predicted = np.array([[1, 0, 1, 1], [1, 1, 1, 1], [1, 0, 0, 0], [0, 1, 0, 0], [1, 1, 1, 1], [0, 0, 0, 0]], bool)
    considered = np.ones((6, 4), bool)
    considered[0, 3] = False
    considered[5, :] = False
    c = count_agreement(predicted, observed, considered)
    assert c["n_epochs"] == 5
    assert c["mean_predicted"] == pytest.approx(12 / 5)
    assert c["mean_observed"] == pytest.approx(13 / 5)
    assert c["constant"] == 3
    assert c["within"] == pytest.approx({0: 0.6, 1: 0.8, 2: 1.0})
    assert c["base_within"] == pytest.approx({0: 0.4, 1: 0.8, 2: 1.0})
    assert c["skill"][0] == pytest.approx(1 / 3)
    assert c["skill"][1] == pytest.approx(0.0)
    assert math.isnan(c["skill"][2])


def test_count_agreement_constant_is_the_median_rounded_half_up():
    observed = np.array([[1, 0, 0, 0], [1, 1, 0, 0], [1, 1, 1, 0], [1, 1, 1, 1]], bool)   # counts 1..4: median 2.5
    c = count_agreement(observed, observed)
    assert c["constant"] == 3
    assert c["within"][0] == 1.0 and c["skill"][0] == pytest.approx(1.0)               # perfect prediction
    assert c["base_within"][0] == pytest.approx(0.25)


@pytest.mark.parametrize("shapes", [((3, 4), (3, 5)), ((4,), (4,))])
def test_count_agreement_names_bad_shapes(shapes):
    with pytest.raises(ValueError, match="count_agreement"):
        count_agreement(np.zeros(shapes[0], bool), np.zeros(shapes[1], bool))


def test_feature_ceiling_on_a_hand_built_sample():
    # feature 0: observed 1, 0 -> its majority answers one of the two right (a tie answers "no": the 0 right)
    # feature 1: observed 1, 1, 0 -> "yes", two right.  In-sample: 3 of 5 = 0.6; base rate 3/5 yes = 0.6
    c = feature_ceiling([np.array([0, 0, 1, 1, 1])], [1, 0, 1, 1, 0])
    assert c == {"n": 5, "accuracy": pytest.approx(0.6), "base_rate": pytest.approx(0.6), "groups": 2}
    # two features: (0, 0) -> 1; (0, 1) -> 0; (1, 0) -> 1, 1; (1, 1) -> 0: every entry right
    c = feature_ceiling([np.array([0, 0, 1, 1, 1]), np.array([0, 1, 0, 0, 1])], [1, 0, 1, 1, 0])
    assert c["accuracy"] == 1.0 and c["groups"] == 4


def test_feature_ceiling_fitted_on_one_part_scores_the_other():
    # fit on the first four: feature 0 -> (1, 1) "yes"; feature 1 -> (0, 0) "no"; feature 2 never met -> the fit
    # part's majority (2 of 4 yes: a tie, "no").  Scored on the last four: 0 -> 1 right, 1 -> 1 wrong (answer no),
    # 2 -> 0 right, 2 -> 1 wrong: 2 of 4
    f = np.array([0, 0, 1, 1, 0, 1, 2, 2])
    y = np.array([1, 1, 0, 0, 1, 1, 0, 1], bool)
    c = feature_ceiling([f], y, fit=np.arange(8) < 4)
    assert c["n"] == 4 and c["accuracy"] == pytest.approx(0.5) and c["groups"] == 2


def test_feature_ceiling_bounds_every_rule_of_the_features():
    rng = np.random.default_rng(3)
    el_bin = rng.integers(0, 18, 5000)
    state = rng.integers(0, 3, 5000)
    observed = (rng.random(5000) < 0.2 + 0.04 * el_bin * (state == 0))      # good more often high and in sight
    ceiling = feature_ceiling([state, el_bin], observed)["accuracy"]
    for _ in range(50):                                  # any rule of (state, elevation bin) scores at most that
        table = rng.random((3, 18)) < 0.5
        assert skill(table[state, el_bin], observed)["accuracy"] <= ceiling + 1e-12
    assert ceiling > feature_ceiling([state], observed)["accuracy"]          # the elevation carries information
    held = feature_ceiling([state, el_bin], observed, fit=np.arange(5000) < 2500)["accuracy"]
    assert held <= ceiling + 0.03                        # a fitted rule loses on the part it did not see


def test_feature_ceiling_names_bad_inputs():
    with pytest.raises(ValueError, match="integer arrays"):
        feature_ceiling([np.array([0.5, 1.5])], [True, False])
    with pytest.raises(ValueError, match="do not broadcast"):
        feature_ceiling([np.array([0, 1, 2])], [True, False])
    with pytest.raises(ValueError, match="no feature"):
        feature_ceiling([], [True, False])
    with pytest.raises(ValueError, match="none to score"):
        feature_ceiling([np.array([0, 1])], [True, False], fit=np.array([True, True]))

"""How well a yes/no prediction (a satellite in line of sight, RTK available) matches what happened: accuracy
against the base rate of always answering the more frequent class, and the Heidke skill score.

Heidke skill score (P. Heidke, Geografiska Annaler 8, 1926; the 2x2 contingency-table form of Wilks, Statistical
Methods in the Atmospheric Sciences): HSS = (PC - E) / (1 - E), PC the proportion correct, E the proportion
correct by chance of a prediction independent of the outcome with the same marginals, E = (p_yes_pred p_yes_obs +
p_no_pred p_no_obs).  HSS 0: no skill over chance, 1: perfect, < 0: worse than chance.
"""
from __future__ import annotations

import numpy as np


def skill(predicted, observed, considered=None) -> dict:
    """Scores of boolean ``predicted`` against ``observed`` (same shape) over the ``considered`` entries (all by
    default): n, accuracy, base_rate (share of the majority observed class), hss, hit_rate (predicted yes among
    observed yes), false_alarm_ratio (observed no among predicted yes), p_pred, p_obs (shares of yes)."""
    p = np.asarray(predicted, bool)
    o = np.asarray(observed, bool)
    if p.shape != o.shape:
        raise ValueError(f"skill: predicted {p.shape} and observed {o.shape} differ in shape")
    m = np.ones(p.shape, bool) if considered is None else np.asarray(considered, bool)
    p, o = p[m], o[m]
    n = int(p.size)
    if n == 0:
        raise ValueError("skill: no entry to score")
    a, b = int(np.sum(p & o)), int(np.sum(p & ~o))          # hits, false alarms
    c, d = int(np.sum(~p & o)), int(np.sum(~p & ~o))        # misses, correct negatives
    pc = (a + d) / n
    pp, po = (a + b) / n, (a + c) / n
    e = pp * po + (1.0 - pp) * (1.0 - po)
    return {"n": n, "accuracy": pc, "base_rate": max(po, 1.0 - po),
            "hss": (pc - e) / (1.0 - e) if e < 1.0 else float("nan"),
            "hit_rate": a / (a + c) if a + c else float("nan"),
            "false_alarm_ratio": b / (a + b) if a + b else float("nan"), "p_pred": pp, "p_obs": po}


def count_agreement(predicted, observed, considered=None, tolerances=(0, 1, 2)) -> dict:
    """Per-epoch agreement of the NUMBER of good satellites: ``predicted`` and ``observed`` booleans of shape
    (epochs, satellites), counted per epoch over the ``considered`` entries (all by default); an epoch without any
    considered entry is left out.  Furukawa, Kubo and El-Mowafy (ION ITM 2020, pp. 763-771) score this way: the
    number of predicted and measured satellites with good signal quality "in agreement at least 87.8 % of the
    time" (per epoch, not per satellite-epoch).

    Returns n_epochs; mean_predicted, mean_observed (counts per epoch); constant, the reference forecast: the
    observed median count rounded half up (always answering it, the base rate of a count); and per tolerance k
    (0: equal) ``within[k]``, the share of epochs with |predicted - observed| <= k, ``base_within[k]`` the same for
    the constant, ``skill[k]`` = (within - base_within) / (1 - base_within) (the generic skill score over a
    reference forecast, Wilks, Statistical Methods in the Atmospheric Sciences; nan when the base is perfect)."""
    p = np.asarray(predicted, bool)
    o = np.asarray(observed, bool)
    if p.shape != o.shape or p.ndim != 2:
        raise ValueError(f"count_agreement: predicted {p.shape} and observed {o.shape} must be the same "
                         "(epochs, satellites) shape")
    m = np.ones(p.shape, bool) if considered is None else np.asarray(considered, bool)
    if m.shape != p.shape:
        raise ValueError(f"count_agreement: considered {m.shape} differs from {p.shape}")
    rows = m.any(axis=1)
    if not rows.any():
        raise ValueError("count_agreement: no epoch to score")
    n_pred = np.sum(p & m, axis=1)[rows]
    n_obs = np.sum(o & m, axis=1)[rows]
    constant = int(np.floor(np.median(n_obs) + 0.5))
    within, base, gain = {}, {}, {}
    for k in tolerances:
        within[k] = float(np.mean(np.abs(n_pred - n_obs) <= k))
        base[k] = float(np.mean(np.abs(constant - n_obs) <= k))
        gain[k] = (within[k] - base[k]) / (1.0 - base[k]) if base[k] < 1.0 else float("nan")
    return {"n_epochs": int(rows.sum()), "mean_predicted": float(n_pred.mean()),
            "mean_observed": float(n_obs.mean()), "constant": constant,
            "within": within, "base_within": base, "skill": gain}


def feature_ceiling(features, observed, considered=None, fit=None) -> dict:
    """What ``features`` can tell about boolean ``observed`` at best: the accuracy of the best yes/no prediction
    that is a function of the features alone (each combination of feature values answered by its majority).

    ``features``: integer arrays (bin continuous ones first) broadcastable to ``observed``'s shape; scored over the
    ``considered`` entries (all by default).  Without ``fit`` the majorities are those of the scored entries
    themselves (in-sample): no predictor from these features scores more on this sample, so a target above it
    needs other information.  With ``fit`` (boolean, same shape) the majorities come from the considered ``fit``
    entries and the score from the considered others (a combination not met in the fit part answered by the fit
    part's majority): what such a rule, fitted once, carries to data it did not see.

    Returns n (entries scored), accuracy, base_rate (the scored entries' majority share), groups (feature
    combinations met where the majorities come from)."""
    o = np.asarray(observed, bool)
    m = np.ones(o.shape, bool) if considered is None else np.asarray(considered, bool)
    if m.shape != o.shape:
        raise ValueError(f"feature_ceiling: considered {m.shape} differs from observed {o.shape}")
    if not len(features):
        raise ValueError("feature_ceiling: no feature given")
    try:
        cols = [np.broadcast_to(np.asarray(f), o.shape)[m] for f in features]
    except ValueError:
        raise ValueError(f"feature_ceiling: features {[np.shape(f) for f in features]} do not broadcast to "
                         f"observed {o.shape}") from None
    if any(c.dtype.kind not in "biu" for c in cols):
        raise ValueError("feature_ceiling: features must be integer arrays (bin continuous ones first)")
    y = o[m]
    train = np.ones(y.shape, bool) if fit is None else np.broadcast_to(np.asarray(fit, bool), o.shape)[m]
    score = np.ones(y.shape, bool) if fit is None else ~train
    if not train.any() or not score.any():
        raise ValueError("feature_ceiling: no entry to fit on or none to score")
    _, group = np.unique(np.stack(cols, axis=1), axis=0, return_inverse=True)
    group = group.reshape(-1)
    n_groups = int(group.max()) + 1
    yes = np.bincount(group[train], weights=y[train], minlength=n_groups)
    total = np.bincount(group[train], minlength=n_groups)
    overall = 2 * y[train].sum() > train.sum()           # the fit part's majority (ties: "no")
    answer = np.where(total > 0, 2 * yes > total, overall)
    p_obs = float(y[score].mean())
    return {"n": int(score.sum()), "accuracy": float(np.mean(answer[group[score]] == y[score])),
            "base_rate": max(p_obs, 1.0 - p_obs), "groups": int(np.count_nonzero(total))}

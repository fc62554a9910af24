"""Compare simulated and real GNSS observations (the thesis's comparison chapter, as a tool).

Inputs are RINEX 3 observation files (read with georinex) or rosbag2 bags
holding ``gnss_sim_msgs/Observations`` (read with rosbags); both become one
:class:`ObsTable`: epochs (GPS time) x satellites, one (epoch, sv) array per
RINEX observation code ("C1C", "L1C", "D1C", "S1C"), NaN where absent.

Method (:func:`compare`):

* Epochs are matched by time (to 1 ms), satellites by id, signals by RINEX
  band and tracking attribute: the same code first, else another attribute of
  the same band ("C1X" real against "C1C" simulated): :func:`pair_signals`.
* Pseudorange: d = P_sim - P_real.  The receiver clocks of both receivers
  differ per epoch; per epoch and system the median of d over the common
  satellites of that system's reference signal (its first paired code) is
  taken; the reference system (GPS when present) gives the clock offset of
  the epoch, every other system one constant inter-system bias (median over
  epochs of its median minus the reference one).  Residuals
  d - clock(epoch) - ISB(system) are what the tables show.  A residual above
  ``gross_m`` counts as a gross error and is left out of the statistics
  (counted separately).
* Carrier phase: the integer ambiguity of each track is arbitrary, so phases
  are compared **time-differenced** (delta range): dL = lambda (L(e) - L(e-1))
  between consecutive common epochs, sim minus real, with the same per-epoch
  median removal (the receiver clock change).  Cycle slips show up as outliers.
* Doppler: as range rate -lambda D [m/s] (so that bands share the receiver
  clock drift), sim minus real, per-epoch median removed (clock drift).
* C/N0: S observations, sim minus real [dB-Hz], nothing removed.
  Doppler and C/N0 are reported *unavailable* when one side has none (the
  OPEC real file has neither): never as zero.
* Visibility: per epoch the satellites with a code observation, on the
  systems both files observe (optionally above an elevation mask computed
  from the navigation data): seen by both / only simulated / only real and
  the Jaccard index |both| / |union| over (epoch, satellite) pairs.
* Signals: per-signal statistics of both files (core/calibration/signal_stats.py, the ones ``gnss-sim
  calibrate`` fits to) compared by core/comparison/signal_compare.py: Jaccard of (epoch, satellite, signal)
  triples above the mask, C/N0 per 10-degree bin, code noise by the multipath combination, LLI at the first
  epoch (needs elevations: ``nav_paths``).
* Positions: single point solutions of both files with the same solver
  (:func:`spp_solutions`: our :func:`~gnss_sim_ros2.core.solver.solve_pvt`
  with the broadcast ephemeris, Klobuchar ionosphere and Saastamoinen/Niell
  troposphere; or RTKLIB rnx2rtkp with the same models), against each other
  and against a ground truth (default: the real file's APPROX POSITION).

:func:`write_report` writes ``report.md`` and PNG figures (matplotlib Agg).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import constants as k
from ..calibration.reading import elevations_deg
from ..calibration.signal_stats import RecordingStats, signal_statistics
from ..ephemeris.broadcast import BroadcastEphemeris
from ..input_file import not_a_file
from ..receiver.outputs import write_navigation
from ..rinex.header import read_obs_header
from ..rinex.obs_table import EPOCH_MATCH_NS, ObsTable, match_epochs
from .canyon import Canyon, canyon_split
from .pairing import SignalPair, pair_signals
from .rtklib import rtklib_solutions
from .signal_compare import compare_statistics
from .sources import load_observations
from .spp import Solutions, spp_solutions
from .statistics import (
    GROSS_LIMITS,
    KINDS,
    KindResult,
    enu_errors_m,
    position_stats,
    remove_common_offsets,
    summary_stats,
)
from .truth import truth_from_csv


@dataclass
class Comparison:
    """Everything :func:`write_report` needs (arrays over common epochs x ``sv``)."""

    sim: ObsTable
    real: ObsTable
    time: np.ndarray                     #: (E,) common epochs
    sv: np.ndarray                       #: (S,) satellites of the common systems (union of both)
    systems: str                         #: systems observed by both
    systems_only_sim: str
    systems_only_real: str
    epochs_only_sim: int
    epochs_only_real: int
    pairs: list[SignalPair]
    kinds: dict[str, KindResult]         #: "code" | "phase" | "doppler" | "cn0"
    seen_sim: np.ndarray                 #: (E, S) bool, above the mask
    seen_real: np.ndarray
    el_deg: np.ndarray | None            #: (E, S) elevation at the truth position (None without nav)
    mask_deg: float
    sim_cn0: dict[SignalPair, np.ndarray] = field(default_factory=dict)    #: (E, S) raw S of each side
    real_cn0: dict[SignalPair, np.ndarray] = field(default_factory=dict)
    truth_ecef_m: np.ndarray | None = None   #: (E, 3)
    truth_label: str = ""
    sol_sim: Solutions | None = None
    sol_real: Solutions | None = None
    position_note: str = ""
    warnings: list[str] = field(default_factory=list)   #: the inputs look like two sites or two days
    #: per-signal statistics of both sides and their comparison (core/calibration; None without elevations)
    signal_stats_sim: RecordingStats | None = None
    signal_stats_real: RecordingStats | None = None
    signals: dict | None = None
    #: the real file's own truth (E, 3) when it differs from the simulated one's (``real_truth_csv``); else None
    truth_real_ecef_m: np.ndarray | None = None
    truth_real_label: str = ""
    #: the line-of-sight / NLOS split by a scene (core/comparison/canyon.py; None without a scene)
    canyon: Canyon | None = None
    epoch_tol_ms: float = 1.0            #: epochs matched within this [ms]
    max_tag_difference_ms: float = 0.0   #: largest time-tag difference of the matched epochs [ms]
    #: :attr:`signals` over the line-of-sight ("los") and the NLOS ("nlos") satellite-epochs (with a scene)
    signals_split: dict = field(default_factory=dict)

    # ------------------------------------------------------------------ summaries
    def sys_of_col(self) -> np.ndarray:
        return np.array([s[0] for s in self.sv.tolist()])

    def stats(self, kind: str, pair: SignalPair, sv: str | None = None) -> dict:
        kr = self.kinds[kind]
        d = kr.residuals.get(pair)
        if d is None:
            return summary_stats(np.zeros(0), GROSS_LIMITS[kind])
        d = d[:, self.sv == sv] if sv is not None else d[:, self.sys_of_col() == pair.system]
        return summary_stats(d, GROSS_LIMITS[kind])

    def system_stats(self, kind: str, system: str) -> dict:
        """Statistics of every pair of ``system`` together."""
        kr = self.kinds[kind]
        cols = self.sys_of_col() == system
        parts = [kr.residuals[p][:, cols].ravel() for p in self.pairs if p.system == system and p in kr.residuals]
        return summary_stats(np.concatenate(parts) if parts else np.zeros(0), GROSS_LIMITS[kind])

    def per_satellite(self, kind: str, pair: SignalPair) -> dict[str, dict]:
        out = {}
        for s in self.sv.tolist():
            if s[0] == pair.system:
                st = self.stats(kind, pair, s)
                if st["n"] or st["n_gross"]:
                    out[s] = st
        return out

    def visibility(self) -> dict:
        """Jaccard per system and overall, satellites seen by one side only, per-satellite epoch counts."""
        both = self.seen_sim & self.seen_real
        only_s = self.seen_sim & ~self.seen_real
        only_r = self.seen_real & ~self.seen_sim
        sysc = self.sys_of_col()
        jac = {}
        for s in self.systems:
            c = sysc == s
            u = (self.seen_sim | self.seen_real)[:, c].sum()
            jac[s] = float(both[:, c].sum() / u) if u else math.nan
        u = (self.seen_sim | self.seen_real).sum()
        jac["all"] = float(both.sum() / u) if u else math.nan
        per_sv = {s: {"both": int(both[:, j].sum()), "only_sim": int(only_s[:, j].sum()),
                      "only_real": int(only_r[:, j].sum())} for j, s in enumerate(self.sv.tolist())}
        never_real = [s for s, c in per_sv.items() if c["only_sim"] and not c["both"]]
        never_sim = [s for s, c in per_sv.items() if c["only_real"] and not c["both"]]
        return {"jaccard": jac, "per_sv": per_sv, "only_sim_svs": never_real, "only_real_svs": never_sim,
                "n_both": int(both.sum()), "n_only_sim": int(only_s.sum()), "n_only_real": int(only_r.sum())}

    def solved_epochs(self) -> dict:
        """Epochs each side solved (and has a truth, where one is given) and those both did."""
        if self.sol_sim is None or self.sol_real is None:
            return {}
        ok = {}
        for name, sol, tr in (("sim", self.sol_sim, self.truth_ecef_m), ("real", self.sol_real, self.real_truth())):
            o = np.all(np.isfinite(sol.pos_ecef_m), axis=1)
            ok[name] = o & np.all(np.isfinite(tr), axis=1) if tr is not None else o
        return {"sim": int(ok["sim"].sum()), "real": int(ok["real"].sum()), "both": int((ok["sim"] & ok["real"]).sum()),
                "mask": ok["sim"] & ok["real"]}

    def real_truth(self) -> np.ndarray | None:
        """The real file's truth: its own (``real_truth_csv``) or the common one."""
        return self.truth_real_ecef_m if self.truth_real_ecef_m is not None else self.truth_ecef_m

    def positions(self) -> dict:
        """Position statistics on the epochs both sides solved (:meth:`solved_epochs`), each against its own truth."""
        out = {}
        if self.sol_sim is None or self.sol_real is None:
            return out
        both = self.solved_epochs()["mask"]

        def common(pos):
            p = np.array(pos, dtype=float)
            p[~both] = np.nan
            return p

        if self.truth_ecef_m is not None:
            out["sim_vs_truth"] = position_stats(enu_errors_m(common(self.sol_sim.pos_ecef_m), self.truth_ecef_m))
            out["real_vs_truth"] = position_stats(enu_errors_m(common(self.sol_real.pos_ecef_m), self.real_truth()))
        out["sim_vs_real"] = position_stats(enu_errors_m(common(self.sol_sim.pos_ecef_m), self.sol_real.pos_ecef_m))
        return out


class CompareWarning(UserWarning):
    """The two inputs look like different sites or days: the statistics mix what should not be mixed."""


#: farther apart than this the two files are not one site [m]
SITE_APART_M = 5000.0


def _first_day(tab: ObsTable, path) -> np.datetime64:
    """Day of the first observation of a file (RINEX header TIME OF FIRST OBS, else its first epoch)."""
    if tab.kind == "rinex":
        first = read_obs_header(Path(path))["first_obs"]
        if first is not None:
            return first.astype("datetime64[D]")
    return tab.time[0].astype("datetime64[D]")


def _input_warnings(cmp: Comparison, sim_path, real_path) -> list[str]:
    """Messages when the files are more than SITE_APART_M apart (headers or solutions) or of different days."""
    out = []
    a, b = cmp.sim.approx_pos_ecef_m, cmp.real.approx_pos_ecef_m
    if a is not None and b is not None and np.linalg.norm(a - b) > SITE_APART_M:
        out.append(f"{sim_path} and {real_path}: APPROX POSITION XYZ {np.linalg.norm(a - b) / 1000.0:.1f} km apart: "
                   "not one site, the differences mix two places")
    elif cmp.sol_sim is not None and cmp.sol_real is not None:
        d = np.linalg.norm(cmp.sol_sim.pos_ecef_m - cmp.sol_real.pos_ecef_m, axis=1)
        d = d[np.isfinite(d)]
        if d.size and np.median(d) > SITE_APART_M:
            out.append(f"{sim_path} and {real_path}: their single point positions are {np.median(d) / 1000.0:.1f} km "
                       "apart (median): not one site, the differences mix two places")
    day_s, day_r = _first_day(cmp.sim, sim_path), _first_day(cmp.real, real_path)
    if day_s != day_r:
        out.append(f"{sim_path} starts on {day_s}, {real_path} on {day_r}: files of different days")
    return out


def _kind_diffs(c: str, sim: ObsTable, real: ObsTable, pairs, svs, i_sim, i_real) -> dict[SignalPair, np.ndarray]:
    """Raw sim - real of observation kind ``c`` per pair over (common epoch, svs) (phase: time-differenced,
    metres; Doppler: range rate m/s)."""
    js = {s: j for j, s in enumerate(sim.sv.tolist())}
    jr = {s: j for j, s in enumerate(real.sv.tolist())}
    out = {}
    for p in pairs:
        a = np.full((len(i_sim), len(svs)), np.nan)
        b = np.full((len(i_sim), len(svs)), np.nan)
        cs, cr = sim.values.get(c + p.sim_code), real.values.get(c + p.real_code)
        if cs is None or cr is None:
            continue
        for j, s in enumerate(svs.tolist()):
            if s[0] != p.system or s not in js or s not in jr:
                continue
            x, y = cs[i_sim, js[s]], cr[i_real, jr[s]]
            if c in "LD":   # to metres (phase) and m/s (Doppler, as -lambda D)
                lam_s = k.C_MPS / sim.frequency_hz(s, p.sim_code)
                lam_r = k.C_MPS / real.frequency_hz(s, p.real_code)
                x, y = x * lam_s, y * lam_r
                if c == "D":
                    x, y = -x, -y
            a[:, j], b[:, j] = x, y
        if c == "L":
            a = np.vstack([np.full((1, a.shape[1]), np.nan), np.diff(a, axis=0)])
            b = np.vstack([np.full((1, b.shape[1]), np.nan), np.diff(b, axis=0)])
        out[p] = a - b
    return out


def _signal_statistics(cmp: Comparison, i_sim, i_real) -> None:
    """Per-signal statistics of both files over the common epochs (10-degree bins, the comparison's mask) and
    their comparison (core/comparison/signal_compare.py); with a scene also over the line-of-sight and the NLOS
    satellite-epochs of each file (:attr:`Comparison.signals_split`).  The real file's matched epochs carry the
    simulated time labels (epochs matched within ``epoch_tol_ms`` are one epoch)."""
    col = {s: j for j, s in enumerate(cmp.sv.tolist())}
    sides = []
    for tab, idx, name in ((cmp.sim, i_sim, "sim"), (cmp.real, i_real, "real")):
        el = np.full((len(idx), len(tab.sv)), np.nan)
        for j, s in enumerate(tab.sv.tolist()):
            if s in col:
                el[:, j] = cmp.el_deg[:, col[s]]
        sub = tab.subset(epochs=idx)
        sub.time = cmp.time
        sides.append((sub, el, name))
    pairs = [(p.system, p.sim_code, p.real_code) for p in cmp.pairs]
    out = [signal_statistics(sub, el, mask_deg=cmp.mask_deg, bin_deg=10.0) for sub, el, _ in sides]
    cmp.signal_stats_sim, cmp.signal_stats_real = out
    cmp.signals = compare_statistics(*out, pairs)
    if cmp.canyon is not None:
        for cls in ("los", "nlos"):
            st = [signal_statistics(sub, el, mask_deg=cmp.mask_deg, bin_deg=10.0,
                                    los=cmp.canyon.selection(name, cls, sub.sv), scene=cmp.canyon.scene)
                  for sub, el, name in sides]
            cmp.signals_split[cls] = compare_statistics(*st, pairs)


def compare(sim_path, real_path, nav_paths=None, truth_ecef_m=None, truth_csv=None, mask_deg: float = 0.0,
            solver: str = "ours", restrict_real_to_sim_span: bool = True, workdir=None, *, real_truth_csv=None,
            scene=None, scene_name: str = "", ground_height_m: float | None = None,
            epoch_tol_ms: float | None = None) -> Comparison:
    """Compare two observation sources (RINEX or bag).  ``nav_paths``: broadcast navigation files for
    elevations and positions (none: no positions, no elevations); ``truth_ecef_m`` (3,) or ``truth_csv``
    (default truth: the real file's APPROX POSITION, else the simulated one's); ``real_truth_csv``: the real
    file's own truth when the simulation was made on another path; ``mask_deg`` applies to
    the visibility sets where an elevation is known; ``solver`` "ours" | "rtklib" (RINEX inputs only);
    ``scene`` (a loaded Scene, ``scene_name`` its option and file): the line-of-sight / NLOS split
    (core/comparison/canyon.py; needs ``nav_paths``), ``ground_height_m`` places the truth that high above the
    scene's ground; ``epoch_tol_ms``: epochs of the two files matched within this [ms] (default 1 ms; a receiver
    whose time tags wander by milliseconds, like the Hong Kong u-blox's +-3 ms, needs more: its code differences then
    carry range rate x tag difference, reported)."""
    if solver not in ("ours", "rtklib"):
        raise ValueError(f"solver {solver!r}: expected 'ours' or 'rtklib'")
    if truth_ecef_m is not None and truth_csv is not None:
        raise ValueError("give either truth_ecef_m or truth_csv, not both")
    sim = load_observations(sim_path)
    if not len(sim.time):
        raise ValueError(f"{sim_path}: no observation epochs")
    tlim = (sim.time[0] - np.timedelta64(1, "s"), sim.time[-1] + np.timedelta64(1, "s")) \
        if restrict_real_to_sim_span else None
    real = load_observations(real_path, tlim)
    if not len(real.time):
        raise ValueError(f"{real_path}: no observation epochs"
                         + (" within the simulated span" if restrict_real_to_sim_span else ""))
    if epoch_tol_ms is not None and not 0.0 < epoch_tol_ms <= 500.0:
        raise ValueError(f"--epoch-tol-ms {epoch_tol_ms!r}: the epoch tolerance must be in (0, 500] ms")
    tol_ns = EPOCH_MATCH_NS if epoch_tol_ms is None else int(round(epoch_tol_ms * 1e6))
    i_sim, i_real = match_epochs(sim.time, real.time, tol_ns)
    if not len(i_sim):
        raise ValueError(f"{sim_path} ({sim.time[0]} .. {sim.time[-1]}) and {real_path} "
                         f"({real.time[0]} .. {real.time[-1]}) have no common epoch")
    sys_s, sys_r = sim.systems, real.systems
    systems = "".join(s for s in sys_s if s in sys_r)
    svs = np.array(sorted({s for s in sim.sv.tolist() + real.sv.tolist() if s[0] in systems}), dtype="<U3")
    pairs = pair_signals(sim, real, systems)
    sysc = np.array([s[0] for s in svs.tolist()])
    times = sim.time[i_sim]

    kinds = {}
    for c, name in KINDS.items():
        ps = [p for p in pairs if sim.has_data(c + p.sim_code) and real.has_data(c + p.real_code)]
        if not ps:
            lacking = [lab for lab, t in (("simulated", sim), ("real", real))
                       if not any(t.has_data(c + (p.sim_code if t is sim else p.real_code)) for p in pairs)]
            why = (f"the {' and the '.join(lacking)} file{'s have' if len(lacking) > 1 else ' has'} no "
                   f"{c} ({name}) observations" if lacking else f"no signal has {c} observations on both sides")
            kinds[name] = KindResult(name, False, why, {})
            continue
        raw = _kind_diffs(c, sim, real, ps, svs, i_sim, i_real)
        if name == "cn0":
            kinds[name] = KindResult(name, True, "", raw)
        else:
            res, clock, isb, ref = remove_common_offsets(raw, sysc)
            kinds[name] = KindResult(name, True, "", res, clock, isb, ref)

    def seen(tab: ObsTable, idx):
        j = {s: i for i, s in enumerate(tab.sv.tolist())}
        out = np.zeros((len(idx), len(svs)), dtype=bool)
        codes = [c for c in tab.values if c[0] == "C"]
        for col, s in enumerate(svs.tolist()):
            if s in j:
                out[:, col] = np.any([np.isfinite(tab.values[c][idx, j[s]]) for c in codes], axis=0) if codes else False
        return out

    seen_sim, seen_real = seen(sim, i_sim), seen(real, i_real)

    # truth
    truth_label = ""
    truth = None
    if truth_csv is not None:
        truth = truth_from_csv(truth_csv, times)
        truth_label = f"CSV {truth_csv}"
    elif truth_ecef_m is not None:
        truth = np.tile(np.asarray(truth_ecef_m, float).reshape(1, 3), (len(times), 1))
        truth_label = "given ECEF " + ", ".join(f"{v:.3f}" for v in np.ravel(truth_ecef_m))
    elif real.approx_pos_ecef_m is not None:
        truth = np.tile(real.approx_pos_ecef_m, (len(times), 1))
        truth_label = "real file header APPROX POSITION XYZ"
    elif sim.approx_pos_ecef_m is not None:
        truth = np.tile(sim.approx_pos_ecef_m, (len(times), 1))
        truth_label = "simulated file header APPROX POSITION XYZ"

    tag_ms = np.abs((real.time[i_real] - times).astype("timedelta64[ns]").astype(np.int64)) / 1e6
    cmp = Comparison(sim, real, times, svs, systems, "".join(s for s in sys_s if s not in sys_r),
                     "".join(s for s in sys_r if s not in sys_s), len(sim.time) - len(i_sim),
                     len(real.time) - len(i_real), pairs, kinds, seen_sim, seen_real, None, mask_deg,
                     truth_ecef_m=truth, truth_label=truth_label)
    cmp.epoch_tol_ms, cmp.max_tag_difference_ms = tol_ns / 1e6, float(tag_ms.max())
    # raw C/N0 for the figure
    for p in pairs:
        for tab, idx, dst, code in ((sim, i_sim, cmp.sim_cn0, p.sim_code), (real, i_real, cmp.real_cn0, p.real_code)):
            a = tab.values.get("S" + code)
            if a is None or not np.isfinite(a).any():
                continue
            j = {s: i for i, s in enumerate(tab.sv.tolist())}
            m = np.full((len(idx), len(svs)), np.nan)
            for col, s in enumerate(svs.tolist()):
                if s in j and s[0] == p.system:
                    m[:, col] = a[idx, j[s]]
            dst[p] = m

    if nav_paths:
        nav_paths = [str(p) for p in nav_paths]
        for p in nav_paths:
            if (why := not_a_file(p)) is not None:
                raise ValueError(f"--nav {p}: {why}")
        eph = BroadcastEphemeris.from_files(nav_paths)
        rx = truth if truth is not None else None
        sys_nav = "".join(s for s in systems if s in "GRECJI" and eph.svs(s))
        ref = {}        # per system its first signal with pseudoranges on both sides
        for p in pairs:
            if (p.system in sys_nav and p.system not in ref and sim.has_data("C" + p.sim_code)
                    and real.has_data("C" + p.real_code)):
                ref[p.system] = p
        code_sim = {s: p.sim_code for s, p in ref.items()}
        code_real = {s: p.real_code for s, p in ref.items()}
        if solver == "rtklib" and not (sim.kind == real.kind == "rinex"):
            cmp.position_note = "RTKLIB needs RINEX inputs: gnss_sim solve_pvt used instead"
            solver = "ours"
        if solver == "rtklib":
            wd = Path(workdir) if workdir is not None else Path(sim_path).parent
            wd.mkdir(parents=True, exist_ok=True)
            # RTKLIB gets the navigation data as our reader understood it (one merged RINEX 3.04 file):
            # some published files need repairs it does not make (BeiDou angles in semicircles)
            merged = write_navigation(wd / "rtklib_nav.rnx", eph, "".join(ref))
            cmp.sol_sim = rtklib_solutions(sim_path, [merged], "".join(ref), times, wd / "rtklib_sim")
            cmp.sol_real = rtklib_solutions(real_path, [merged], "".join(ref), times, wd / "rtklib_real")
            cmp.position_note = "; ".join(n for n in (cmp.sol_sim.note, cmp.sol_real.note) if n)
        elif ref:
            prior = truth[0] if truth is not None and np.all(np.isfinite(truth[0])) else None
            cmp.sol_sim = spp_solutions(sim, eph, code_sim, i_sim, prior)
            cmp.sol_real = spp_solutions(real, eph, code_real, i_real, prior)
        if rx is None and cmp.sol_real is not None:
            rx = cmp.sol_real.pos_ecef_m
        if rx is not None:
            cmp.el_deg = elevations_deg(eph, times, svs, rx)
            if mask_deg > 0:
                low = np.isfinite(cmp.el_deg) & (cmp.el_deg < mask_deg)
                cmp.seen_sim = cmp.seen_sim & ~low
                cmp.seen_real = cmp.seen_real & ~low
    if real_truth_csv is not None:
        cmp.truth_real_ecef_m = truth_from_csv(real_truth_csv, times)
        cmp.truth_real_label = f"CSV {real_truth_csv}"
    if scene is not None:
        if not nav_paths or not ref:
            raise ValueError(f"{scene_name or 'the scene'}: the line-of-sight split needs --nav and a signal with "
                             "pseudoranges on both sides")
        if cmp.truth_ecef_m is None:
            raise ValueError(f"{scene_name or 'the scene'}: the line-of-sight split needs a truth (--truth, "
                             "--truth-csv or an APPROX POSITION XYZ)")
        cmp.canyon = canyon_split(sim_path, real_path, scene, scene_name, eph, times, cmp.truth_ecef_m,
                                  cmp.real_truth(), "".join(ref), code_sim, code_real, mask_deg, ground_height_m)
    if cmp.el_deg is not None:
        _signal_statistics(cmp, i_sim, i_real)
    cmp.warnings = _input_warnings(cmp, sim_path, real_path)
    for msg in cmp.warnings:
        warnings.warn(msg, CompareWarning, stacklevel=2)
    return cmp

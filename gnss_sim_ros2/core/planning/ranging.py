"""The ranging error budget (UERE) of a receiver profile, per satellite: what "HDOP x UERE" multiplies.

sigma_i^2 = SISRE(system)^2 + (iono_error_frac x I_z x F(el))^2 + (T_z / sin el)^2 + mp(el)^2 + dll(C/N0)^2
          [+ NLOS excess^2 for a reflected-only satellite]

- SISRE: the receiver configuration's broadcast orbit + clock error per system (``ReceiverConfig.sisre_m``,
  Montenbruck et al., GPS Solutions 19:321, 2015, physics-anchors.md);
- ionosphere: the residual the simulator leaves after the receiver's Klobuchar correction (``iono_error_frac``
  ["klobuchar"] = 0.5, about 50 % of the RMS delay removed: Navipedia) of a nominal zenith delay I_z =
  NOMINAL_ZENITH_IONO_L1_M (an assumption: about 18 TECU, a mid-latitude daytime value; the real one varies by
  a factor of ten over a day and the solar cycle), mapped by the ICD's obliquity F = 1 + 16 (0.53 - E)^3
  (E in semicircles, IS-GPS-200N 20.3.3.5.2.5); single frequency for every profile (the simulator's point
  solution corrects the ionosphere by the broadcast model);
- troposphere: the residual of the Saastamoinen + mapping correction, T_z = TROPO_RESIDUAL_ZENITH_M (a few cm:
  UNB3m-class models against radiosondes, physics-anchors.md) over sin(el);
- code multipath: the profile's open-sky model (receiver/code_multipath.py, mp_zenith_m + mp_low_m
  exp(-el / 15 deg) or its table);
- DLL thermal noise at NOMINAL_LOS_CN0_DBHZ minus the satellite's attenuation (receiver/noise.py, Kaplan eq.
  5.23, the profile's loop bandwidth, spacing, integration and front end) on the profile's first signal.

NLOS: a reflected-only satellite (multipath on) adds its excess path (the scene's shortest reflection's,
``VisibilityResult.extra_path_m``) as a bias: NLOS pseudorange errors are the positive excess delay of the
reflection (Hsu, GPS Solutions 22:7, 2018), tens of metres in Hong Kong canyons; the expected accuracy
HDOP x UERE then takes the RMS of the used satellites' sigma_i, so a larger NLOS share inflates it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: nominal zenith ionospheric delay at L1 [m] (assumption: about 18 TECU x 0.162 m/TECU; module doc)
NOMINAL_ZENITH_IONO_L1_M = 3.0
#: zenith troposphere residual after the model [m] (module doc)
TROPO_RESIDUAL_ZENITH_M = 0.05
_SIN_1_DEG = float(np.sin(np.radians(1.0)))
#: C/N0 of an unobstructed satellite for the thermal noise term [dB-Hz] (Kaplan's table at 45 dB-Hz: 0.82 m
#: for a 0.5-chip C/A DLL at 1 Hz; physics-anchors.md)
NOMINAL_LOS_CN0_DBHZ = 45.0


@dataclass
class RangingBudget:
    """Per system: SISRE [m], whether tracked on two frequencies, thermal noise at the nominal C/N0 [m]."""

    profile: str
    sisre_m: dict
    dual_frequency: dict
    iono_frac: float
    multipath: object                # CodeMultipath of the profile (sigma_m(el))
    thermal: dict                    # system -> callable(cn0_dbhz) -> sigma [m]

    def sigma_m(self, systems, el_deg, attenuation_db=0.0, nlos_excess_m=0.0) -> np.ndarray:
        """(K, N) sigma_i [m] of satellites of ``systems`` (N,) letters at ``el_deg`` (K, N) (module doc)."""
        el = np.asarray(el_deg, np.float64)
        sysv = np.broadcast_to(np.asarray(systems), el.shape)
        att = np.broadcast_to(np.asarray(attenuation_db, float), el.shape)
        ex = np.broadcast_to(np.asarray(nlos_excess_m, float), el.shape)
        return self.sigma_entries_m(sysv.ravel(), el.ravel(), att.ravel(), ex.ravel()).reshape(el.shape)

    def sigma_entries_m(self, systems, el_deg, attenuation_db, nlos_excess_m) -> np.ndarray:
        """sigma_i [m] of entries (K,): system letter, elevation, attenuation and NLOS excess each (K,)."""
        letters, column = np.unique(np.asarray(systems), return_inverse=True)
        return self.sigma_of_columns_m(letters, column, el_deg, attenuation_db, nlos_excess_m)

    def sigma_of_columns_m(self, column_systems, column, el_deg, attenuation_db, nlos_excess_m,
                           sin_el=None) -> np.ndarray:
        """sigma_i [m] of entries (K,) whose system is ``column_systems[column]`` (a satellite column's letter, no
        string per entry); elevation, attenuation and NLOS excess each (K,).  The thermal term of an unattenuated
        entry is its system's at the nominal C/N0, computed once.  ``sin_el``: the sines of the elevations when
        known (the up components of the unit lines of sight: no sine per entry), else from ``el_deg``."""
        return np.sqrt(self.variance_of_columns_m2(column_systems, column, el_deg, attenuation_db, nlos_excess_m,
                                                   sin_el))

    def variance_of_columns_m2(self, column_systems, column, el_deg, attenuation_db, nlos_excess_m,
                               sin_el=None) -> np.ndarray:
        """sigma_i^2 [m^2] of :meth:`sigma_of_columns_m`'s entries (what the UERE sums: no root taken and squared
        again)."""
        el = np.clip(np.asarray(el_deg, np.float64), 1.0, 90.0)
        x = 0.53 - el / 180.0
        obliq = 1.0 + 16.0 * (x * x * x)                            # IS-GPS-200N 20.3.3.5.2.5 (cube: no pow)
        var = (self.iono_frac * NOMINAL_ZENITH_IONO_L1_M * obliq) ** 2
        if sin_el is None:
            sin_el = np.sin(np.radians(el))
        else:                                                       # the same clip as the elevation's
            sin_el = np.clip(np.asarray(sin_el, np.float64), _SIN_1_DEG, 1.0)
        var = var + (TROPO_RESIDUAL_ZENITH_M / sin_el) ** 2
        var = var + self.multipath.sigma_m(el) ** 2
        col_sys = np.asarray(column_systems).reshape(-1).tolist()
        col = np.asarray(column, np.int64)
        att = np.asarray(attenuation_db, float)
        sisre2 = np.array([self.sisre_m.get(s, 1.5) ** 2 for s in col_sys])
        th2 = {s: float(self.thermal[s](np.array([NOMINAL_LOS_CN0_DBHZ]))[0]) ** 2 for s in set(col_sys)}
        weak = att != 0.0
        var = var + sisre2[col] + np.where(weak, 0.0, np.array([th2[s] for s in col_sys])[col])
        w = np.flatnonzero(weak)
        if len(w):
            letter = np.array(col_sys)[col[w]]
            for s in np.unique(letter).tolist():
                k = w[letter == s]
                var[k] += self.thermal[s](NOMINAL_LOS_CN0_DBHZ - att[k]) ** 2
        return var + np.asarray(nlos_excess_m, float) ** 2


def budget_from_profile(profile: str, systems: str) -> RangingBudget:
    """The budget of receiver profile ``profile`` (a built-in name or a file) for ``systems``."""
    from ..receiver.code_multipath import CodeMultipath
    from ..receiver.config import ReceiverConfig
    from ..receiver.noise import code_sigma_m

    cfg = ReceiverConfig(profile=profile)
    sig = cfg.profile                                  # after construction: {system: [codes]} tracked
    thermal, dual = {}, {}
    for s in systems:
        codes = sig.get(s) or []
        dual[s] = len({c[0] for c in codes}) >= 2      # two bands (first character of the RINEX code)
        code = codes[0] if codes else None

        def th(cn0, s=s, code=code):
            if code is None:
                return np.full(np.shape(cn0), np.inf)  # not tracked by this profile
            return code_sigma_m(s, code, np.maximum(cn0, 10.0), bn_hz=cfg.dll_bn_hz,
                                spacing_chips=cfg.dll_spacing_chips, t_int_s=cfg.dll_t_int_s,
                                frontend_bw_hz=cfg.frontend_bandwidth_hz)
        thermal[s] = th
    return RangingBudget(str(profile), dict(cfg.sisre_m), dual, float(cfg.iono_error_frac.get("klobuchar", 0.5)),
                         CodeMultipath(cfg, np.random.default_rng(0)), thermal)


def tracked_systems(profile: str, systems: str) -> str:
    """The letters of ``systems`` the profile tracks (ValueError naming --systems / --profile when none)."""
    from ..receiver.config import ReceiverConfig

    sig = ReceiverConfig(profile=profile).profile
    out = "".join(s for s in systems if sig.get(s))
    if not out:
        raise ValueError(f"option --systems {systems!r}: profile {profile!r} tracks none of them "
                         f"(it tracks {''.join(sig)})")
    return out

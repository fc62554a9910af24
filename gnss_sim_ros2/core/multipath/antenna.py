"""Antenna gain for right- and left-hand circular polarisation against elevation of arrival.

Elevation is the arrival direction seen from the antenna (negative: from below, e.g. a ground
reflection).  Two patterns, linear interpolation in dB between the tabulated points:

- ``patch``: the generic mass-market patch (PATCH_GAIN_DBIC, also the C/N0 link budget's in
  receiver/cn0.py; +4 dBic at zenith, -4 dBic at 10 deg) for RHCP.  LHCP = RHCP - XPD(el):
  cross-polar discrimination about 15 dB at zenith falling to 0-3 dB at the horizon: small ceramic
  patches have an axial ratio of 2-3 dB at zenith (XPD = 20 log10((AR + 1) / (AR - 1)) = 19-15 dB)
  that widens towards the horizon (patch data sheets, e.g. u-blox ANN-MB; Hannah 2001, ch. 3; figures
  from memory, not re-read here).  Below the horizon the back lobe (-15 to -25 dBic).
- ``choke_ring``: a geodetic choke ring (e.g. Dorne-Margolin / Leica AR25 class): RHCP +5 dBic at
  zenith rolling off to -5 dBic at 5 deg, steeper below the horizon (-25 dBic at -30 deg and below);
  XPD about 25 dB at zenith, 10 dB at 10 deg (Tranquilla et al., "Analysis of a choke ring groundplane
  for multipath control in GPS applications", IEEE Trans. AP 42(7), 1994: -20 dB back/front; NovAtel
  GNSS-750 class data sheets: front/back ratios of 25 dB and more; from memory, not re-read here).

These are representative tables, not one product's measured pattern: stated approximations.
"""
from __future__ import annotations

import numpy as np

#: generic patch antenna RHCP gain pattern: elevation [deg] -> gain [dBic] (+4 dBic at zenith, -4 dBic at
#: 10 deg, -5.5 dBic at 5 deg, -8 dBic at the horizon; the link budget's default, receiver/cn0.py docstring)
PATCH_EL_DEG = np.array([-90.0, -10.0, 0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0])
PATCH_GAIN_DBIC = np.array([-25.0, -12.0, -8.0, -5.5, -4.0, -2.8, -1.8, -0.2, 1.8, 3.0, 3.7, 4.0])

_PATCH_XPD_EL = np.array([-90.0, -10.0, 0.0, 10.0, 30.0, 60.0, 90.0])
_PATCH_XPD_DB = np.array([0.0, 0.0, 1.0, 4.0, 9.0, 13.0, 15.0])

_CHOKE_EL = np.array([-90.0, -30.0, -10.0, 0.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 90.0])
_CHOKE_RHCP = np.array([-30.0, -25.0, -17.0, -9.0, -5.0, -3.0, -0.5, 1.5, 3.2, 4.3, 5.0])
_CHOKE_XPD_EL = np.array([-90.0, -10.0, 0.0, 10.0, 30.0, 60.0, 90.0])
_CHOKE_XPD_DB = np.array([5.0, 5.0, 7.0, 10.0, 17.0, 22.0, 25.0])

PATTERNS = ("patch", "choke_ring")

#: RINEX header ANT # / TYPE of each pattern: IGS antenna name, A16 type + A4 radome (RINEX 3.04 table A2;
#: IGS rcvr_ant.tab naming); the simulator's own names, as these are representative, not one product's tables
RINEX_ANTENNA_TYPE = {"patch": "GNSS_SIM_PATCH  NONE", "choke_ring": "GNSS_SIM_CHOKE  NONE"}


def gain_dbic(pattern: str, el_deg):
    """(RHCP gain, LHCP gain) [dBic] at arrival elevations ``el_deg`` (array)."""
    el = np.asarray(el_deg, dtype=np.float64)
    if pattern == "patch":
        r = np.interp(el, PATCH_EL_DEG, PATCH_GAIN_DBIC)
        return r, r - np.interp(el, _PATCH_XPD_EL, _PATCH_XPD_DB)
    if pattern == "choke_ring":
        r = np.interp(el, _CHOKE_EL, _CHOKE_RHCP)
        return r, r - np.interp(el, _CHOKE_XPD_EL, _CHOKE_XPD_DB)
    raise ValueError(f"multipath: antenna pattern {pattern!r} is not one of {PATTERNS}")

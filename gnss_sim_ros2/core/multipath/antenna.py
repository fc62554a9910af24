"""Antenna gain for right- and left-hand circular polarisation against elevation of arrival, per antenna
class: the one table of each class, used both by the reflections (multipath/composite.py) and by the C/N0 link
budget (receiver/cn0.py).

Elevation is the arrival direction seen from the antenna (negative: from below, e.g. a ground
reflection).  Three classes, linear interpolation in dB between the tabulated points; a class may have a
second table for the lower L band (1164-1300 MHz: L2, L5/E5, E6/B3, G2/G3) where the literature gives
its pattern as different from L1's:

- ``patch``: the generic mass-market patch (+4 dBic at zenith, -4 dBic at 10 deg, -8 dBic at the
  horizon: 8 dB from zenith to 10 deg; u-blox ANN-MB / Tallysman TW-class data sheets give +3 to +5 dBic
  at zenith; from memory, check) for RHCP, the same table in every band.  LHCP = RHCP - XPD(el):
  cross-polar discrimination about 15 dB at zenith falling to 0-3 dB at the horizon: small ceramic
  patches have an axial ratio of 2-3 dB at zenith (XPD = 20 log10((AR + 1) / (AR - 1)) = 19-15 dB)
  that widens towards the horizon (patch data sheets, e.g. u-blox ANN-MB; Hannah 2001, ch. 3; figures
  from memory, not re-read here).  Below the horizon the back lobe (-15 to -25 dBic).
- ``helical``: a quadrifilar helix (survey / UAV helical antennas, e.g. Tallysman HC-series, Harxon
  helix): a broad beam, +2.5 dBic at zenith, -2 dBic at 10 deg (4.5 dB roll-off), good axial ratio down
  to low elevations (XPD 20 dB at zenith, 8 dB at 10 deg) but a weak back lobe rejection (-15 to -20 dBic
  below; helix data sheets, from memory, check).
- ``choke_ring``: a geodetic choke ring with a Dorne-Margolin element (AOAD/M_T, ASH701945, LEIAR25,
  TRM59800 class): RHCP +5 dBic at zenith, -8 dBic at 10 deg and -11 dBic at 5 deg on L1 (a 13 dB
  roll-off to 10 deg, the steepest of the three: the choke rings suppress the low-elevation and below-horizon
  field; NovAtel GNSS-750 and Leica AR25 data sheets give about +5 dBic at zenith and 10-13 dB roll-off to
  10 deg, Tranquilla et al., "Analysis of a choke ring groundplane for multipath control in GPS
  applications", IEEE Trans. AP 42(7), 1994, a -20 dB back/front ratio; from memory, check).  With the
  range term left by the satellites' shaped beams (receiver/cn0.py) L1 C/N0 rises about 16 dB from 5 deg
  to the zenith (a PolaRx5 with an ASH701945E_M choke ring: about 17 dB, physics-anchors.md).  Lower band:
  the chokes are tuned between L1 and L2, the L2 beam is slightly broader: 0.5 dB less at zenith, 1 dB more
  at 10 deg (Tranquilla 1994; stated approximation).  XPD (cross-polar discrimination, the LHCP rejection)
  from the axial ratio AR: XPD = 20 log10((AR + 1) / (AR - 1)) (AR linear; IEEE Std 145 / 149 definitions):
  about 25 dB at zenith (AR ~1 dB, the Dorne-Margolin element's), 15 dB at 30 deg, 7 dB at 10 deg (AR ~8 dB) and
  2 dB at the horizon: along the conducting choke-ring ground plane the tangential field vanishes, so the
  field that reaches the element at grazing arrival is the vertical (linear) component alone, AR -> infinity and
  XPD -> 0 dB (Rao, Kunysz, Fante, McDonald, "GPS/GNSS Antennas", Artech 2013, ch. 4; from memory, check).
  Published patterns of geodetic antennas (choke rings, NovAtel pinwheel, Trimble Zephyr) give 15-25 dB at
  zenith falling to a few dB near the horizon.  Until issue 27 the table held 10 dB at 10 deg and 7 dB at the
  horizon, more rejection than those patterns: low-elevation LHCP reflections (a wall facing the satellite,
  incidence below the Brewster angle, fresnel.py) were 3-5 dB too weak for a geodetic receiver to track.

These are representative tables, not one product's measured pattern: stated approximations.
"""
from __future__ import annotations

import numpy as np

#: L band split: carriers below this are the lower L band (L2/L5/E5/E6/B3/G2/G3)
LOWER_BAND_MAX_HZ = 1.4e9

#: generic patch antenna RHCP gain pattern: elevation [deg] -> gain [dBic] (every band)
PATCH_EL_DEG = np.array([-90.0, -10.0, 0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0])
PATCH_GAIN_DBIC = np.array([-25.0, -12.0, -8.0, -5.5, -4.0, -2.8, -1.8, -0.2, 1.8, 3.0, 3.7, 4.0])
_PATCH_XPD_EL = np.array([-90.0, -10.0, 0.0, 10.0, 30.0, 60.0, 90.0])
_PATCH_XPD_DB = np.array([0.0, 0.0, 1.0, 4.0, 9.0, 13.0, 15.0])

#: quadrifilar helix RHCP gain pattern (every band)
HELICAL_EL_DEG = np.array([-90.0, -10.0, 0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0])
HELICAL_GAIN_DBIC = np.array([-18.0, -8.0, -4.5, -3.2, -2.0, -1.2, -0.5, 0.5, 1.5, 2.1, 2.4, 2.5])
_HELICAL_XPD_EL = np.array([-90.0, -10.0, 0.0, 10.0, 30.0, 60.0, 90.0])
_HELICAL_XPD_DB = np.array([2.0, 2.0, 4.0, 8.0, 15.0, 18.0, 20.0])

#: choke ring RHCP gain pattern, L1 (upper L band) and the lower L band
CHOKE_EL_DEG = np.array([-90.0, -30.0, -10.0, 0.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0])
CHOKE_GAIN_DBIC = np.array([-30.0, -25.0, -18.5, -14.0, -11.0, -8.0, -5.8, -4.0, -1.0, 2.0, 3.8, 4.7, 5.0])
CHOKE_LOW_GAIN_DBIC = np.array([-30.0, -24.0, -17.5, -13.0, -10.0, -7.0, -5.0, -3.3, -0.5, 2.2, 3.6, 4.3, 4.5])
_CHOKE_XPD_EL = np.array([-90.0, -10.0, 0.0, 10.0, 30.0, 60.0, 90.0])
_CHOKE_XPD_DB = np.array([5.0, 3.0, 2.0, 7.0, 15.0, 22.0, 25.0])

#: class -> (elevation [deg], RHCP gain upper band [dBic], RHCP gain lower band [dBic], XPD elevation, XPD [dB])
_TABLES = {
    "patch": (PATCH_EL_DEG, PATCH_GAIN_DBIC, PATCH_GAIN_DBIC, _PATCH_XPD_EL, _PATCH_XPD_DB),
    "helical": (HELICAL_EL_DEG, HELICAL_GAIN_DBIC, HELICAL_GAIN_DBIC, _HELICAL_XPD_EL, _HELICAL_XPD_DB),
    "choke_ring": (CHOKE_EL_DEG, CHOKE_GAIN_DBIC, CHOKE_LOW_GAIN_DBIC, _CHOKE_XPD_EL, _CHOKE_XPD_DB),
}

PATTERNS = ("patch", "helical", "choke_ring")

#: RINEX header ANT # / TYPE of each pattern: IGS antenna name, A16 type + A4 radome (RINEX 3.04 table A2;
#: IGS rcvr_ant.tab naming); the simulator's own names, as these are representative, not one product's tables
RINEX_ANTENNA_TYPE = {"patch": "GNSS_SIM_PATCH  NONE", "helical": "GNSS_SIM_HELIX  NONE",
                      "choke_ring": "GNSS_SIM_CHOKE  NONE"}


def rhcp_gain_dbic(pattern: str, el_deg, frequency_hz=None):
    """RHCP gain [dBic] of antenna class ``pattern`` at elevations ``el_deg`` (array); ``frequency_hz``
    (scalar or broadcasting with ``el_deg``; None: L1) picks the upper or lower L-band table."""
    el = np.asarray(el_deg, dtype=np.float64)
    try:
        e, g_up, g_low, _, _ = _TABLES[pattern]
    except (KeyError, TypeError):
        raise ValueError(f"multipath: antenna pattern {pattern!r} is not one of {PATTERNS}") from None
    up = np.interp(el, e, g_up)
    if frequency_hz is None or g_low is g_up:
        return up
    return np.where(np.asarray(frequency_hz) < LOWER_BAND_MAX_HZ, np.interp(el, e, g_low), up)


def gain_dbic(pattern: str, el_deg, frequency_hz=None):
    """(RHCP gain, LHCP gain) [dBic] at arrival elevations ``el_deg`` (array)."""
    r = rhcp_gain_dbic(pattern, el_deg, frequency_hz)
    _, _, _, xe, xd = _TABLES[pattern]
    return r, r - np.interp(np.asarray(el_deg, dtype=np.float64), xe, xd)

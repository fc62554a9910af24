"""Carrier-to-noise density C/N0 [dB-Hz] from a link budget.

    C/N0 = P_rx + G_ant(el, band) - 10 log10(k T_sys) - L_impl - A_obstruction

- P_rx, received power of the tracked component at a 0 dBic antenna: each satellite is given the EIRP
  that delivers the ICD minimum received power (core/signals.py ``min_power_dbw``) plus the published
  margin by which satellites exceed it (signals.POWER_MARGIN_DB, Steigenberger et al., J Geod 92:609,
  2018) at the edge of coverage (the ICD's elevation, 5 or 10 deg), times the share of the component
  the RINEX code tracks (signals.COMPONENT_DB: data or pilot alone of a data + pilot signal, -3 dB for
  an equal split), plus ``LinkBudget.power_margin_db`` (a receiver-side offset, 0 by default).  The
  satellites' transmit antennas are shaped to compensate most of the longer path to the edge of the
  Earth: IS-GPS-200 (figure 3.3-1, user received minimum signal level against elevation) shows the
  received level only about 1 dB higher at zenith than at 5 deg where the free-space loss differs by
  2.1 dB (from memory, check), so the free-space term enters with the share SAT_PATTERN_PATH_SHARE:
  P_rx = P_min + margin + component + share * 20 log10(rho_edge / rho).  rho_edge follows from the
  satellite's own orbit radius (derived from range and elevation on a spherical Earth, R = 6371 km),
  so MEO, IGSO and GEO need no table.
- G_ant(el, band): the RHCP gain table of the receiver's antenna class (``LinkBudget.antenna``: patch,
  helical, choke_ring; core/multipath/antenna.py, the same tables the reflections use), the lower-L-band
  table for carriers below 1.4 GHz; a custom pattern (``antenna_el_deg``/``antenna_gain_dbic``)
  replaces it in every band.
- Noise density: k T_sys with T_sys = 290 K (-204.0 dBW/Hz), antenna sky
  temperature ~100 K plus a ~2 dB noise-figure LNA.
- L_impl = 1.5 dB: quantisation (2 bit: ~0.6 dB) and correlation losses
  (Kaplan & Hegarty 2nd ed. ch. 5 typical 1-2 dB).
- ``LinkBudget.cn0_table_dbhz`` (a profile's per-signal mean open-sky C/N0 against elevation, as that
  receiver reports it, e.g. fitted by ``gnss-sim calibrate``) replaces all of the above but A for the
  signals it holds (range and gain are in the table, not added again).
- A_obstruction: foliage/diffraction attenuation from the visibility step, subtracted in every case.
  Reference: a single tree fades L-band by 10-20 dB, median ~12 dB
  (Vogel & Goldhirsh, IEEE Trans. AP 34(12), 1986) -> FOLIAGE_MEDIAN_DB.

Resulting GPS L1 C/A figures with the choke ring (test_link_budget): about 52 dB-Hz at zenith, 39 at
10 deg, 36 at 5 deg (a geodetic receiver with a choke ring reports 50-52 at zenith); with the patch
50 at zenith, 41 at 10 deg, inside Kaplan's typical values and RTKLIB's simulator table (40-51).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnss_sim_ros2.core import constants as k
from gnss_sim_ros2.core import signals as _signals
from gnss_sim_ros2.core.memo import BoundedCache, read_only
from gnss_sim_ros2.core.multipath import antenna as _antenna

from . import signal_tables
from .signal_rows import array_key

#: share of the free-space loss change over the Earth disc left after the satellites' shaped beams (module doc)
SAT_PATTERN_PATH_SHARE = 0.4
#: median attenuation of a single tree at L-band/UHF [dB] (Vogel & Goldhirsh 1986, 869 MHz)
FOLIAGE_MEDIAN_DB = 12.0


@dataclass
class LinkBudget:
    """Receiver-side parameters of the C/N0 link budget."""

    noise_temperature_k: float = k.T0_NOISE_K
    implementation_loss_db: float = 1.5
    power_margin_db: float = 0.0        #: receiver-side offset on top of the signal table's published margins
    #: antenna class (multipath/antenna.py PATTERNS); None: the receiver's ``antenna`` (ReceiverConfig), else patch
    antenna: str | None = None
    #: a custom RHCP pattern: elevation [deg], gain [dBic] (both or neither; replaces the class's tables)
    antenna_el_deg: np.ndarray | None = None
    antenna_gain_dbic: np.ndarray | None = None
    #: per signal ("G1C"): {el_deg: [...], cn0_dbhz: [...]}, the receiver's mean open-sky C/N0 (module doc)
    cn0_table_dbhz: dict | None = None

    def __post_init__(self):
        if not self.noise_temperature_k > 0:
            raise ValueError(f"LinkBudget: parameter 'noise_temperature_k' = {self.noise_temperature_k} must be > 0")
        if self.antenna is not None and self.antenna not in _antenna.PATTERNS:
            raise ValueError(f"LinkBudget: parameter 'antenna' = {self.antenna!r} (one of {_antenna.PATTERNS})")
        if (self.antenna_el_deg is None) != (self.antenna_gain_dbic is None):
            raise ValueError("LinkBudget: 'antenna_el_deg' and 'antenna_gain_dbic' go together")
        if self.antenna_el_deg is not None:
            el = np.asarray(self.antenna_el_deg, dtype=np.float64)
            g = np.asarray(self.antenna_gain_dbic, dtype=np.float64)
            if el.shape != g.shape or el.ndim != 1 or el.size == 0 or np.any(np.diff(el) <= 0):
                raise ValueError("LinkBudget: 'antenna_el_deg' must increase strictly and match 'antenna_gain_dbic'")
            self.antenna_el_deg, self.antenna_gain_dbic = el, g
        self._cn0_table = signal_tables.validate(self.cn0_table_dbhz, "link_budget.cn0_table_dbhz", "cn0_dbhz")

    @property
    def noise_density_dbwhz(self) -> float:
        """10 log10(k T_sys) [dBW/Hz]."""
        return 10.0 * np.log10(k.K_BOLTZMANN_JPK * self.noise_temperature_k)

    def antenna_gain(self, el_deg, frequency_hz=None):
        """Antenna RHCP gain [dBic] at elevation ``el_deg`` (and carrier ``frequency_hz``, None: L1)."""
        if self.antenna_el_deg is not None:
            return np.interp(np.asarray(el_deg, dtype=np.float64), self.antenna_el_deg, self.antenna_gain_dbic)
        return _antenna.rhcp_gain_dbic(self.antenna or "patch", el_deg, frequency_hz)

    def table_cn0_dbhz(self, keys, el_deg) -> np.ndarray:
        """``cn0_table_dbhz`` at ``el_deg`` for signal keys ``keys`` ("G1C"); NaN where it has no row."""
        return signal_tables.lookup(self._cn0_table, keys, el_deg)


DEFAULT_BUDGET = LinkBudget()


def slant_range_m(sat_radius_m, el_deg, earth_radius_m=k.R_EARTH_MEAN_M):
    """Range [m] from a point on a sphere of radius R to a satellite at radius r seen at elevation el."""
    return _slant_range_m(np.asarray(sat_radius_m, dtype=np.float64), *_slant_terms(el_deg, earth_radius_m))


def _slant_terms(el_deg, earth_radius_m):
    """(-R sin el [m], (R cos el)^2 [m^2]): what slant_range_m's range takes from the elevation."""
    e = np.radians(el_deg)
    return -earth_radius_m * np.sin(e), (earth_radius_m * np.cos(e)) ** 2


def _slant_range_m(r, near_m, across2_m2):
    """slant_range_m from the orbit radius ``r`` and the elevation's _slant_terms."""
    return near_m + np.sqrt(r * r - across2_m2)


#: _slant_terms of the signals' edge-of-coverage elevations by their contents (the same signals epoch after epoch)
_EDGE_TERMS = BoundedCache(16)


def sat_radius_from_range_m(range_m, el_deg, earth_radius_m=k.R_EARTH_MEAN_M):
    """Satellite orbit radius [m] from range and elevation seen from the sphere's surface."""
    rho = np.asarray(range_m, dtype=np.float64)
    e = np.radians(el_deg)
    return np.sqrt(earth_radius_m**2 + rho * rho + 2.0 * earth_radius_m * rho * np.sin(e))


def _lookup(system, code, attr):
    if np.ndim(system) == 0 and np.ndim(code) == 0:
        return getattr(_signals.signal(system, code), attr)
    s, c = np.broadcast_arrays(np.asarray(system), np.asarray(code))
    return np.array([getattr(_signals.signal(a, b), attr) for a, b in zip(s.ravel(), c.ravel())]).reshape(s.shape)


def power_params(system, code):
    """(edge power [dBW], edge elevation [deg]) of signals ``(system, code)`` (arrays broadcast): the power of the
    tracked component at a 0 dBic antenna at the edge of coverage, ICD minimum + published margin + component
    share (module doc), for :func:`cn0_dbhz_from_params` when the same signals come back every epoch."""
    p_min, margin, comp = (_lookup(system, code, a) for a in ("min_power_dbw", "power_margin_db", "component_db"))
    return p_min + margin + comp, _lookup(system, code, "min_power_el_deg")


def received_power_dbw(system, code, range_m, el_deg, sat_radius_m=None, power_margin_db=0.0):
    """Received power of the tracked component at a 0 dBic antenna [dBW] (see module docstring)."""
    p_min, el_min = power_params(system, code)
    return _received_power_dbw(p_min, el_min, range_m, el_deg, sat_radius_m, power_margin_db)


def _received_power_dbw(p_min, el_min, range_m, el_deg, sat_radius_m, power_margin_db):
    rho = np.asarray(range_m, dtype=np.float64)
    if (rho <= 0).any():
        raise ValueError("receiver.cn0: parameter 'range_m' must be > 0")
    r_sat = sat_radius_from_range_m(rho, el_deg) if sat_radius_m is None else np.asarray(sat_radius_m)
    key = (np.shape(el_min), array_key(el_min))       # the shape too: array_key holds a scalar as one value
    terms = _EDGE_TERMS.get(key)
    if terms is None:
        terms = _EDGE_TERMS.put(key, read_only(_slant_terms(el_min, k.R_EARTH_MEAN_M)))
    rho_edge = _slant_range_m(r_sat, *terms)
    return p_min + power_margin_db + SAT_PATTERN_PATH_SHARE * 20.0 * np.log10(rho_edge / rho)


def cn0_dbhz(system, code, range_m, el_deg, attenuation_db=0.0, sat_radius_m=None, budget: LinkBudget = None):
    """C/N0 [dB-Hz] of signal ``(system, code)`` (scalars or arrays, broadcast over satellites).

    ``range_m``: geometric range; ``el_deg``: elevation at the antenna (for its
    gain); ``attenuation_db``: obstruction loss (foliage, diffraction) from the
    visibility step; ``sat_radius_m``: orbit radius if known (else derived).
    """
    p_edge, el_min = power_params(system, code)
    freq = _lookup(system, code, "f0_hz")
    keys = signal_tables.signal_keys(*np.broadcast_arrays(np.asarray(system), np.asarray(code)))
    return cn0_dbhz_from_params(p_edge, el_min, range_m, el_deg, attenuation_db, sat_radius_m, budget, freq, keys)


def cn0_dbhz_from_params(edge_power_dbw, min_power_el_deg, range_m, el_deg, attenuation_db=0.0, sat_radius_m=None,
                         budget: LinkBudget = None, frequency_hz=None, signal_keys=None):
    """:func:`cn0_dbhz` with the signals' table values given (from :func:`power_params`); ``frequency_hz``: carrier
    per row (antenna band; None: L1), ``signal_keys``: "G1C" per row (for ``cn0_table_dbhz``; None: no table)."""
    b = DEFAULT_BUDGET if budget is None else budget
    p = _received_power_dbw(edge_power_dbw, min_power_el_deg, range_m, el_deg, sat_radius_m, b.power_margin_db)
    c = p + b.antenna_gain(el_deg, frequency_hz) - b.noise_density_dbwhz - b.implementation_loss_db
    if b._cn0_table and signal_keys is not None:
        tab = b.table_cn0_dbhz(signal_keys, el_deg)
        c = np.where(np.isnan(tab), c, tab)
    return c - np.asarray(attenuation_db, dtype=np.float64)

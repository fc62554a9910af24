"""Carrier-to-noise density C/N0 [dB-Hz] from a link budget.

    C/N0 = P_rx + G_ant(el) - 10 log10(k T_sys) - L_impl - A_obstruction

- P_rx, received power at a 0 dBic antenna: each satellite is given the EIRP
  that delivers exactly the ICD minimum received power (core/signals.py,
  ``min_power_dbw``) at the edge of coverage (the ICD's elevation,
  5 or 10 deg), plus ``power_margin_db``; its satellite antenna pattern is
  taken as flat over the Earth disc, so only free-space loss changes:
  P_rx = P_min + margin + 20 log10(rho_edge / rho).  rho_edge follows from the
  satellite's own orbit radius (derived from range and elevation on a
  spherical Earth, R = 6371 km), so MEO, IGSO and GEO need no table.
- G_ant(el): a generic right-hand circularly polarised patch (the table
  PATCH_GAIN_DBIC of core/multipath/antenna.py), +4 dBic at
  zenith, -4 dBic at 10 deg, -5.5 dBic at 5 deg, -8 dBic at the horizon
  (an 8 dB roll-off from zenith to 10 deg; NovAtel documents >= +5 dBic at
  zenith for its elements; AML reports ~15 dB from 90 to 5 deg for high-end
  geodetic antennas, cheaper patches roll off less steeply at the top).
- Noise density: k T_sys with T_sys = 290 K (-204.0 dBW/Hz), antenna sky
  temperature ~100 K plus a ~2 dB noise-figure LNA.
- L_impl = 1.5 dB: quantisation (2 bit: ~0.6 dB) and correlation losses
  (Kaplan & Hegarty 2nd ed. ch. 5 typical 1-2 dB).
- A_obstruction: foliage/diffraction attenuation from the visibility step.
  Reference: a single tree fades L-band by 10-20 dB, median ~12 dB
  (Vogel & Goldhirsh, IEEE Trans. AP 34(12), 1986) -> FOLIAGE_MEDIAN_DB.

Resulting GPS L1 C/A figures (test_receiver_models): 49.9 dB-Hz at zenith,
40.2 at 10 deg, 38.5 at 5 deg, inside the 48-51 (zenith) and 38-42 (10 deg)
ranges of Kaplan's typical values and RTKLIB's simulator table (40-51).
Signals whose ICD minimum is low (BeiDou B1I/B3I -163 dBW: 45.3 dB-Hz at
zenith) come out below what receivers report, because satellites exceed the
minimum by a few dB; raise ``LinkBudget.power_margin_db`` to model that.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gnss_sim_ros2.core import constants as k
from gnss_sim_ros2.core import signals as _signals
from gnss_sim_ros2.core.multipath.antenna import PATCH_EL_DEG, PATCH_GAIN_DBIC

#: median attenuation of a single tree at L-band/UHF [dB] (Vogel & Goldhirsh 1986, 869 MHz)
FOLIAGE_MEDIAN_DB = 12.0


@dataclass
class LinkBudget:
    """Receiver-side parameters of the C/N0 link budget."""

    noise_temperature_k: float = k.T0_NOISE_K
    implementation_loss_db: float = 1.5
    power_margin_db: float = 0.0        #: satellites' power above the ICD minimum
    antenna_el_deg: np.ndarray = field(default_factory=lambda: PATCH_EL_DEG.copy())
    antenna_gain_dbic: np.ndarray = field(default_factory=lambda: PATCH_GAIN_DBIC.copy())

    def __post_init__(self):
        if self.noise_temperature_k <= 0:
            raise ValueError(f"LinkBudget: parameter 'noise_temperature_k' = {self.noise_temperature_k} must be > 0")
        el = np.asarray(self.antenna_el_deg, dtype=np.float64)
        g = np.asarray(self.antenna_gain_dbic, dtype=np.float64)
        if el.shape != g.shape or el.ndim != 1 or np.any(np.diff(el) <= 0):
            raise ValueError("LinkBudget: 'antenna_el_deg' must increase strictly and match 'antenna_gain_dbic'")

    @property
    def noise_density_dbwhz(self) -> float:
        """10 log10(k T_sys) [dBW/Hz]."""
        return 10.0 * np.log10(k.K_BOLTZMANN_JPK * self.noise_temperature_k)

    def antenna_gain(self, el_deg):
        """Antenna gain [dBic] at elevation ``el_deg`` (linear interpolation of the pattern)."""
        return np.interp(np.asarray(el_deg, dtype=np.float64), self.antenna_el_deg, self.antenna_gain_dbic)


DEFAULT_BUDGET = LinkBudget()


def slant_range_m(sat_radius_m, el_deg, earth_radius_m=k.R_EARTH_MEAN_M):
    """Range [m] from a point on a sphere of radius R to a satellite at radius r seen at elevation el."""
    e = np.radians(el_deg)
    r = np.asarray(sat_radius_m, dtype=np.float64)
    return -earth_radius_m * np.sin(e) + np.sqrt(r * r - (earth_radius_m * np.cos(e)) ** 2)


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
    """(min_power_dbw, min_power_el_deg) of signals ``(system, code)`` from core/signals.py (arrays broadcast),
    for :func:`cn0_dbhz_from_params` when the same signals come back every epoch."""
    return _lookup(system, code, "min_power_dbw"), _lookup(system, code, "min_power_el_deg")


def received_power_dbw(system, code, range_m, el_deg, sat_radius_m=None, power_margin_db=0.0):
    """Received power at a 0 dBic antenna [dBW] (see module docstring)."""
    p_min, el_min = power_params(system, code)
    return _received_power_dbw(p_min, el_min, range_m, el_deg, sat_radius_m, power_margin_db)


def _received_power_dbw(p_min, el_min, range_m, el_deg, sat_radius_m, power_margin_db):
    rho = np.asarray(range_m, dtype=np.float64)
    if np.any(rho <= 0):
        raise ValueError("receiver.cn0: parameter 'range_m' must be > 0")
    r_sat = sat_radius_from_range_m(rho, el_deg) if sat_radius_m is None else np.asarray(sat_radius_m)
    rho_edge = slant_range_m(r_sat, el_min)
    return p_min + power_margin_db + 20.0 * np.log10(rho_edge / rho)


def cn0_dbhz(system, code, range_m, el_deg, attenuation_db=0.0, sat_radius_m=None, budget: LinkBudget = None):
    """C/N0 [dB-Hz] of signal ``(system, code)`` (scalars or arrays, broadcast over satellites).

    ``range_m``: geometric range; ``el_deg``: elevation at the antenna (for its
    gain); ``attenuation_db``: obstruction loss (foliage, diffraction) from the
    visibility step; ``sat_radius_m``: orbit radius if known (else derived).
    """
    p_min, el_min = power_params(system, code)
    return cn0_dbhz_from_params(p_min, el_min, range_m, el_deg, attenuation_db, sat_radius_m, budget)


def cn0_dbhz_from_params(min_power_dbw, min_power_el_deg, range_m, el_deg, attenuation_db=0.0, sat_radius_m=None,
                         budget: LinkBudget = None):
    """:func:`cn0_dbhz` with the signals' table values given (from :func:`power_params`)."""
    b = DEFAULT_BUDGET if budget is None else budget
    p = _received_power_dbw(min_power_dbw, min_power_el_deg, range_m, el_deg, sat_radius_m, b.power_margin_db)
    return (p + b.antenna_gain(el_deg) - b.noise_density_dbwhz - b.implementation_loss_db
            - np.asarray(attenuation_db, dtype=np.float64))

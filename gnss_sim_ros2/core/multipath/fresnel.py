"""Electrical properties of building materials at L-band and Fresnel reflection coefficients.

Materials: ITU-R P.2040-3 (2023) table 3, valid 1-100 GHz for buildings (1-10 GHz for the grounds):

    eta' = a f^b,   sigma = c f^d [S/m],  f in GHz,
    complex relative permittivity  eta = eta' - j 17.98 sigma / f          (P.2040 eq. (9b))

Fresnel coefficients of a smooth half-space (P.2040 section 2.2.1, eqs. (31)-(32)), theta the angle of
incidence from the facet's normal:

    R_TE = (cos(theta) - sqrt(eta - sin^2(theta))) / (cos(theta) + sqrt(eta - sin^2(theta)))
    R_TM = (eta cos(theta) - sqrt(eta - sin^2(theta))) / (eta cos(theta) + sqrt(eta - sin^2(theta)))

Circular polarisation (e.g. Hannah, "Modelling and simulation of GPS multipath propagation", QUT thesis,
2001, eq. 3.22): an incident RHCP wave leaves a smooth surface as

    RHCP (co-polar)    R_co    = (R_TE + R_TM) / 2
    LHCP (cross-polar) R_cross = (R_TE - R_TM) / 2

so at normal incidence everything turns into LHCP (R_co = 0), at grazing incidence the wave stays RHCP
(R_co -> -1), and the two are equal at the Brewster angle (R_TM = 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..constants import F_L1_HZ


@dataclass(frozen=True)
class Material:
    """ITU-R P.2040-3 table 3 row: eta' = a f^b, sigma = c f^d (f in GHz)."""

    name: str
    a: float
    b: float
    c: float
    d: float
    f_range_ghz: tuple[float, float]

    def permittivity(self, f_hz: float = F_L1_HZ) -> complex:
        """Complex relative permittivity eta' - j eta'' at ``f_hz`` (P.2040 eq. (9b))."""
        f = f_hz / 1e9
        re = self.a * f ** self.b
        sigma = self.conductivity_spm(f_hz)
        return complex(re, -17.98 * sigma / f)

    def conductivity_spm(self, f_hz: float = F_L1_HZ) -> float:
        return self.c * (f_hz / 1e9) ** self.d


#: ITU-R P.2040-3 table 3 (materials asked for by the scene model; "ground" = medium dry ground)
MATERIALS: dict[str, Material] = {m.name: m for m in (
    Material("concrete", 5.24, 0.0, 0.0462, 0.7822, (1.0, 100.0)),
    Material("brick", 3.91, 0.0, 0.0238, 0.16, (1.0, 40.0)),
    Material("plasterboard", 2.73, 0.0, 0.0085, 0.9395, (1.0, 100.0)),
    Material("wood", 1.99, 0.0, 0.0047, 1.0718, (0.001, 100.0)),
    Material("glass", 6.31, 0.0, 0.0036, 1.3394, (0.1, 100.0)),
    Material("metal", 1.0, 0.0, 1e7, 0.0, (1.0, 100.0)),
    Material("very_dry_ground", 3.0, 0.0, 0.00015, 2.52, (1.0, 10.0)),
    Material("ground", 15.0, -0.1, 0.035, 1.63, (1.0, 10.0)),
    Material("wet_ground", 30.0, -0.4, 0.15, 1.30, (1.0, 10.0)),
)}

#: substrings of a scene material class name -> P.2040 material (first match wins; else DEFAULT_MATERIAL)
NAME_HINTS = (("glass", "glass"), ("window", "glass"), ("metal", "metal"), ("steel", "metal"),
              ("brick", "brick"), ("wood", "wood"), ("timber", "wood"), ("plaster", "plasterboard"),
              ("ground", "ground"), ("terrain", "ground"), ("grass", "ground"), ("concrete", "concrete"))
DEFAULT_MATERIAL = "concrete"


def material(name: str) -> Material:
    """The table row ``name``; ValueError naming the known ones."""
    try:
        return MATERIALS[name]
    except KeyError:
        raise ValueError(f"multipath: material {name!r} is not in the ITU-R P.2040 table "
                         f"({', '.join(MATERIALS)})") from None


def material_for_class(class_name: str) -> str:
    """P.2040 material of a scene material class name (NAME_HINTS; DEFAULT_MATERIAL otherwise)."""
    low = class_name.lower()
    for hint, mat in NAME_HINTS:
        if hint in low:
            return mat
    return DEFAULT_MATERIAL


def fresnel_te_tm(eta, incidence_deg):
    """(R_TE, R_TM) complex, broadcast over ``eta`` (complex permittivity) and the incidence angle [deg]."""
    th = np.radians(np.asarray(incidence_deg, dtype=np.float64))
    eta = np.asarray(eta, dtype=np.complex128)
    c = np.cos(th)
    root = np.sqrt(eta - np.sin(th) ** 2)
    r_te = (c - root) / (c + root)
    r_tm = (eta * c - root) / (eta * c + root)
    return r_te, r_tm


def circular_coefficients(eta, incidence_deg):
    """(R_co RHCP->RHCP, R_cross RHCP->LHCP) complex (module docstring)."""
    r_te, r_tm = fresnel_te_tm(eta, incidence_deg)
    return 0.5 * (r_te + r_tm), 0.5 * (r_te - r_tm)


def brewster_deg(eta_real: float) -> float:
    """Brewster angle from the normal of a lossless dielectric [deg]: tan(theta_B) = sqrt(eta)."""
    return float(np.degrees(np.arctan(np.sqrt(eta_real))))

"""Which ionosphere is true (NeQuick-G or Klobuchar, ReceiverConfig.ionosphere) and the Klobuchar
coefficients a receiver corrects with, from a navigation header's coefficients."""
from __future__ import annotations

import warnings

import numpy as np

from ..nequick import available as nequick_available

#: Klobuchar coefficients used when a navigation file carries none: the GPS broadcast of
#: 2022-01-01 (OPEC00NOR_S_20220010000_01D_GN.rnx header, IONOSPHERIC CORR GPSA/GPSB)
KLOBUCHAR_FALLBACK_ALPHA = np.array([1.2107e-08, -7.4506e-09, -5.9605e-08, 1.1921e-07])
KLOBUCHAR_FALLBACK_BETA = np.array([1.1674e05, -2.4576e05, -6.5536e04, 1.1141e06])


def truth_model(setting: str, iono: dict | None) -> str:
    """The true ionosphere's model for ``setting`` (ReceiverConfig.ionosphere) and the header's coefficients.

    "auto": NeQuick-G where the Galileo coefficients are given and the library is installed, Klobuchar
    otherwise (a warning names the missing library).  "nequick" without coefficients: Klobuchar while none
    are known (``iono`` None: a node before its first message), an error when a header lacks them.
    """
    has_gal = bool(iono) and iono.get("GAL") is not None and len(iono["GAL"]) >= 3 and any(iono["GAL"][:3])
    if setting == "auto":
        if has_gal and not nequick_available():
            warnings.warn("receiver: the 'nequick' package is not installed; the true ionosphere falls back to "
                          "Klobuchar (pip install --no-deps nequick, see requirements/no-deps.txt)", stacklevel=3)
            return "klobuchar"
        return "nequick" if has_gal else "klobuchar"
    if setting == "nequick" and not has_gal:
        if iono is None:
            return "klobuchar"
        raise ValueError("receiver: parameter 'ionosphere' = 'nequick' needs the Galileo coefficients (GAL "
                         "IONOSPHERIC CORR) in the navigation header; none were given")
    return setting


def klobuchar_coeffs(iono: dict | None):
    """GPS alpha/beta from a navigation header dict ({"GPSA": [...], "GPSB": [...]}); typical values otherwise."""
    if iono:
        a = iono.get("GPSA") or iono.get("alpha")
        b = iono.get("GPSB") or iono.get("beta")
        if a is not None and b is not None and len(a) == 4 and len(b) == 4:
            return np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return KLOBUCHAR_FALLBACK_ALPHA, KLOBUCHAR_FALLBACK_BETA

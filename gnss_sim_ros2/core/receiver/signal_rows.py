"""What the receiver derives once per set of satellites (``SignalRows``: one row per signal of the receiver's
profile, Receiver._rows_of) and the cache key of an array's contents."""
from __future__ import annotations

import numpy as np


class SignalRows:
    """What the receiver derives once per set of satellites (Receiver._rows_of)."""

    signal_rows: tuple          # (sat_i, codes, freq, chip, systems)
    lam: np.ndarray
    gd_factor: np.ndarray
    p_min: np.ndarray
    el_min: np.ndarray
    omega: np.ndarray
    sv_j: np.ndarray
    code_bias_m: np.ndarray
    sisre_sigma: np.ndarray
    sisre_terms: tuple | None
    mp_idx: np.ndarray
    sig_key: np.ndarray         # "G1C" per row (the profile's per-signal tables)
    dll_factor: np.ndarray      # code-noise factor of the modulation (signals.Signal.dll_noise_factor)

    @staticmethod
    def stack(parts: list, sat_offset) -> SignalRows:
        """The rows of several epochs one after another; ``sat_offset``: the first satellite row of each
        epoch in the stacked states (signal_rows[0] then indexes those)."""
        out = SignalRows()
        cols = list(zip(*(p.signal_rows for p in parts)))
        out.signal_rows = (np.concatenate([c + o for c, o in zip(cols[0], sat_offset)]),
                           *(np.concatenate(c) for c in cols[1:]))
        for name in ("lam", "gd_factor", "p_min", "el_min", "omega", "sv_j", "code_bias_m", "sisre_sigma",
                     "mp_idx", "sig_key", "dll_factor"):
            setattr(out, name, np.concatenate([getattr(p, name) for p in parts]))
        terms = [p.sisre_terms for p in parts if p.sisre_terms is not None]
        out.sisre_terms = (np.concatenate([x[0] for x in terms]), np.concatenate([x[1] for x in terms])) \
            if terms else None
        return out


def array_key(a) -> tuple:
    """Hashable key of an array's contents (dtype, shape, bytes)."""
    a = np.ascontiguousarray(a)
    return (a.dtype.str, a.shape, a.tobytes())

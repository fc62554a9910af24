"""The two inputs of a comparison: a RINEX observation file or a bag, as one ObsTable."""
from __future__ import annotations

from pathlib import Path

from ..bag_obs import is_bag, load_bag
from ..rinex.obs_read import load_rinex
from ..rinex.obs_table import ObsTable


def load_observations(path, tlim=None) -> ObsTable:
    """Observations of a RINEX 3 observation file or of a bag (``/gnss/observations``).

    ``tlim``: optional (first, last) numpy datetime64 (GPS time) to read only that span.
    """
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: no such file or bag folder")
    return load_bag(p, tlim) if is_bag(p) else load_rinex(p, tlim)

"""RINEX files, one module per kind (georinex's layout: one reader per kind behind one entry point).

- nav/: RINEX 2, 3 and 4 navigation files -> per-system record tables (one text splitter per version behind
  ``nav.read_nav_files``; numbers read by georinex);
- nav_write.py: RINEX 3.04 mixed navigation writer;
- obs_table.py: observations of one receiver as epochs x satellites per RINEX code (ObsTable);
- obs_read.py: RINEX observation files -> ObsTable;
- obs_write.py: the streaming RINEX 3.04 observation writer (crash safe);
- header.py: header fields the readers need beyond georinex's.
"""
from __future__ import annotations

import importlib

#: name -> its module: imported when first asked for (PEP 562), so that importing one kind (the simulation's
#: navigation reader and observation writer) does not import the others (the observation reader)
_HOMES = {"read_nav_file": "nav", "read_nav_files": "nav", "write_rinex3_nav": "nav_write", "load_rinex": "obs_read",
          "ObsTable": "obs_table", "RinexObsHeader": "obs_write", "RinexObsWriter": "obs_write"}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)

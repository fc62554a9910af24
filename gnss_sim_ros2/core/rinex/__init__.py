"""RINEX files, one module per kind (georinex's layout: one reader per kind behind one entry point).

- nav/: RINEX 2, 3 and 4 navigation files -> per-system record tables (one text splitter per version behind
  ``nav.read_nav_files``; numbers read by georinex);
- nav_write.py: RINEX 3.04 mixed navigation writer;
- obs_table.py: observations of one receiver as epochs x satellites per RINEX code (ObsTable);
- obs_read.py: RINEX observation files -> ObsTable;
- obs_write.py: the streaming RINEX 3.04 observation writer (crash safe);
- header.py: header fields the readers need beyond georinex's.
"""
from .nav import read_nav_file, read_nav_files
from .nav_write import write_rinex3_nav
from .obs_read import load_rinex
from .obs_table import ObsTable
from .obs_write import RinexObsHeader, RinexObsWriter

__all__ = ["ObsTable", "RinexObsHeader", "RinexObsWriter", "load_rinex", "read_nav_file", "read_nav_files",
           "write_rinex3_nav"]

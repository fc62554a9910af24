"""RINEX 2, 3 and 4 broadcast navigation files -> per-system record tables, as georinex lays its readers out:
one text splitter per version behind one entry point.

- read.py: the entry point (``read_nav_files``, ``read_nav_file``, ``parse_nav_text``: checks the header,
  dispatches on the version, filters, hands the records to georinex) and ``nav_from_records`` (the same
  NavData from records without text);
- containers.py: ``NavData``, ``SystemTable``, the record dtypes, ``NavDataWarning``;
- record_text.py: what every version's text shares (number fields, header, RINEX 3/4 epoch line, message type);
- v2.py, v3.py, v4.py: the text of one version -> records (sys, sv, epoch, message type, body lines, line);
- georinex_adapter.py: records -> georinex -> tables, and tables -> georinex-named dicts;
- tables.py: the record tables (times as GPS time, units, impossible orbits dropped, duplicates removed).
"""
from .containers import (
    GLONASS_DTYPE,
    KEPLER_DTYPE,
    KEPLER_SYSTEMS,
    SUPPORTED_SYSTEMS,
    NavData,
    NavDataWarning,
    SystemTable,
    epoch_key,
    toc_time,
    toe_time,
)
from .georinex_adapter import GEORINEX_FIELDS, header_dict, records_as_dicts
from .read import nav_from_records, parse_nav_text, read_nav_file, read_nav_files

__all__ = ["GEORINEX_FIELDS", "GLONASS_DTYPE", "KEPLER_DTYPE", "KEPLER_SYSTEMS", "SUPPORTED_SYSTEMS", "NavData",
           "NavDataWarning", "SystemTable", "epoch_key", "header_dict", "nav_from_records", "parse_nav_text",
           "read_nav_file", "read_nav_files", "records_as_dicts", "toc_time", "toe_time"]

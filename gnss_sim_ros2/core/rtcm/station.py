"""RTCM3 station messages (RTCM 10403.3, 3.5.3 and 3.5.10): 1005/1006 antenna reference point,
1033 receiver and antenna descriptors, 1230 GLONASS code-phase biases."""
from __future__ import annotations

from .frame import BitWriter


def _station_head(w: BitWriter, number: int, station_id: int) -> None:
    w.u(12, number, "DF002").u(12, station_id, "DF003")


def encode_1005(station_id: int, arp_ecef_m, systems: str = "GRE", antenna_height_m: float | None = None) -> bytes:
    """1005 (or 1006 with ``antenna_height_m``): antenna reference point ECEF [m], 0.1 mm
    (DF025-DF027 int38), ITRF year 0, physical reference station, GPS/GLONASS/Galileo flags."""
    x, y, z = (float(v) for v in arp_ecef_m)
    w = BitWriter()
    _station_head(w, 1006 if antenna_height_m is not None else 1005, station_id)
    w.u(6, 0, "DF021")
    w.u(1, "G" in systems, "DF022").u(1, "R" in systems, "DF023").u(1, "E" in systems, "DF024")
    w.u(1, 0, "DF141")
    w.s(38, round(x / 1e-4), "DF025")
    w.u(1, 0, "DF142").u(1, 0, "DF001")
    w.s(38, round(y / 1e-4), "DF026")
    w.u(2, 0, "DF364")
    w.s(38, round(z / 1e-4), "DF027")
    if antenna_height_m is not None:
        w.u(16, round(float(antenna_height_m) / 1e-4), "DF028")
    return w.payload()


def _text(w: BitWriter, text: str, what: str) -> None:
    data = text.encode("ascii", "replace")[:31]
    w.u(8, len(data), what)
    for b in data:
        w.u(8, b, what)


def encode_1033(station_id: int, antenna_type: str, antenna_serial: str, receiver_type: str,
                receiver_version: str, receiver_serial: str) -> bytes:
    """1033: antenna descriptor (DF030, setup ID DF031 = 0, serial DF033), receiver type,
    firmware version and serial (DF228-DF233); each string at most 31 characters."""
    w = BitWriter()
    _station_head(w, 1033, station_id)
    _text(w, antenna_type, "DF029/DF030")
    w.u(8, 0, "DF031")
    _text(w, antenna_serial, "DF032/DF033")
    _text(w, receiver_type, "DF227/DF228")
    _text(w, receiver_version, "DF229/DF230")
    _text(w, receiver_serial, "DF231/DF232")
    return w.payload()


#: 1230 bias order (DF423-DF426): L1 C/A, L1 P, L2 C/A, L2 P (RINEX C1C, C1P, C2C, C2P)
GLONASS_BIAS_CODES = ("C1C", "C1P", "C2C", "C2P")


def encode_1230(station_id: int, biases_m: dict, aligned: bool = False) -> bytes:
    """1230: GLONASS code-phase biases [m] (RINEX GLONASS COD/PHS/BIS values, 0.02 m, int16)
    with the alignment indicator DF421; only the codes given are sent (signal mask DF422)."""
    w = BitWriter()
    _station_head(w, 1230, station_id)
    w.u(1, 1 if aligned else 0, "DF421").u(3, 0, "DF001")
    present = [c in biases_m for c in GLONASS_BIAS_CODES]
    w.bits(present)
    for c, p in zip(GLONASS_BIAS_CODES, present):
        if p:
            w.s(16, round(float(biases_m[c]) / 0.02), f"1230 {c}")
    return w.payload()

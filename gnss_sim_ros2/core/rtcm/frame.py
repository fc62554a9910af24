"""Bit packing and RTCM3 transport framing (RTCM 10403.3, section 4: preamble 0xD3, 6 reserved
bits, 10-bit length, payload, CRC-24Q over everything before it).

The CRC is pyrtcm's (``calc_crc24q``, the Qualcomm CRC-24Q of RTCM 10403.3 4.2).
"""
from __future__ import annotations

from pyrtcm.rtcmhelpers import calc_crc24q

PREAMBLE = 0xD3
#: largest payload of one frame [bytes] (10-bit length field)
MAX_PAYLOAD_BYTES = 1023


class RtcmFieldError(ValueError):
    """A value does not fit the bits of its RTCM data field."""


class BitWriter:
    """Big-endian bit accumulator: fields are appended most significant bit first."""

    def __init__(self):
        self._acc = 0
        self.nbits = 0

    def u(self, nbits: int, value: int, name: str = "") -> BitWriter:
        """Unsigned integer field (RTCM uint / bit(n))."""
        v = int(value)
        if v < 0 or v >= 1 << nbits:
            raise RtcmFieldError(f"RTCM field {name or '?'}: {v} does not fit uint{nbits}")
        self._acc = (self._acc << nbits) | v
        self.nbits += nbits
        return self

    def s(self, nbits: int, value: int, name: str = "") -> BitWriter:
        """Two's complement integer field (RTCM int(n))."""
        v = int(value)
        if v < -(1 << (nbits - 1)) or v >= 1 << (nbits - 1):
            raise RtcmFieldError(f"RTCM field {name or '?'}: {v} does not fit int{nbits}")
        return self.u(nbits, v & ((1 << nbits) - 1), name)

    def sm(self, nbits: int, value: int, name: str = "") -> BitWriter:
        """Sign-magnitude integer field (RTCM intS(n), the GLONASS fields): sign bit then magnitude."""
        v = int(value)
        if abs(v) >= 1 << (nbits - 1):
            raise RtcmFieldError(f"RTCM field {name or '?'}: {v} does not fit intS{nbits}")
        return self.u(nbits, ((1 << (nbits - 1)) if v < 0 else 0) | abs(v), name)

    def bits(self, flags) -> BitWriter:
        """One bit per item of ``flags`` (masks)."""
        for f in flags:
            self.u(1, 1 if f else 0)
        return self

    def payload(self) -> bytes:
        """The bits, zero-padded to whole bytes."""
        pad = (-self.nbits) % 8
        n = (self.nbits + pad) // 8
        return (self._acc << pad).to_bytes(n, "big") if n else b""


def frame(payload: bytes) -> bytes:
    """One RTCM3 frame around ``payload``."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise RtcmFieldError(f"RTCM message of {len(payload)} bytes: a frame holds at most {MAX_PAYLOAD_BYTES}")
    head = bytes((PREAMBLE, (len(payload) >> 8) & 0x03, len(payload) & 0xFF))
    crc = calc_crc24q(head + payload)
    return head + payload + crc.to_bytes(3, "big")


def split_frames(data: bytes) -> tuple[list[bytes], bytes]:
    """Complete frames at the start of ``data`` (CRC checked) and the bytes left over.

    Bytes before a preamble, and frames whose CRC fails, are skipped (as a
    stream reader resynchronises).  Used by the rtk node to forward whole
    messages and by the tests.
    """
    out, i, n = [], 0, len(data)
    while i + 6 <= n:
        if data[i] != PREAMBLE:
            i += 1
            continue
        length = ((data[i + 1] & 0x03) << 8) | data[i + 2]
        end = i + 3 + length + 3
        if end > n:
            break
        if calc_crc24q(data[i:end - 3]) == int.from_bytes(data[end - 3:end], "big"):
            out.append(data[i:end])
            i = end
        else:
            i += 1
    return out, data[i:]


def message_number(frame_bytes: bytes) -> int:
    """DF002 of a framed message."""
    return (frame_bytes[3] << 4) | (frame_bytes[4] >> 4)


def is_msm(frame_bytes: bytes) -> bool:
    """A Multiple Signal Message (1071-1137, RTCM 10403.3 table 3.5-78)."""
    n = message_number(frame_bytes)
    return 1071 <= n <= 1137 and n % 10 != 0 and n % 10 <= 7


def msm_more_follow(frame_bytes: bytes) -> bool:
    """DF393 of an MSM frame: more MSMs of the same epoch follow (payload bit 54)."""
    return bool((int.from_bytes(frame_bytes[3:11], "big") >> (64 - 55)) & 1)


def epochs_of(data: bytes) -> list[bytes]:
    """An RTCM3 stream cut after each epoch's last MSM (multiple message bit 0): the bytes of each epoch,
    with the station and ephemeris messages that came before its observations."""
    frames, _ = split_frames(data)
    out, cur = [], []
    for f in frames:
        cur.append(f)
        if is_msm(f) and not msm_more_follow(f):
            out.append(b"".join(cur))
            cur = []
    if cur:
        out.append(b"".join(cur))
    return out


#: MSM message number tens -> system (RTCM 10403.3 table 3.5-78; msm.MSM_BASE)
_MSM_SYSTEM = {107: "G", 108: "R", 109: "E", 111: "J", 112: "C", 113: "I"}
_WEEK_MS = 604_800_000


def msm_epoch_gps_ms(frame_bytes: bytes) -> int | None:
    """GPS time of week [ms] of an MSM frame's epoch (DF004/DF248/DF427/DF428, payload bits 24-53), or None
    for a GLONASS MSM (its epoch is a GLONASS time of day) or another message.  BeiDou time is GPS - 14 s
    (BDS-SIS-ICD 3.3): its epoch is moved back onto GPS time."""
    if not is_msm(frame_bytes):
        return None
    system = _MSM_SYSTEM.get(message_number(frame_bytes) // 10)
    if system in (None, "R"):
        return None
    ms = (int.from_bytes(frame_bytes[3:10], "big") >> (56 - 54)) & ((1 << 30) - 1)
    return (ms + 14_000) % _WEEK_MS if system == "C" else ms


def epoch_gps_ms(data: bytes) -> int | None:
    """The GPS time of week [ms] of the first non-GLONASS MSM in ``data`` (one epoch's messages), or None."""
    for f in split_frames(data)[0]:
        ms = msm_epoch_gps_ms(f)
        if ms is not None:
            return ms
    return None

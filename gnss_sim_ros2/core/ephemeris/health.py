"""What a broadcast record's health field says, per system: is the record usable, and for which signals.

Every system but QZSS: health 0 = usable, anything else = not (GPS IS-GPS-200N 20.3.3.3.1.4; Galileo OS SIS ICD
5.1.9.3, RINEX 3.05 A8; BeiDou SatH1, BDS-SIS-ICD-B1I 5.2.4.6; GLONASS Bn; NavIC).

QZSS: the 6-bit SV health of the L1C/A navigation message holds one bit per signal (IS-QZSS-PNT-005 5.4.1,
"SV Health"; RINEX 3.05 A9 stores the 6 bits as they are), MSB first:

    bit 5 (0x20): L1 health (L1C/A and L1C together)     bit 2 (0x04): L5
    bit 4 (0x10): L1C/A                                  bit 1 (0x02): L1C
    bit 3 (0x08): L2C                                    bit 0 (0x01): L1C/B (LEX/L6 in IS-QZSS 1.x)

A set bit flags that one signal; the others stay usable.  Every QZS broadcasts health 1 since the L1C/B bit was
introduced (the satellites do not transmit L1C/B), and real receivers track them (NovAtel OEM729, Septentrio
mosaic-X5: s-taka.org/en/qzss-health-info-update-for-7-sats); RTKLIB masks the bit too (satexclude:
``svh &= 0xFE`` for QZSS, its comment's "LEX health" being the IS-QZSS 1.x meaning of the LSB).  So this module keeps
a QZSS record while any of L1C/A, L2C, L5 and L1C is healthy, and ``signal_usable`` drops only the flagged
signals.  (Bit layout as the georust/rinex crate documents it from IS-QZSS-PNT 5.4.1; written without re-reading
the ICD here, check the bit order against the document.)
L6 has no bit in this field: it is taken as usable.
"""
from __future__ import annotations

import numpy as np

#: QZSS LNAV health bits (IS-QZSS-PNT-005 5.4.1)
QZSS_L1, QZSS_L1CA, QZSS_L2C, QZSS_L5, QZSS_L1C, QZSS_L1CB = 0x20, 0x10, 0x08, 0x04, 0x02, 0x01
#: the bits that flag a QZSS signal, by RINEX band + attribute's first character ("1C" L1C/A, "1L" L1C, ...)
_QZSS_BITS = {"1C": QZSS_L1 | QZSS_L1CA, "1S": QZSS_L1 | QZSS_L1C, "1L": QZSS_L1 | QZSS_L1C,
              "1X": QZSS_L1 | QZSS_L1C, "1Z": QZSS_L1 | QZSS_L1CB, "1E": QZSS_L1 | QZSS_L1CB,
              "2": QZSS_L2C, "5": QZSS_L5, "6": 0}
#: every ranging signal a QZSS record serves (L1C/A, L2C, L5, L1C) flagged: the record is of no use
_QZSS_ALL = QZSS_L1CA | QZSS_L2C | QZSS_L5 | QZSS_L1C


def record_usable(systems, health) -> np.ndarray:
    """Per record (arrays of system letters and health fields): whether a receiver uses it."""
    systems = np.asarray(systems)
    health = np.asarray(health, dtype=np.int64)
    qzss = systems == "J"
    l1_all = (health & QZSS_L1) != 0
    flagged = (health & _QZSS_ALL) | np.where(l1_all, QZSS_L1CA | QZSS_L1C, 0)
    return np.where(qzss, (flagged & _QZSS_ALL) != _QZSS_ALL, health == 0)


def signal_usable(system: str, health: int, code: str) -> bool:
    """Whether signal ``code`` ("1C", "2L", "5Q", ...) of a satellite whose record has ``health`` is usable:
    health 0 for every system but QZSS; for QZSS the signal's own bits clear."""
    health = int(health)
    if health == 0:
        return True
    if system != "J":
        return False
    bits = _QZSS_BITS.get(code, _QZSS_BITS.get(code[0], 0))
    return (health & bits) == 0

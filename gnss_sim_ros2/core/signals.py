"""Table of GNSS signals: RINEX 3 observation code, carrier, chip rate, minimum received power.

Keys are ``(system, code)`` with the RINEX system letter (G R E C J I) and the
two-character band+attribute of RINEX 3.04 (section 5.1, tables 4-10), e.g.
``("G", "1C")`` for GPS L1 C/A.  Codes sharing a band and chipping share the
same entry (``"5I"``, ``"5Q"``, ``"5X"`` are data, pilot and combined tracking
of L5).

Minimum received power: the ICD figure for the signal (data + pilot together
where the signal has two components, since receivers combine them), at the
output of a 0 dBic RHCP antenna (= the "3 dBi linearly polarised" antenna of
the GPS/GLONASS ICDs), for a satellite at ``min_power_el_deg`` or higher.
Sources per row; where the ICD gives several values per satellite type the
MEO / current-block value is used.  receiver/cn0.py anchors its link budget on
these numbers.  The GPS, Galileo E1/E5 and GLONASS figures are the well-known
ICD values; those of BeiDou B1C/B2a/B2b, Galileo E6, QZSS L6 and NavIC were
written from the cited ICDs without re-reading them here (no access while
writing): check them against the documents before relying on them.
Satellites usually deliver a few dB more than the minimum (receiver/cn0.py
``power_margin_db``).

Chip rate: of the ranging code that determines the code tracking noise (BPSK
formula in receiver/noise.py; BOC signals are treated as BPSK of the same chip
rate, a conservative choice).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnss_sim_ros2.core import constants as k

SYSTEMS = ("G", "R", "E", "C", "J", "I")


@dataclass(frozen=True)
class Signal:
    system: str            #: RINEX system letter
    code: str              #: RINEX 3 band + attribute, e.g. "1C"
    band: str              #: band name in the system's ICD, e.g. "L1", "E5a", "B1I"
    name: str              #: human-readable signal name
    f0_hz: float           #: carrier [Hz] (GLONASS FDMA: channel k = 0)
    df_hz: float           #: GLONASS FDMA channel spacing [Hz]; 0 for CDMA
    chip_rate_cps: float   #: ranging-code chip rate [chip/s]
    min_power_dbw: float   #: ICD minimum received power [dBW] at a 0 dBic antenna
    min_power_el_deg: float  #: elevation at and above which min_power_dbw holds [deg]
    source: str            #: document for min_power / chip rate

    @property
    def chip_length_m(self) -> float:
        """Length of one chip [m] = c / chip rate."""
        return k.C_MPS / self.chip_rate_cps

    @property
    def wavelength_m(self) -> float:
        """Carrier wavelength at channel 0 [m]."""
        return k.C_MPS / self.f0_hz

    @property
    def power_margin_db(self) -> float:
        """Published exceedance of ``min_power_dbw`` by the satellites [dB] (POWER_MARGIN_DB)."""
        return POWER_MARGIN_DB.get((self.system, self.band), 0.0)

    @property
    def component_db(self) -> float:
        """Share of the signal's power [dB] in the component this RINEX code tracks (COMPONENT_DB): data or
        pilot alone of a data + pilot signal; 0 for the whole signal."""
        return COMPONENT_DB.get((self.system, self.code), 0.0)

    @property
    def dll_noise_factor(self) -> float:
        """Code-noise factor of the modulation against a BPSK code of the same chip rate (DLL_NOISE_FACTOR)."""
        return DLL_NOISE_FACTOR.get((self.system, self.name), 1.0)


# (system, codes, band, name, f0, df, chip rate, min power dBW, elevation deg, source)
_ROWS = (
    # --- GPS -------------------------------------------------------------------------------
    ("G", ("1C",), "L1", "L1 C/A", k.F_L1_HZ, 0.0, 1.023e6, -158.5, 5.0,
     "IS-GPS-200N 3.3.1.6 table 3-Va (IIR/IIR-M/IIF/III L1 C/A); chip rate 3.3.2.1"),
    ("G", ("1P", "1W", "1Y"), "L1", "L1 P(Y)", k.F_L1_HZ, 0.0, 10.23e6, -161.5, 5.0,
     "IS-GPS-200N 3.3.1.6 table 3-Va (L1 P(Y)); chip rate 3.3.2.1"),
    ("G", ("1S", "1L", "1X"), "L1", "L1C", k.F_L1_HZ, 0.0, 1.023e6, -157.0, 5.0,
     "IS-GPS-800J 3.2.1.6 (L1C total: L1CP -158.25 + L1CD -163 dBW)"),
    ("G", ("2S", "2L", "2X"), "L2", "L2C", k.F_L2_HZ, 0.0, 1.023e6, -160.0, 5.0,
     "IS-GPS-200N 3.3.1.6 table 3-Va (L2C, IIR-M/IIF); CM+CL time-multiplexed at 1.023 Mchip/s"),
    ("G", ("2P", "2W", "2Y", "2D"), "L2", "L2 P(Y)", k.F_L2_HZ, 0.0, 10.23e6, -161.5, 5.0,
     "IS-GPS-200N 3.3.1.6 table 3-Va (L2 P(Y), IIR-M/IIF/III)"),
    ("G", ("5I", "5Q", "5X"), "L5", "L5", k.F_L5_HZ, 0.0, 10.23e6, -154.9, 5.0,
     "IS-GPS-705J 3.3.1.6 (I5 and Q5 each -157.9 dBW, IIF); chip rate 3.3.2.1"),
    # --- GLONASS (FDMA) ---------------------------------------------------------------------
    ("R", ("1C",), "G1", "G1 C/A", k.F_G1_HZ, k.DF_G1_HZ, 0.511e6, -161.0, 5.0,
     "GLONASS ICD 5.1 (2008) 3.3.1.6 (L1 >= -161 dBW); C/A chip rate 3.3.2.2"),
    ("R", ("1P",), "G1", "G1 P", k.F_G1_HZ, k.DF_G1_HZ, 5.11e6, -161.0, 5.0,
     "GLONASS ICD 5.1 3.3.1.6; P code 5.11 Mchip/s"),
    ("R", ("2C",), "G2", "G2 C/A", k.F_G2_HZ, k.DF_G2_HZ, 0.511e6, -167.0, 5.0,
     "GLONASS ICD 5.1 3.3.1.6 (L2 >= -167 dBW)"),
    ("R", ("2P",), "G2", "G2 P", k.F_G2_HZ, k.DF_G2_HZ, 5.11e6, -167.0, 5.0,
     "GLONASS ICD 5.1 3.3.1.6 (L2 >= -167 dBW)"),
    # GLONASS CDMA L3OC (data 3I + pilot 3Q), only on the satellites that transmit it (signal_plans/plans.yaml)
    ("R", ("3I", "3Q", "3X"), "G3", "L3OC", k.F_G3_HZ, 0.0, 10.23e6, -158.0, 5.0,
     "GLONASS ICD CDMA open service L3 band 1.0 (2016): 1202.025 MHz, 10.23 Mchip/s; minimum power "
     "(data + pilot) -158 dBW written from memory, check against the document"),
    # --- Galileo ----------------------------------------------------------------------------
    ("E", ("1B", "1C", "1X", "1Z"), "E1", "E1 OS", k.F_L1_HZ, 0.0, 1.023e6, -157.0, 10.0,
     "Galileo OS SIS ICD 2.1 2.3.2 table 4 (E1-B + E1-C); chip rate table 3"),
    ("E", ("5I", "5Q", "5X"), "E5a", "E5a", k.F_L5_HZ, 0.0, 10.23e6, -155.0, 10.0,
     "Galileo OS SIS ICD 2.1 2.3.2 table 4 (E5a-I + E5a-Q)"),
    ("E", ("7I", "7Q", "7X"), "E5b", "E5b", k.F_E5B_HZ, 0.0, 10.23e6, -155.0, 10.0,
     "Galileo OS SIS ICD 2.1 2.3.2 table 4 (E5b-I + E5b-Q)"),
    ("E", ("8I", "8Q", "8X"), "E5", "E5 AltBOC", k.F_E5_HZ, 0.0, 10.23e6, -152.0, 10.0,
     "Galileo OS SIS ICD 2.1 2.3.2 table 4 (E5a + E5b power)"),
    ("E", ("6B", "6C", "6X", "6Z"), "E6", "E6", k.F_E6_HZ, 0.0, 5.115e6, -155.0, 10.0,
     "Galileo E6-B/C SIS ICD 1.0 (2023) (E6-B + E6-C); chip rate 5.115 Mchip/s"),
    # --- BeiDou -----------------------------------------------------------------------------
    ("C", ("2I", "2Q", "2X"), "B1I", "B1I", k.F_B1I_HZ, 0.0, 2.046e6, -163.0, 5.0,
     "BDS-SIS-ICD-B1I 3.0 (2019) 3.2 / 4.2 (B1I >= -163 dBW); chip rate 2.046 Mchip/s"),
    ("C", ("7I", "7Q", "7X"), "B2I", "B2I", k.F_E5B_HZ, 0.0, 2.046e6, -163.0, 5.0,
     "BDS-SIS-ICD 2.1 (2016) (B2I >= -163 dBW); BDS-2 satellites only"),
    ("C", ("6I", "6Q", "6X"), "B3I", "B3I", k.F_B3I_HZ, 0.0, 10.23e6, -163.0, 5.0,
     "BDS-SIS-ICD-B3I 1.0 (2018) (B3I >= -163 dBW); chip rate 10.23 Mchip/s"),
    ("C", ("1D", "1P", "1X"), "B1C", "B1C", k.F_L1_HZ, 0.0, 1.023e6, -159.0, 5.0,
     "BDS-SIS-ICD-B1C 1.0 (2017) 4.2 (MEO, data + pilot); chip rate 1.023 Mchip/s"),
    ("C", ("5D", "5P", "5X"), "B2a", "B2a", k.F_L5_HZ, 0.0, 10.23e6, -156.0, 5.0,
     "BDS-SIS-ICD-B2a 1.0 (2017) 4.2 (MEO, data + pilot)"),
    ("C", ("7D", "7P", "7Z"), "B2b", "B2b", k.F_E5B_HZ, 0.0, 10.23e6, -160.0, 5.0,
     "BDS-SIS-ICD-B2b 1.0 (2020) 4.2 (MEO, B2b-I); RINEX 3.04 codes 7D/7P/7Z"),
    # --- QZSS -------------------------------------------------------------------------------
    ("J", ("1C",), "L1", "L1 C/A", k.F_L1_HZ, 0.0, 1.023e6, -158.5, 10.0,
     "IS-QZSS-PNT-005 3.1.2.1 table 3.1.2-1 (L1C/A)"),
    ("J", ("1S", "1L", "1X"), "L1", "L1C", k.F_L1_HZ, 0.0, 1.023e6, -157.0, 10.0,
     "IS-QZSS-PNT-005 table 3.1.2-1 (L1C total)"),
    ("J", ("2S", "2L", "2X"), "L2", "L2C", k.F_L2_HZ, 0.0, 1.023e6, -160.0, 10.0,
     "IS-QZSS-PNT-005 table 3.1.2-1 (L2C)"),
    ("J", ("5I", "5Q", "5X"), "L5", "L5", k.F_L5_HZ, 0.0, 10.23e6, -154.9, 10.0,
     "IS-QZSS-PNT-005 table 3.1.2-1 (I5 and Q5 each -157.9 dBW)"),
    ("J", ("6S", "6L", "6X", "6E", "6Z"), "L6", "L6", k.F_E6_HZ, 0.0, 5.115e6, -155.7, 10.0,
     "IS-QZSS-L6-005 3.1.2 (L6 -155.7 dBW); chip rate 5.115 Mchip/s"),
    # --- NavIC ------------------------------------------------------------------------------
    ("I", ("5A",), "L5", "L5 SPS", k.F_L5_HZ, 0.0, 1.023e6, -159.0, 5.0,
     "IRNSS SIS ICD for SPS 1.1 (2017) 2.4 (L5 SPS >= -159 dBW); chip rate 1.023 Mchip/s"),
    ("I", ("9A",), "S", "S SPS", k.F_S_HZ, 0.0, 1.023e6, -162.3, 5.0,
     "IRNSS SIS ICD for SPS 1.1 2.4 (S SPS >= -162.3 dBW)"),
)

# ---- power and modulation beyond the ICD minimum (receiver/cn0.py, receiver/noise.py) --------------------------
#: Received power above the ICD minimum [dB] at the edge of coverage, per (system, band): satellites deliver
#: more than the specification.  Steigenberger, Thoelert, Montenbruck, "GNSS satellite transmit power and its
#: impact on orbit determination", J Geod 92:609 (2018) (transmit power per block from high-gain antenna
#: measurements) and Thoelert et al.'s DLR signal-quality measurements put GPS and Galileo 1-4 dB above the
#: ICD minimum and BeiDou's B1I/B2I/B3I well above their conservative -163 dBW; GLONASS-M transmits L2 as
#: strongly as L1 (GLONASS ICD 5.1 raises the GLONASS-M L2 minimum to -161 dBW, the row holds the older
#: -167 dBW).  The figures below are per system and band, written from memory of those papers (check against
#: the documents); per satellite generation: TODO once signal_plans gives the block of each satellite.
POWER_MARGIN_DB: dict[tuple[str, str], float] = {
    ("G", "L1"): 3.0, ("G", "L2"): 2.5, ("G", "L5"): 2.0,
    ("R", "G1"): 3.0, ("R", "G2"): 9.0, ("R", "G3"): 2.0,        # G2: 6 dB GLONASS-M raise + 3 dB as G1
    ("E", "E1"): 2.0, ("E", "E5a"): 2.0, ("E", "E5b"): 2.0, ("E", "E5"): 2.0, ("E", "E6"): 2.0,
    ("C", "B1I"): 6.0, ("C", "B2I"): 6.0, ("C", "B3I"): 6.0, ("C", "B1C"): 2.0, ("C", "B2a"): 2.0, ("C", "B2b"): 2.0,
    ("J", "L1"): 3.0, ("J", "L2"): 2.0, ("J", "L5"): 2.0, ("J", "L6"): 2.0,
    ("I", "L5"): 2.0, ("I", "S"): 2.0,
}
_HALF_DB = -3.01   # 10 log10(1/2): data and pilot share the power equally
#: Power of the tracked component against the row's total [dB], per RINEX code (RINEX 3.05 tables 4-10:
#: attribute I/D/S/B = data, Q/P/L/C = pilot, X = both).  Splits: GPS/QZSS L1C 25 % data / 75 % pilot
#: (IS-GPS-800J 3.2.1.6); L2C CM and CL chip by chip (IS-GPS-200N 3.3.2.3, half each); L5 I5/Q5 equal
#: (IS-GPS-705J); Galileo E1-B/C, E5a-I/Q, E5b-I/Q, E5 pilot, E6-B/C equal (OS SIS ICD 2.1 2.3.2); BeiDou B1C
#: 25/75 and B2a 50/50 (BDS-SIS-ICD-B1C/B2a 1.0); GLONASS L3OC I/Q equal.  B1I/B2I/B3I rows hold the
#: I component already (0).
COMPONENT_DB: dict[tuple[str, str], float] = {
    ("G", "1S"): -6.02, ("G", "1L"): -1.25, ("G", "2S"): _HALF_DB, ("G", "2L"): _HALF_DB,
    ("G", "5I"): _HALF_DB, ("G", "5Q"): _HALF_DB,
    ("J", "1S"): -6.02, ("J", "1L"): -1.25, ("J", "2S"): _HALF_DB, ("J", "2L"): _HALF_DB,
    ("J", "5I"): _HALF_DB, ("J", "5Q"): _HALF_DB,
    ("R", "3I"): _HALF_DB, ("R", "3Q"): _HALF_DB,
    ("E", "1B"): _HALF_DB, ("E", "1C"): _HALF_DB, ("E", "5I"): _HALF_DB, ("E", "5Q"): _HALF_DB,
    ("E", "7I"): _HALF_DB, ("E", "7Q"): _HALF_DB, ("E", "8I"): _HALF_DB, ("E", "8Q"): _HALF_DB,
    ("E", "6B"): _HALF_DB, ("E", "6C"): _HALF_DB,
    ("C", "1D"): -6.02, ("C", "1P"): -1.25, ("C", "5D"): _HALF_DB, ("C", "5P"): _HALF_DB,
}
#: DLL thermal-noise factor of BOC-family codes against BPSK of the same chip rate, for a narrow early-late
#: spacing: the correlation peak of a sine BOC with k half-periods of subcarrier per chip is (2k - 1) times
#: steeper, the discriminator noise variance scales as 1 / slope: BOC(1,1) / CBOC / TMBOC / QMBOC: 1/sqrt(3),
#: AltBOC(15,10): 1/sqrt(5) (Betz, "Binary offset carrier modulations for radionavigation", Navigation 48(4),
#: 2001; Kaplan & Hegarty 2017 ch. 8; from memory, check).  Keyed by (system, signal name); others (BPSK): 1.
DLL_NOISE_FACTOR: dict[tuple[str, str], float] = {
    ("G", "L1C"): 3 ** -0.5, ("J", "L1C"): 3 ** -0.5, ("E", "E1 OS"): 3 ** -0.5, ("E", "E5 AltBOC"): 5 ** -0.5,
    ("C", "B1C"): 3 ** -0.5,
}

#: (system, code) -> Signal
SIGNALS: dict[tuple[str, str], Signal] = {}
for _sys, _codes, _band, _name, _f0, _df, _chip, _pmin, _el, _src in _ROWS:
    for _code in _codes:
        SIGNALS[(_sys, _code)] = Signal(_sys, _code, _band, _name, _f0, _df, _chip, _pmin, _el, _src)

#: BeiDou geostationary satellites: C01-C05 (BDS-2) and C59-C63 (BDS-3), BDS-OS-PS 3.0 (2021) table 3-1
BEIDOU_GEO_PATTERN = r"C0[1-5]|C59|C6[0-3]"

def signal(system: str, code: str) -> Signal:
    """The :class:`Signal` of ``(system, code)``; ``code`` may be "1C" or an obs type "C1C"/"L1C"."""
    if system not in SYSTEMS:
        raise ValueError(f"signals.signal: parameter 'system' = {system!r} is not one of {SYSTEMS}")
    c = str(code)
    if len(c) == 3 and c[0] in "CLDS":
        c = c[1:]
    try:
        return SIGNALS[(system, c)]
    except KeyError:
        known = sorted(cd for (s, cd) in SIGNALS if s == system)
        raise ValueError(
            f"signals.signal: parameter 'code' = {code!r} is not a known RINEX 3 code for system "
            f"{system!r} (known: {', '.join(known)})"
        ) from None


def frequency_hz(system: str, code: str, glo_channel=0):
    """Carrier frequency [Hz]; for GLONASS FDMA f = f0 + k * df (GLONASS ICD 5.1 3.3.1.4).

    ``glo_channel`` (k, -7..+6 in use, -7..+13 accepted) may be an array: the result broadcasts.
    Ignored (must be 0 or anything) for CDMA signals.
    """
    s = signal(system, code)
    if s.df_hz == 0.0:
        kk = np.asarray(glo_channel)
        return s.f0_hz if kk.ndim == 0 else np.full(kk.shape, s.f0_hz)
    kk = np.asarray(glo_channel)
    if not np.issubdtype(kk.dtype, np.integer):
        if not np.all(np.equal(np.mod(kk, 1), 0)):
            raise ValueError(f"signals.frequency_hz: parameter 'glo_channel' = {glo_channel!r} is not an integer")
    if np.any(kk < -7) or np.any(kk > 13):
        raise ValueError(f"signals.frequency_hz: parameter 'glo_channel' = {glo_channel!r} is outside -7..13")
    f = s.f0_hz + kk * s.df_hz
    return float(f) if np.ndim(f) == 0 else f


def wavelength_m(system: str, code: str, glo_channel=0):
    """Carrier wavelength [m] = c / f (broadcasts over ``glo_channel`` like :func:`frequency_hz`)."""
    return k.C_MPS / frequency_hz(system, code, glo_channel)


def validate_profile(prof: dict[str, list[str]]) -> None:
    """Raise ValueError naming the system/code of a profile mapping that the table does not know."""
    for sys_, codes in prof.items():
        for c in codes:
            signal(sys_, c)


def group_delay_factor(systems, codes, freq):
    """Factor on the broadcast group delay (TGD/BGD) in the satellite clock of each signal (arrays of system
    letters, band+attribute codes "1C", carrier frequencies [Hz]): GPS/QZSS TGD scaled by (f_L1/f)^2 on L1/L2
    (IS-GPS-200N 20.3.3.3.3.2); Galileo BGD(E1,E5a) by (f_E1/f)^2 on E1/E5a/E5b (OS SIS ICD 5.1.5); BeiDou
    TGD1 on B1I (BDS-SIS-ICD-B1I 5.2.4.10); 0 elsewhere (inter-signal corrections not modelled)."""
    systems = np.asarray(systems)
    band = np.array([c[0] for c in codes])
    f = np.zeros(len(codes))
    gps_like = (systems == "G") | (systems == "J")
    f = np.where(gps_like & ((band == "1") | (band == "2")), (k.F_L1_HZ / freq) ** 2, f)
    gal = (systems == "E") & ((band == "1") | (band == "5") | (band == "7"))
    f = np.where(gal, (k.F_L1_HZ / freq) ** 2, f)
    f = np.where((systems == "C") & (band == "2"), 1.0, f)
    return f

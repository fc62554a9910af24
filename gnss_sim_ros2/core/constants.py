"""Physical and system constants, each with its unit and its source document.

Names carry units.  Where two systems define the same constant differently
(GM, Earth rotation rate) each system's value is kept: ephemerides must be
evaluated with the constants of the ICD they were fitted with.
"""

#: speed of light in vacuum [m/s] (IS-GPS-200N 20.3.4.3; all GNSS ICDs)
C_MPS = 299792458.0

# --- Earth gravitational constants, by system --------------------------------
#: WGS 84 GM [m^3/s^2] (IS-GPS-200N 20.3.3.4.3.3, table 20-IV); also QZSS, NavIC
GM_GPS_M3PS2 = 3.986005e14
#: GTRF GM [m^3/s^2] (Galileo OS SIS ICD 2.1, 5.1.1)
GM_GAL_M3PS2 = 3.986004418e14
#: CGCS2000 GM [m^3/s^2] (BDS-SIS-ICD-B1I 3.0, 5.2.4.10)
GM_BDS_M3PS2 = 3.986004418e14
#: PZ-90 GM [m^3/s^2] (GLONASS ICD 5.1, A.3.1.2)
GM_GLO_M3PS2 = 3.9860044e14

# --- Earth rotation rate, by system --------------------------------------------
#: WGS 84 Earth rotation rate [rad/s] (IS-GPS-200N table 20-IV)
OMEGA_E_GPS_RADPS = 7.2921151467e-5
#: GTRF Earth rotation rate [rad/s] (Galileo OS SIS ICD 2.1, 5.1.1)
OMEGA_E_GAL_RADPS = 7.2921151467e-5
#: CGCS2000 Earth rotation rate [rad/s] (BDS-SIS-ICD-B1I 3.0, 5.2.4.10)
OMEGA_E_BDS_RADPS = 7.292115e-5
#: PZ-90 Earth rotation rate [rad/s] (GLONASS ICD 5.1, A.3.1.2)
OMEGA_E_GLO_RADPS = 7.292115e-5

#: relativistic clock constant F = -2 sqrt(GM)/c^2 [s/m^0.5] (IS-GPS-200N 20.3.3.3.3.1)
F_REL_GPS_S_PER_SQRTM = -4.442807633e-10
#: Galileo value [s/m^0.5] (Galileo OS SIS ICD 2.1, 5.1.3)
F_REL_GAL_S_PER_SQRTM = -4.442807309e-10
#: BeiDou value [s/m^0.5] (BDS-SIS-ICD-B1I 3.0, 5.2.4.10)
F_REL_BDS_S_PER_SQRTM = -4.442807309e-10

# --- GLONASS PZ-90 geopotential (GLONASS ICD 5.1, A.3.1.2) -----------------------
#: PZ-90 equatorial radius [m]
A_E_GLO_M = 6378136.0
#: second zonal harmonic J2 of PZ-90 [-] (C20 = -J2)
J2_GLO = 1.0826257e-3

# --- Ellipsoid (WGS 84; NIMA TR8350.2) --------------------------------------------
#: WGS 84 semi-major axis [m]
WGS84_A_M = 6378137.0
#: WGS 84 flattening [-]
WGS84_F = 1.0 / 298.257223563

# --- Time ---------------------------------------------------------------------
#: seconds per GNSS week [s]
SECONDS_PER_WEEK = 604800.0

# --- Carrier frequencies [Hz] (IS-GPS-200N 3.3.1.1, IS-GPS-705 3.3.1.1,
#     Galileo OS SIS ICD 2.1 2.3, BDS ICDs B1I/B1C/B2a/B2b/B3I, IS-QZSS-PNT,
#     IRNSS SIS ICD 1.1, GLONASS ICD 5.1 3.3.1.1 and CDMA ICDs) --------------------
F_L1_HZ = 1575.42e6   # GPS L1, Galileo E1, QZSS L1, BeiDou B1C, NavIC L1
F_L2_HZ = 1227.60e6   # GPS/QZSS L2
F_L5_HZ = 1176.45e6   # GPS/QZSS L5, Galileo E5a, BeiDou B2a, NavIC L5
F_E5B_HZ = 1207.140e6  # Galileo E5b, BeiDou B2b (B2I)
F_E5_HZ = 1191.795e6   # Galileo E5 AltBOC, BeiDou B2 (B2a+B2b)
F_E6_HZ = 1278.75e6    # Galileo E6, QZSS L6 (LEX)
F_B1I_HZ = 1561.098e6  # BeiDou B1I
F_B3I_HZ = 1268.52e6   # BeiDou B3I
F_S_HZ = 2492.028e6    # NavIC S band
F_G1_HZ = 1602.0e6     # GLONASS G1 channel 0
DF_G1_HZ = 0.5625e6    # GLONASS G1 channel spacing
F_G2_HZ = 1246.0e6     # GLONASS G2 channel 0
DF_G2_HZ = 0.4375e6    # GLONASS G2 channel spacing
F_G3_HZ = 1202.025e6   # GLONASS G3 CDMA

# --- Added for the broadcast ephemeris (core/ephemeris) --------------------------
#: QZSS GM [m^3/s^2] (IS-QZSS-PNT-005 5.2.4.13, table 5.2.4-2: WGS 84 value as GPS)
GM_QZS_M3PS2 = 3.986005e14
#: NavIC GM [m^3/s^2] (IRNSS SIS ICD for SPS 1.1, 6.2.1.3: WGS 84 value as GPS)
GM_IRN_M3PS2 = 3.986005e14
#: QZSS / NavIC Earth rotation rate [rad/s] (IS-QZSS-PNT-005 table 5.2.4-2; IRNSS SIS ICD 1.1 6.2.1.3)
OMEGA_E_QZS_RADPS = 7.2921151467e-5
OMEGA_E_IRN_RADPS = 7.2921151467e-5
#: QZSS / NavIC relativistic constant F [s/m^0.5] (as GPS: IS-QZSS-PNT-005 5.2.4.10; IRNSS SIS ICD 1.1 6.2.1.2)
F_REL_QZS_S_PER_SQRTM = -4.442807633e-10
F_REL_IRN_S_PER_SQRTM = -4.442807633e-10
#: tilt of the BeiDou GEO orbit frame about X [deg] (BDS-SIS-ICD-B1I 3.0, 5.2.4.12: R_X(-5 deg))
BDS_GEO_TILT_DEG = -5.0
#: WGS 84 / EGM96 second zonal harmonic J2 = -sqrt(5) C20bar [-] (NIMA TR8350.2 table 5.1,
#: C20bar = -0.484166774985e-3); used for the analytic acceleration of Keplerian ephemerides
J2_WGS84 = 1.08262982131e-3

# --- Thermal noise and Earth sphere (link budgets) ---------------------------------
#: Boltzmann constant [J/K] (exact; SI Brochure, 9th ed., BIPM 2019)
K_BOLTZMANN_JPK = 1.380649e-23
#: standard noise reference temperature [K] (IEEE Std 100 / ITU-R P.372): kT0 = -204.0 dBW/Hz
T0_NOISE_K = 290.0
#: mean Earth radius R1 [m] (Moritz, Geodetic Reference System 1980, J. Geodesy 74:128, 2000)
R_EARTH_MEAN_M = 6371008.8

# --- Scene / visibility --------------------------------------------------------------
#: default specific attenuation of foliage (tree crowns) [dB/m]: chosen so that a typical
#: crown path of 5-8 m gives about 12 dB, the median single-tree fade measured by
#: Vogel & Goldhirsh (IEEE Trans. Antennas Propag. 34(12), 1986, 869 MHz; fades 10-20 dB;
#: see docs notes physics-anchors.md): 1.85 dB/m x 6.5 m = 12.0 dB.
FOLIAGE_ATTENUATION_DB_PER_M = 1.85
#: fixed foliage loss [dB] of the "touch" foliage model (any penetrable volume on the line of sight
#: costs this, whatever the path length inside): the median single-tree fade of Vogel & Goldhirsh
#: (IEEE Trans. Antennas Propag. 34(12), 1986; fades 10-20 dB), the figure FOLIAGE_ATTENUATION_DB_PER_M
#: is scaled to (1.85 dB/m x 6.5 m)
FOLIAGE_MEDIAN_LOSS_DB = 12.0

#: Earth rotation rate [rad/s] each system's ICD uses (for the Sagnac term of its satellites)
OMEGA_BY_SYSTEM = {
    "G": OMEGA_E_GPS_RADPS, "J": OMEGA_E_QZS_RADPS, "I": OMEGA_E_IRN_RADPS,
    "E": OMEGA_E_GAL_RADPS, "C": OMEGA_E_BDS_RADPS, "R": OMEGA_E_GLO_RADPS,
}

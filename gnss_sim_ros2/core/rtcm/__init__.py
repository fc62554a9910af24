"""RTCM 10403.3 (RTCM3) output of a simulated receiver: MSM observations, station, ephemerides.

``writer.RtcmWriter`` is the entry point (same epoch-by-epoch shape as
core/rinex/obs_write.RinexObsWriter); ``msm``, ``station`` and ``ephemeris`` encode
single messages; ``frame`` packs bits and frames a message (CRC-24Q).
"""

"""Receiver-chain test inputs: the default receiver parameters at a rate and the synthetic ephemeris over a span."""
from __future__ import annotations

import tempfile


def synthetic_sky(rate_hz: float, span_s: float):
    """(receiver parameters of the default configuration at ``rate_hz``, start GnssTime, the synthetic ephemeris
    provider from the start over ``span_s`` [s])."""
    from gnss_sim_ros2.config_file import load_config
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.time import GnssTime

    rcv = load_config(overrides={"/**": {"rate_hz": rate_hz}}).node("receiver")
    start = GnssTime.from_iso(rcv["start_time"])
    with tempfile.TemporaryDirectory() as tmp:
        provider, _ = open_ephemeris("synthetic", start, span_s, rcv["systems"], workdir=tmp)
    return rcv, start, provider

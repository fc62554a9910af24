"""The scenario's ground truth as a message: ``/gnss/threats/active`` (std_msgs/String, one JSON object per epoch)

    {"stamp": [sec, nanosec], "active": ["car_ppd", "fault2"],
     "bands": {"1": {"jamming_indicator": 87, "agc_db": 20.6}}}

``active``: the names of the scenario's events active at the epoch (the ``active_events`` column of fix.csv);
``bands``: per RINEX band digit the receiver's jamming indicator (0-255, like u-blox jamInd) and AGC gain
reduction [dB] (core/threats/jamming.py), empty without an active jammer.  A user's detector is scored against
``active``."""
from __future__ import annotations

import json

from std_msgs.msg import String


def threats_to_msg(stamp, active: list[str], bands: dict) -> String:
    return String(data=json.dumps({"stamp": [int(stamp[0]), int(stamp[1])], "active": list(active),
                                   "bands": bands}, sort_keys=True))


def threats_from_msg(msg) -> dict:
    """The JSON object of a ``threats/active`` message."""
    return json.loads(msg.data)

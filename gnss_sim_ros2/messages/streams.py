"""The receiver's byte and text streams as std_msgs (nmea_msgs, rtcm_msgs and mavros_msgs are not available as
Kilted wheels on PyPI): NMEA sentences as ``std_msgs/String``, RTCM3 frames as ``std_msgs/UInt8MultiArray``."""
from __future__ import annotations

from std_msgs.msg import String, UInt8MultiArray


def nmea_to_msg(sentences: str) -> String:
    """One epoch's NMEA sentences (or one sentence), CR LF separated as the receiver writes them."""
    return String(data=sentences)


def rtcm_to_msg(frames: bytes) -> UInt8MultiArray:
    """RTCM3 frames (one epoch's messages, or any run of whole frames)."""
    return UInt8MultiArray(data=frames)


def rtcm_from_msg(msg) -> bytes:
    """The bytes of an RTCM3 UInt8MultiArray."""
    return bytes(msg.data)

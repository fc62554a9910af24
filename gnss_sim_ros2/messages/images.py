"""``sensor_msgs/Image`` of a picture held as a numpy array."""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import Image


def rgb8_image(header, rgb: np.ndarray) -> Image:
    """An ``rgb8`` Image of an (height, width, 3) uint8 array, rows top down."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    height, width = rgb.shape[:2]
    return Image(header=header, height=height, width=width, encoding="rgb8", is_bigendian=0, step=3 * width,
                 data=rgb.tobytes())

"""image_transport's `compressed` transport as the sim publishes it: `<image>/compressed`,
sensor_msgs/CompressedImage, JPEG by cv2.imencode, the format string compressed_image_transport
writes ('<encoding>; jpeg compressed bgr8' for colour, '...mono8' for grey), so its subscriber
(image_transport republish, RViz, Foxglove, rqt_image_view) decodes it as its own.

A VGA rgb8 frame is 0.92 MB raw; the sim's tabletop scene is ~0.13 MB as JPEG at quality 95
(compressed_image_transport's default jpeg_quality), ~1 ms of CPU per frame: figures in
docs/vizzy_sim_bridge.md.
"""

from __future__ import annotations

import array
from typing import Any

import cv2
import numpy as np

from vizzy_runtime.ros import USING_REAL_ROS, message

CompressedImage = message('sensor_msgs/msg/CompressedImage')

SUFFIX = '/compressed'          # image_transport's topic for the transport: <image>/compressed
DEFAULT_JPEG_QUALITY = 95       # compressed_image_transport's jpeg_quality default
# what cv2 needs to write the true colours, per encoding the sim publishes or may
_TO_BGR = {'rgb8': cv2.COLOR_RGB2BGR, 'bgr8': None, 'mono8': None}


def jpeg_format(encoding: str) -> str:
    """CompressedImage.format of a JPEG of an image in encoding, as compressed_image_transport
    writes it: what the image was, then what the JPEG holds."""
    return f'{encoding}; jpeg compressed {"mono8" if encoding == "mono8" else "bgr8"}'


def encode_jpeg(image: np.ndarray, encoding: str, quality: int) -> bytes:
    """JPEG bytes of an rgb8, bgr8 or mono8 image; ValueError names an encoding it cannot."""
    if encoding not in _TO_BGR:
        raise ValueError(f'no JPEG of {encoding!r} images (rgb8, bgr8, mono8)')
    code = _TO_BGR[encoding]
    pixels = cv2.cvtColor(image, code) if code is not None else image
    ok, buf = cv2.imencode('.jpg', pixels, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f'cv2.imencode could not encode a {image.shape} {encoding} image')
    return buf.tobytes()


def compressed_image(image: np.ndarray, encoding: str, header: Any, quality: int) -> Any:
    """sensor_msgs/CompressedImage of image (header shared with its raw message)."""
    jpeg = encode_jpeg(image, encoding, quality)
    msg = CompressedImage(format=jpeg_format(encoding))
    msg.header = header
    msg.data = array.array('B', jpeg) if USING_REAL_ROS else np.frombuffer(jpeg, np.uint8)
    return msg

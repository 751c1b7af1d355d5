"""compressed.py: the JPEGs of <image>/compressed carry compressed_image_transport's format
string and the true colours (issue 29 item 3). Plain pytest."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from vizzy_runtime.ros import message
from vizzy_sim_bridge.compressed import (
    DEFAULT_JPEG_QUALITY,
    SUFFIX,
    compressed_image,
    encode_jpeg,
    jpeg_format,
)

Header = message('std_msgs/msg/Header')


def test_format_strings_are_compressed_image_transports() -> None:
    # compressed_publisher.cpp: message.encoding + "; jpeg compressed " + bgr8 or mono8
    assert jpeg_format('rgb8') == 'rgb8; jpeg compressed bgr8'
    assert jpeg_format('bgr8') == 'bgr8; jpeg compressed bgr8'
    assert jpeg_format('mono8') == 'mono8; jpeg compressed mono8'
    assert SUFFIX == '/compressed' and DEFAULT_JPEG_QUALITY == 95


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8'])
def test_the_jpeg_holds_the_true_colours(encoding: str) -> None:
    rgb = np.zeros((48, 64, 3), np.uint8)
    rgb[:, :32] = (220, 30, 30)                 # red left half, blue right half
    rgb[:, 32:] = (30, 30, 220)
    image = rgb if encoding == 'rgb8' else rgb[..., ::-1].copy()
    bgr = cv2.imdecode(np.frombuffer(encode_jpeg(image, encoding, 95), np.uint8),
                       cv2.IMREAD_COLOR)       # any JPEG reader: true colours, BGR in OpenCV
    assert np.abs(bgr[..., ::-1].astype(int) - rgb.astype(int))[:, 4:28].max() <= 8


def test_quality_and_grey_images() -> None:
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    assert len(encode_jpeg(noise, 'rgb8', 20)) < 0.5 * len(encode_jpeg(noise, 'rgb8', 95))
    grey = cv2.imdecode(np.frombuffer(encode_jpeg(noise[..., 0], 'mono8', 95), np.uint8),
                        cv2.IMREAD_UNCHANGED)
    assert grey.shape == (120, 160)


def test_an_encoding_without_a_jpeg_is_one_clear_error() -> None:
    with pytest.raises(ValueError, match=r"no JPEG of '32FC1' images \(rgb8, bgr8, mono8\)"):
        encode_jpeg(np.zeros((4, 4), np.float32), '32FC1', 95)


def test_the_message_shares_the_raw_images_header() -> None:
    header = Header(frame_id='left_camera_optical_frame')
    header.stamp.sec, header.stamp.nanosec = 12, 345
    image = np.full((48, 64, 3), 128, np.uint8)
    msg = compressed_image(image, 'rgb8', header, 95)
    assert msg.format == 'rgb8; jpeg compressed bgr8'
    assert (msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec) == (
        'left_camera_optical_frame', 12, 345)
    assert bytes(msg.data) == encode_jpeg(image, 'rgb8', 95)

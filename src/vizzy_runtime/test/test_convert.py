"""numpy <-> Image / PointCloud2 conversions: exact values, layouts with padding, clear errors."""

import numpy as np
import pytest

from vizzy_runtime import msgs
from vizzy_runtime.convert import (
    ConversionError,
    array_to_pointcloud2,
    camera_k,
    image_to_numpy,
    numpy_to_image,
    pointcloud2_to_array,
)


def test_image_round_trip_through_cdr():
    rng = np.random.default_rng(3)
    for arr, enc in ((rng.integers(0, 255, (4, 5, 3), dtype=np.uint8), 'rgb8'),
                     (rng.integers(0, 65535, (3, 7), dtype=np.uint16), 'mono16'),
                     (rng.standard_normal((2, 3)).astype(np.float32), '32FC1')):
        msg = msgs.deserialize(msgs.serialize(numpy_to_image(arr, enc)), 'sensor_msgs/msg/Image')
        np.testing.assert_array_equal(image_to_numpy(msg), arr)


def test_image_with_row_padding():
    Image = msgs.get_message('sensor_msgs/msg/Image')
    data = np.zeros((2, 8), np.uint8)
    data[:, :6] = [[1, 2, 3, 4, 5, 6], [7, 8, 9, 10, 11, 12]]
    msg = Image(height=2, width=2, encoding='rgb8', step=8, data=data.reshape(-1))
    np.testing.assert_array_equal(image_to_numpy(msg)[1, 1], [10, 11, 12])


def test_image_errors_name_the_problem():
    Image = msgs.get_message('sensor_msgs/msg/Image')
    with pytest.raises(ConversionError, match="unsupported image encoding 'yuv422'"):
        image_to_numpy(Image(height=1, width=1, encoding='yuv422', step=2,
                             data=np.zeros(2, np.uint8)))
    with pytest.raises(ConversionError, match='expected 12'):
        image_to_numpy(Image(height=2, width=2, encoding='rgb8', step=6,
                             data=np.zeros(5, np.uint8)))
    with pytest.raises(ConversionError, match='empty image'):
        image_to_numpy(Image(encoding='rgb8'))
    with pytest.raises(ConversionError, match='does not fit'):
        numpy_to_image(np.zeros((2, 2)), 'rgb8')


def test_organized_pointcloud_round_trip():
    dtype = np.dtype([('x', 'f4'), ('y', 'f4'), ('z', 'f4'), ('rgb', 'u4'), ('cov', 'f4', (6,))])
    pts = np.zeros((3, 4), dtype)
    pts['x'] = np.arange(12).reshape(3, 4)
    pts['z'][0, 0] = np.nan
    pts['cov'][..., 2] = 7
    msg = msgs.deserialize(msgs.serialize(array_to_pointcloud2(pts)), 'sensor_msgs/msg/PointCloud2')
    assert (msg.height, msg.width, msg.is_dense) == (3, 4, False)
    assert [f.name for f in msg.fields] == ['x', 'y', 'z', 'rgb',
                                            'cov'] and msg.fields[4].count == 6
    back = pointcloud2_to_array(msg)
    np.testing.assert_array_equal(back['x'], pts['x'])
    assert np.isnan(back['z'][0, 0]) and (back['cov'][..., 2] == 7).all()


def test_pointcloud_too_short_is_an_error():
    msg = array_to_pointcloud2(np.zeros(4, np.dtype([('x', 'f4'), ('y', 'f4'), ('z', 'f4')])))
    msg.data = msg.data[:20]
    with pytest.raises(ConversionError, match='too few'):
        pointcloud2_to_array(msg)


def test_image_refusal_names_the_reason_and_the_values():
    from vizzy_runtime.convert import (
        EMPTY_IMAGE,
        SHORT_DATA,
        SHORT_STEP,
        TOO_LARGE,
        UNCONVERTIBLE,
        UNSUPPORTED_ENCODING,
        image_refusal,
        numpy_to_image,
    )
    rgb = {'rgb8': 3, 'bgr8': 3}
    ok = numpy_to_image(np.zeros((4, 5, 3), np.uint8), 'rgb8')
    assert image_refusal(ok, rgb) is None
    assert image_refusal(numpy_to_image(np.zeros((4, 5), np.uint8), 'mono8'), rgb) == (
        UNSUPPORTED_ENCODING, "'mono8' is not one of rgb8, bgr8")
    assert image_refusal(ok, rgb, max_size=(4, 100))[0] == TOO_LARGE
    ok.step = 14
    assert image_refusal(ok, rgb) == (SHORT_STEP, 'step 14 < 15 bytes for 5 px of rgb8')
    ok.step, ok.height = 15, 5
    assert image_refusal(ok, rgb) == (SHORT_DATA, '60 data bytes, height 5 x step 15 = 75 expected')
    ok.height = 0
    assert image_refusal(ok, rgb) == (EMPTY_IMAGE, '5x0')
    ok.height = 4

    def refuse(msg):
        raise ValueError('no such layout')

    assert image_refusal(ok, rgb, convert=refuse) == (UNCONVERTIBLE, 'no such layout')


def test_camera_k_refuses_focal_lengths_no_camera_has():
    """Issue 28 item 8: fy = 1e-300 passed a '> 0' check and put a saccade 0.024 m from the
    eyes, with overflow warnings on stderr."""
    from types import SimpleNamespace

    def info(fx: float, fy: float, cx: float = 320.0, cy: float = 240.0) -> SimpleNamespace:
        return SimpleNamespace(k=[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0])

    k = camera_k(info(525.0, 525.0))
    assert k is not None and k.shape == (3, 3) and k[1, 1] == 525.0 and k[0, 2] == 320.0
    for bad in (info(525.0, 1e-300), info(1e-300, 525.0), info(525.0, 0.0), info(-1.0, 525.0),
                info(525.0, 1e7), info(525.0, float('nan')), info(525.0, 525.0, cx=1e300),
                SimpleNamespace(k=[525.0] * 8)):
        assert camera_k(bad) is None, bad.k
    assert camera_k(info(1.0, 1e6)) is not None                      # the bounds are inclusive

"""The sim node on the bundled runtime: its images, RGB-D and camera_info, the compressed streams
(encoded only while read) and camera_info from a calibration file.

A listener node in the test process subscribes to the sim's topics (`running`, conftest.py);
nothing asserts on wall-clock time (every test waits for a condition). Images are rendered at
reduced resolution.
"""


from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from vizzy_runtime.convert import image_to_numpy, pointcloud2_to_array
from vizzy_runtime.ros import (
    Context,
    Node,
    Parameter,
    SingleThreadedExecutor,
    qos_profile_sensor_data,
)
from vizzy_runtime.testing import no_renderer, wait_until
from vizzy_sim_bridge.camera_calibration import Calibration, to_yaml
from vizzy_sim_bridge.compressed import encode_jpeg
from vizzy_sim_bridge.core import render as render_mod
from vizzy_sim_bridge.sim_node import SimNode
from vizzy_vision.camera import camera_matrix
from vizzy_vision.kinematics import (
    BASELINE,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_node_support import (  # noqa: E402
    OVERRIDES,
    TIMEOUT,
    CameraInfo,
    CompressedImage,
    H,
    Image,
    W,
)

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)


def test_images_and_camera_info(running) -> None:
    sim, listener, _ = running
    k = camera_matrix(W, H, 85.4)
    for side in ('left', 'right'):
        img = listener.last[f'/vizzy/{side}/image_raw']
        assert (img.width, img.height, img.encoding) == (W, H, 'rgb8')
        assert img.header.frame_id == f'{side}_camera_optical_frame'
        assert image_to_numpy(img).std() > 5.0
        info = listener.last[f'/vizzy/{side}/camera_info']
        assert info.header.frame_id == img.header.frame_id
        assert (info.width, info.height, info.distortion_model) == (W, H, 'plumb_bob')
        np.testing.assert_allclose(np.reshape(info.k, (3, 3)), k)
        np.testing.assert_array_equal(info.d, np.zeros(5))
        np.testing.assert_array_equal(np.reshape(info.r, (3, 3)), np.eye(3))
        p = np.reshape(info.p, (3, 4))
        np.testing.assert_allclose(p[:, :3], k)
        tx = -k[0, 0] * BASELINE if side == 'right' else 0.0
        assert p[0, 3] == pytest.approx(tx)
    # each stereo pair shares one stamp
    left = set(listener.stamps['/vizzy/left/image_raw'])
    assert left & set(listener.stamps['/vizzy/right/image_raw'])


def test_rgbd_cloud_depth_and_info(running) -> None:
    _, listener, _ = running
    cloud = listener.last['/vizzy/rgbd/points']
    assert cloud.header.frame_id == 'rgbd_camera_optical_frame'
    assert (cloud.height, cloud.width) == (H, W) and not cloud.is_dense
    assert [f.name for f in cloud.fields] == ['x', 'y', 'z', 'rgb']
    pts = pointcloud2_to_array(cloud)
    valid = np.isfinite(pts['z'])
    assert valid.mean() > 0.5
    assert np.nanmin(pts['z']) >= 0.5 and np.nanmax(pts['z']) <= 3.5
    depth = listener.last['/vizzy/rgbd/depth/image_raw']
    assert depth.encoding == '32FC1' and depth.header.frame_id == cloud.header.frame_id
    info = listener.last['/vizzy/rgbd/camera_info']
    np.testing.assert_allclose(np.reshape(info.k, (3, 3)), camera_matrix(W, H, 58.0))
    assert listener.last['/vizzy/rgbd/image_raw'].encoding == 'rgb8'


def _ns(msg: Any) -> int:
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


def test_compressed_images_are_encoded_only_while_read(running) -> None:
    """<image>/compressed beside each raw image (image_transport's compressed transport): a JPEG
    at jpeg_quality with compressed_image_transport's format string and the raw image's header,
    encoded only while something subscribes (issue 29 item 3)."""
    sim, listener, spin = running
    stamps = listener.stamps['/vizzy/left/image_raw']
    encodes, n = sim.jpeg_encodes, len(stamps)
    assert wait_until(lambda: len(stamps) >= n + 4, TIMEOUT, spin=spin)
    assert sim.jpeg_encodes == encodes          # four stereo pairs, RGB-D images: no JPEG

    reader = Node('compressed_reader', context=sim.context, start_parameter_services=False)
    got: dict[str, list[Any]] = {t: [] for t in ('left', 'right', 'rgbd')}
    raw: dict[int, Any] = {}
    for t in got:
        reader.create_subscription(CompressedImage, f'/vizzy/{t}/image_raw/compressed',
                                   got[t].append, qos_profile_sensor_data)
    reader.create_subscription(Image, '/vizzy/left/image_raw',
                               lambda m: raw.__setitem__(_ns(m), m), qos_profile_sensor_data)
    spin.add_node(reader)
    try:
        assert wait_until(lambda: all(len(v) >= 2 for v in got.values())
                          and any(_ns(m) in raw for m in got['left']), TIMEOUT, spin=spin)
        assert sim.jpeg_encodes > encodes
        frames = {'left': 'left_camera_optical_frame', 'right': 'right_camera_optical_frame',
                  'rgbd': 'rgbd_camera_optical_frame'}
        for t, msgs in got.items():
            assert msgs[-1].format == 'rgb8; jpeg compressed bgr8'
            assert msgs[-1].header.frame_id == frames[t]
            bgr = cv2.imdecode(np.asarray(msgs[-1].data, np.uint8), cv2.IMREAD_COLOR)
            assert bgr is not None and bgr.shape == (H, W, 3)
        jpeg = next(m for m in reversed(got['left']) if _ns(m) in raw)   # same stamp as a raw
        # exactly the JPEG of the raw image at quality 95 (true colours: test_compressed.py)
        assert bytes(jpeg.data) == encode_jpeg(image_to_numpy(raw[_ns(jpeg)]), 'rgb8', 95)
        # jpeg_quality applies from the next frame
        size = len(jpeg.data)
        assert sim.set_parameters([Parameter('jpeg_quality', value=20)])[0].successful
        k = len(got['left'])
        assert wait_until(lambda: len(got['left']) > k + 1, TIMEOUT, spin=spin)
        assert len(got['left'][-1].data) < 0.6 * size
    finally:
        spin.remove_node(reader)
        reader.destroy_node()
        sim.set_parameters([Parameter('jpeg_quality', value=95)])
    pubs = [*sim._compressed_pubs.values(), sim._rgbd_compressed_pub]
    assert wait_until(lambda: all(p.get_subscription_count() == 0 for p in pubs), TIMEOUT,
                      spin=spin)
    # a frame rendered from now on is not encoded: once one is out, the one in flight is done
    now = int(round(sim._sim.time * 1e9))
    assert wait_until(lambda: stamps[-1] > now, TIMEOUT, spin=spin)
    encodes, n = sim.jpeg_encodes, len(stamps)
    assert wait_until(lambda: len(stamps) >= n + 4, TIMEOUT, spin=spin)
    assert sim.jpeg_encodes == encodes


def test_camera_info_url_replaces_the_computed_calibration(tmp_path, capfd) -> None:
    """A camera's <camera>_camera_info_url (camera_info_manager's URL, ${NAME} substituted)
    naming a usable camera_calibration_parsers YAML is published as its camera_info; a file for
    another image size and a missing file each give one error line and the computed calibration
    (issue 29 item 4)."""
    try:
        render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        no_renderer(str(exc))
    left = Calibration('vizzy_left', W, H, (200.0, 0.0, 81.0, 0.0, 201.0, 59.0, 0.0, 0.0, 1.0),
                       'plumb_bob', (-0.1, 0.02, 0.001, -0.002, 0.0),
                       (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
                       (199.0, 0.0, 80.0, 0.0, 0.0, 199.5, 60.0, 0.0, 0.0, 0.0, 1.0, 0.0))
    (tmp_path / 'vizzy_left.yaml').write_text(to_yaml(left))
    (tmp_path / 'right.yaml').write_text(to_yaml(replace(left, camera_name='vizzy_right',
                                                         width=2 * W, height=2 * H)))
    urls = {'left': f'file://{tmp_path}/${{NAME}}.yaml', 'right': f'file://{tmp_path}/right.yaml',
            'rgbd': f'file://{tmp_path}/missing.yaml'}
    ctx = Context()
    ctx.init(['test'])
    # in a namespace of its own: the module's sim may still run in this domain
    sim = SimNode(context=ctx, cli_args=['--ros-args', '-r', '__ns:=/calib'],
                  parameter_overrides=[*OVERRIDES, *(Parameter(f'{c}_camera_info_url', value=u)
                                                     for c, u in urls.items())])
    peer = Node('info_reader', context=ctx, start_parameter_services=False)
    infos: dict[str, Any] = {}
    for c in urls:
        peer.create_subscription(CameraInfo, f'/calib/vizzy/{c}/camera_info',
                                 lambda m, c=c: infos.__setitem__(c, m), qos_profile_sensor_data)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(peer)
    try:
        assert wait_until(lambda: len(infos) == 3, TIMEOUT, spin=executor)
    finally:
        executor.remove_node(peer)
        executor.remove_node(sim)
        peer.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()
    info = infos['left']
    assert (info.width, info.height, info.distortion_model) == (W, H, 'plumb_bob')
    np.testing.assert_array_equal(info.k, left.k)
    np.testing.assert_array_equal(info.d, left.d)
    np.testing.assert_array_equal(info.p, left.p)
    assert info.header.frame_id == 'left_camera_optical_frame'
    k = camera_matrix(W, H, 85.4)
    np.testing.assert_allclose(np.reshape(infos['right'].k, (3, 3)), k)
    assert infos['right'].p[3] == pytest.approx(-k[0, 0] * BASELINE)
    np.testing.assert_allclose(np.reshape(infos['rgbd'].k, (3, 3)), camera_matrix(W, H, 58.0))
    assert sim.calibration_sources == {'left': urls['left'], 'right': 'computed',
                                       'rgbd': 'computed'}
    errors = [line for line in capfd.readouterr().err.splitlines()
              if 'publishing the calibration computed from MuJoCo' in line]
    assert len(errors) == 2, errors
    assert (f'right_camera_info_url: {tmp_path}/right.yaml is for {2 * W}x{2 * H} images, '
            f'the camera gives {W}x{H}') in errors[0]
    assert f'rgbd_camera_info_url: cannot read {tmp_path}/missing.yaml' in errors[1]

"""Probe of the sim's camera streams (issue 29 items 3 and 4): the `sim` node in this process
(bundled runtime), the tabletop scene at 640 x 480, the stereo pair at 15 Hz, RGB-D off.

Measures and prints as one JSON object (last line):
  raw_pair_bytes_per_s          left + right image_raw payload (data bytes) per second at 15 Hz
  compressed_pair_bytes_per_s   the same for <image>/compressed, None when the topic never came
  compressed_format             the CompressedImage.format string received
  encodes_unsubscribed          the sim's JPEG encodes while nobody subscribes to /compressed
                                (over PAIRS pairs; None when the sim has no such counter)
  encodes_subscribed            the same while this process subscribes to both
  jpeg_cpu_ms_q90 / _q95        CPU ms (this thread's) per cv2.imencode of one rendered VGA
                                frame, RGB -> BGR included, median of REPS
  left_fx_published             K[0] of /vizzy/left/camera_info with left_camera_info_url set to
                                a camera_calibration_parsers YAML saying fx = 500 (computed: 346.78)
  right_fx_published            K[0] of /vizzy/right/camera_info with right_camera_info_url set
                                to a file that does not exist (expected: the computed 346.78)

    .venv/bin/python bench/camera_streams.py
"""

from __future__ import annotations

import json
import os
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

RATE_HZ = 15.0
PAIRS = 30
REPS = 30
CALIBRATION = """image_width: 640
image_height: 480
camera_name: vizzy_left
camera_matrix:
  rows: 3
  cols: 3
  data: [500, 0, 320, 0, 500, 240, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.01, -0.02, 0, 0, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [500, 0, 320, 0, 0, 500, 240, 0, 0, 0, 1, 0]
"""


def main() -> int:
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))
    os.environ['VIZZY_RUNTIME'] = 'bundled'
    from vizzy_runtime.convert import image_to_numpy
    from vizzy_runtime.ros import (
        Context,
        Node,
        Parameter,
        SingleThreadedExecutor,
        message,
        qos_profile_sensor_data,
    )
    from vizzy_runtime.testing import wait_until
    from vizzy_sim_bridge.sim_node import SimNode

    Image = message('sensor_msgs/msg/Image')
    CompressedImage = message('sensor_msgs/msg/CompressedImage')
    CameraInfo = message('sensor_msgs/msg/CameraInfo')
    tmp = Path(tempfile.mkdtemp())
    (tmp / 'left.yaml').write_text(CALIBRATION)
    overrides = [Parameter('rate_hz', value=RATE_HZ), Parameter('rgbd_rate_hz', value=0.0),
                 Parameter('initial_joint_positions', value=[0.0, 0.2, 0.15, 0.0, 0.0]),
                 Parameter('left_camera_info_url', value=f'file://{tmp}/left.yaml'),
                 Parameter('right_camera_info_url', value=f'file://{tmp}/missing.yaml')]
    ctx = Context()
    ctx.init(['probe'])
    try:
        sim = SimNode(context=ctx, parameter_overrides=overrides)
    except Exception as exc:  # noqa: BLE001 - the defect may be that the parameter is refused
        print(f'with the camera_info_url parameters the sim did not start: '
              f'{type(exc).__name__}: {exc}', file=sys.stderr)
        sim = SimNode(context=ctx, parameter_overrides=overrides[:3])
    peer = Node('probe', context=ctx, start_parameter_services=False)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(peer)
    raw: dict[str, list[Any]] = {'left': [], 'right': []}
    comp: dict[str, list[Any]] = {'left': [], 'right': []}
    info: dict[str, Any] = {}
    for e in raw:
        peer.create_subscription(Image, f'/vizzy/{e}/image_raw',
                                 lambda m, e=e: raw[e].append(m), qos_profile_sensor_data)
        peer.create_subscription(CameraInfo, f'/vizzy/{e}/camera_info',
                                 lambda m, e=e: info.__setitem__(e, m), qos_profile_sensor_data)
    counter = lambda: getattr(sim, 'jpeg_encodes', None)  # noqa: E731
    result: dict[str, Any] = {}
    try:
        assert wait_until(lambda: len(raw['left']) >= 3 and len(info) == 2, 120.0, spin=executor)
        for v in raw.values():
            v.clear()
        before = counter()
        assert wait_until(lambda: min(map(len, raw.values())) >= PAIRS, 120.0, spin=executor)
        after = counter()
        result['encodes_unsubscribed'] = None if before is None else after - before
        raw_pair = sum(len(m.data) for v in raw.values() for m in v[:PAIRS]) / PAIRS
        result['raw_pair_bytes_per_s'] = round(raw_pair * RATE_HZ)
        for e in comp:
            peer.create_subscription(CompressedImage, f'/vizzy/{e}/image_raw/compressed',
                                     lambda m, e=e: comp[e].append(m), qos_profile_sensor_data)
        got = wait_until(lambda: min(map(len, comp.values())) >= 2, 15.0, spin=executor)
        if got:
            for v in comp.values():
                v.clear()
            before = counter()
            assert wait_until(lambda: min(map(len, comp.values())) >= PAIRS, 120.0,
                              spin=executor)
            after = counter()
            result['encodes_subscribed'] = None if before is None else after - before
            pair = sum(len(m.data) for v in comp.values() for m in v[:PAIRS]) / PAIRS
            result['compressed_pair_bytes_per_s'] = round(pair * RATE_HZ)
            result['compressed_format'] = comp['left'][-1].format
        else:
            result['compressed_pair_bytes_per_s'] = None
            result['compressed_format'] = None
        result['left_fx_published'] = round(float(info['left'].k[0]), 3)
        result['right_fx_published'] = round(float(info['right'].k[0]), 3)
        frame = image_to_numpy(raw['left'][-1])
    finally:
        executor.remove_node(peer)
        executor.remove_node(sim)
        peer.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()
    for q in (90, 95):
        times = []
        for _ in range(REPS):
            t0 = time.thread_time()
            ok, buf = cv2.imencode('.jpg', cv2.cvtColor(frame, cv2.COLOR_RGB2BGR),
                                   [cv2.IMWRITE_JPEG_QUALITY, q])
            times.append(time.thread_time() - t0)
            assert ok
        result[f'jpeg_cpu_ms_q{q}'] = round(1e3 * statistics.median(times), 2)
        result[f'jpeg_bytes_q{q}'] = int(buf.size)
    result['raw_frame_bytes'] = int(frame.nbytes)
    result['frame_std'] = round(float(np.std(frame)), 1)
    print(json.dumps(result), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""Probe of vizzy_runtime.tf's buffer (issue 28, item 3): lookups, memory, loops, stamps.

The head's real tree (vizzy_vision.kinematics: world -> base_link -> neck_pan_link -> ... ->
left/right_camera_optical_frame, ego; the joints on /tf at 100 Hz of sim time, the rest on
/tf_static, as the simulator publishes them), fed as TFMessage transforms the way
TransformListener does. Measured, in CPU time (time.process_time, so a loaded machine changes
little):

- lookup_ms: one ego <- left_camera_optical_frame lookup (latest), with the real tree only,
  and again after `--foreign` (300,000) foreign frame names streamed on /tf (50 per message,
  stamped over 60 s of sim time: issue 28 saw 321,500 in 60 s; the buffer's clock follows the
  stamps; the head's joints go on at 100 Hz meanwhile), plus lookup_at_stamp_ms (the same
  lookup at a stamp between two /tf samples, where the buffer has stamps);
- foreign_memory_mb: what the buffer grew by over the stream (tracemalloc, after gc), and
  frames_kept: the frames it holds after the stream;
- loop_*: a foreign edge that closes a loop with the real tree (left_camera_optical_frame ->
  base_link), once on /tf and once on /tf_static: does ego <- left still come out right?
- pan_error_deg: the head pans at 1 rad/s (neck pan); an image is stamped between two /tf
  samples and looked up 50 ms later (/tf has moved on): the camera's orientation error in ego of
  the latest transform and of the transform at the image's stamp (where the buffer has stamps),
  against the kinematics at that stamp.

    .venv/bin/python bench/tf_buffer.py                       # the buffer in vizzy_runtime.tf
    git show <rev>:src/vizzy_runtime/vizzy_runtime/tf.py > /tmp/tf_old.py
    .venv/bin/python bench/tf_buffer.py --tf-module /tmp/tf_old.py     # another version of it

Prints a few lines, then one JSON object last.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import inspect
import json
import math
import sys
import time
import tracemalloc
from types import ModuleType
from typing import Any

import numpy as np

from vizzy_runtime.ros import message
from vizzy_vision.kinematics import (
    CAMERA_FRAMES,
    JOINT_NAMES,
    frames_in_base,
    joint_transforms,
    static_transforms,
    world_transform,
)

TransformStamped = message('geometry_msgs/msg/TransformStamped')
LEFT = CAMERA_FRAMES['left']
RIGHT = CAMERA_FRAMES['right']
TF_PERIOD_S = 0.01          # /tf at 100 Hz of sim time, as the simulator
PAN_RATE = 1.0              # rad/s: smooth pursuit at its fastest (issue 28)
LAG_S = 0.05                # exposure -> lookup


def load_tf(path: str | None) -> ModuleType:
    if path is None:
        import vizzy_runtime.tf as tf
        return tf
    spec = importlib.util.spec_from_file_location('tf_under_probe', path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def stamped(t: Any, stamp: float) -> Any:
    msg = TransformStamped(child_frame_id=t.child)
    msg.header.frame_id = t.parent
    msg.header.stamp.sec = int(math.floor(stamp))
    msg.header.stamp.nanosec = int(round((stamp - math.floor(stamp)) * 1e9)) % 1_000_000_000
    tr, q = msg.transform.translation, msg.transform.rotation
    tr.x, tr.y, tr.z = (float(v) for v in t.translation)
    q.x, q.y, q.z, q.w = (float(v) for v in t.rotation)
    return msg


class Feeder:
    """Feeds a buffer as TransformListener does, on either version of the API."""

    def __init__(self, tf: ModuleType) -> None:
        self.tf = tf
        params = inspect.signature(tf.TransformBuffer.set_transform_messages).parameters
        self.has_static = 'static' in params
        lookup = inspect.signature(tf.TransformBuffer.lookup_transform).parameters
        self.has_stamp = 'stamp' in lookup
        self.now = 0.0
        kwargs = {}
        if 'clock' in inspect.signature(tf.TransformBuffer).parameters:
            kwargs['clock'] = lambda: self.now       # the stream's own time, not the wall's
        self.buffer = tf.TransformBuffer(**kwargs)

    def send(self, transforms: list[Any], static: bool = False) -> str | None:
        """None, or the one-line error the listener would log."""
        try:
            if self.has_static:
                self.buffer.set_transform_messages(transforms, static=static)
            else:
                self.buffer.set_transform_messages(transforms)
        except (ValueError, LookupError) as exc:
            return f'{type(exc).__name__}: {exc}'
        return None

    def joints(self, t: float) -> None:
        self.now = t
        self.send([stamped(x, t) for x in joint_transforms(pan_joints(t))])

    def lookup(self, target: str, source: str, stamp: float | None = None) -> np.ndarray:
        if stamp is None:
            return np.asarray(self.buffer.lookup_transform(target, source))
        return np.asarray(self.buffer.lookup_transform(target, source, stamp))


def pan_joints(t: float) -> list[float]:
    """Neck pan at PAN_RATE from -0.4 rad (within the +-53 deg limit for 0.8 s), eyes verged."""
    q = dict.fromkeys(JOINT_NAMES, 0.0)
    q['neck_pan_joint'] = -0.4 + PAN_RATE * (t - 100.0)
    q['l_eye_joint'], q['r_eye_joint'] = -0.05, 0.05
    return [q[n] for n in JOINT_NAMES]


def true_ego_left(t: float) -> np.ndarray:
    poses = frames_in_base(pan_joints(t))
    return np.linalg.inv(poses['ego']) @ poses[LEFT]


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = (np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def cpu_ms_per_call(fn: Any, budget_s: float = 0.5, most: int = 20_000) -> float:
    fn()
    n, start = 0, time.process_time()
    while n < most and (n < 3 or time.process_time() - start < budget_s):
        fn()
        n += 1
    return 1e3 * (time.process_time() - start) / n


def fill_real(feeder: Feeder, until: float) -> float:
    """/tf_static once, then /tf at 100 Hz from t = 100 s to until; the last stamp."""
    feeder.send([stamped(x, 100.0) for x in [world_transform()] + static_transforms()],
                static=True)
    t = 100.0
    for k in range(int(round((until - 100.0) / TF_PERIOD_S)) + 1):
        t = 100.0 + k * TF_PERIOD_S
        feeder.joints(t)
    return t


def loop_probe(tf: ModuleType, out: dict[str, Any]) -> None:
    """A loop-closing foreign edge, on /tf and on /tf_static, each into a fresh real tree."""
    for topic, static in (('tf', False), ('tf_static', True)):
        feeder = Feeder(tf)
        newest = fill_real(feeder, 100.1)
        expected = feeder.lookup('ego', LEFT)
        loop = TransformStamped(child_frame_id='base_link')
        loop.header.frame_id = LEFT
        loop.header.stamp.sec = int(newest)
        loop.transform.rotation.w = 1.0
        error = feeder.send([loop], static=static)
        for k in range(1, 11):           # the real /tf goes on for 0.1 s
            feeder.joints(newest + k * TF_PERIOD_S)
            expected = true_ego_left(newest + k * TF_PERIOD_S)
        try:
            works = bool(np.allclose(feeder.lookup('ego', LEFT), expected, atol=1e-9))
            lookup_error = None
        except LookupError as exc:
            works, lookup_error = False, str(exc)[:160]
        out[f'loop_on_{topic}_lookup_works'] = works
        out[f'loop_on_{topic}_lookup_error'] = lookup_error
        out[f'loop_on_{topic}_refusal'] = error[:200] if error else None


def probe(tf: ModuleType, n_foreign: int, per_message: int) -> dict[str, Any]:
    out: dict[str, Any] = {'module': tf.__file__}
    feeder = Feeder(tf)
    out['lookup_at_stamp_supported'] = feeder.has_stamp

    # pan error: the image is stamped half-way between two /tf samples; when it is looked up
    # (LAG_S later) /tf has moved on
    newest = fill_real(feeder, 100.3)
    t_image = newest - LAG_S - TF_PERIOD_S / 2
    truth = true_ego_left(t_image)
    out['pan_rate_rad_s'], out['lag_s'] = PAN_RATE, LAG_S
    out['pan_error_latest_deg'] = round(angle_deg(feeder.lookup('ego', LEFT), truth), 4)
    if feeder.has_stamp:
        out['pan_error_at_stamp_deg'] = round(
            angle_deg(feeder.lookup('ego', LEFT, t_image), truth), 6)

    # lookups on the real tree only
    out['lookup_ms'] = round(cpu_ms_per_call(lambda: feeder.lookup('ego', LEFT)), 4)
    if feeder.has_stamp:
        out['lookup_at_stamp_ms'] = round(
            cpu_ms_per_call(lambda: feeder.lookup('ego', LEFT, t_image)), 4)

    # a stream of foreign frame names: n_foreign over 60 s of sim time, per_message a message
    gc.collect()
    tracemalloc.start()
    base, _ = tracemalloc.get_traced_memory()
    start_cpu = time.process_time()
    refusals = 0
    last_joints = -math.inf
    for i0 in range(0, n_foreign, per_message):
        t = newest + 60.0 * i0 / n_foreign
        feeder.now = t
        batch = []
        for i in range(i0, min(i0 + per_message, n_foreign)):
            msg = TransformStamped(child_frame_id=f'foreign_{i}')
            msg.header.frame_id = 'foreign_map'
            msg.header.stamp.sec = int(t)
            msg.transform.rotation.w = 1.0
            batch.append(msg)
        refusals += feeder.send(batch) is not None
        if t - last_joints >= TF_PERIOD_S - 1e-9:
            feeder.joints(t)             # the real head keeps publishing meanwhile, at 100 Hz
            last_joints = t
    stream_cpu = time.process_time() - start_cpu
    del batch
    gc.collect()
    grown, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    out['foreign_frames_streamed'] = n_foreign
    out['foreign_stream_cpu_us_per_frame'] = round(1e6 * stream_cpu / max(n_foreign, 1), 2)
    out['foreign_messages_refused'] = refusals
    out['foreign_memory_mb'] = round((grown - base) / 2 ** 20, 2)
    out['frames_kept'] = len(feeder.buffer.all_frames())
    out['lookup_after_foreign_ms'] = round(
        cpu_ms_per_call(lambda: feeder.lookup('ego', LEFT), budget_s=1.0, most=2000), 4)
    if feeder.has_stamp:
        last = feeder.now
        feeder.joints(last + TF_PERIOD_S)
        out['lookup_at_stamp_after_foreign_ms'] = round(cpu_ms_per_call(
            lambda: feeder.lookup('ego', LEFT, last + TF_PERIOD_S / 2), budget_s=1.0,
            most=2000), 4)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--tf-module', help='path of a tf.py to probe (default: vizzy_runtime.tf)')
    parser.add_argument('--foreign', type=int, default=300_000,
                        help='foreign frame names streamed (default 300000)')
    parser.add_argument('--per-message', type=int, default=50,
                        help='foreign transforms per TFMessage (default 50)')
    args = parser.parse_args(argv)
    tf = load_tf(args.tf_module)
    result = probe(tf, args.foreign, args.per_message)
    loop_probe(tf, result)
    for key, value in result.items():
        print(f'{key}: {value}', file=sys.stderr)
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())

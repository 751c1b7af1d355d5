"""The /tf path builds each message's matrices itself (issue 27: scipy's Rotation per message was
a third of a /tf sample's CPU): the same numbers and the same refusals as vizzy_vision.frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vizzy_runtime.tf import TransformBuffer, _pose_matrices
from vizzy_vision.frames import matrices_from_transforms


def test_pose_matrices_are_the_references() -> None:
    rng = np.random.default_rng(5)
    t = rng.normal(size=(200, 3))
    q = rng.normal(size=(200, 4)) * rng.uniform(1e-3, 1e3, size=(200, 1))   # unnormalized
    np.testing.assert_allclose(_pose_matrices(np.hstack([t, q])), matrices_from_transforms(t, q),
                               atol=2e-15)
    for bad, match in (([0, math.nan, 0, 0, 0, 0, 1], 'non-finite translation'),
                       ([0, 0, 0, 0, 0, 0, 0], 'invalid rotation'),
                       ([0, 0, 0, math.inf, 0, 0, 1], 'invalid rotation'),
                       ([0, 0, 0, 1e-10, 0, 0, 0], 'invalid rotation')):
        with pytest.raises(ValueError, match=match):
            _pose_matrices(np.array([bad], dtype=np.float64))


def test_messages_give_the_same_tree_as_matrices() -> None:
    from vizzy_runtime.ros import message
    TransformStamped = message('geometry_msgs/msg/TransformStamped')
    rng = np.random.default_rng(9)
    poses = np.hstack([rng.normal(size=(4, 3)), rng.normal(size=(4, 4))])
    frames = ['base', 'a', 'b', 'c', 'd']
    messages = []
    for i, pose in enumerate(poses):
        msg = TransformStamped(child_frame_id=frames[i + 1])
        msg.header.frame_id = frames[i]
        msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 250_000_000
        tr, rot = msg.transform.translation, msg.transform.rotation
        tr.x, tr.y, tr.z = pose[:3]
        rot.x, rot.y, rot.z, rot.w = pose[3:]
        messages.append(msg)
    from_messages, from_matrices = TransformBuffer(), TransformBuffer()
    from_messages.set_transform_messages(messages)
    from_matrices.set_transforms(frames[:-1], frames[1:],
                                 matrices_from_transforms(poses[:, :3], poses[:, 3:]),
                                 [3.25] * 4)
    for stamp in (None, 3.25):
        np.testing.assert_allclose(from_messages.lookup_transform('base', 'd', stamp),
                                   from_matrices.lookup_transform('base', 'd', stamp),
                                   atol=1e-14)

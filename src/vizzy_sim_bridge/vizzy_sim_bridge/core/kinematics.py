"""Approximate kinematic chain of the Vizzy head.

The numbers are approximate (neck tilt axis 0.370 m above base_link, eyes 0.102 m either side of
the head's midplane, camera centre 0.0275 m in front of each eye's rotation axis) until the
MuJoCo model replaces them. Frames follow REP 103: links are x forward, y left, z up; optical
frames are z forward, x right, y down.

base_link -> neck_pan_link (z, neck_pan_joint) -> neck_tilt_link (y, neck_tilt_joint)
 -> eyes_tilt_link (y, eyes_tilt_joint) -> {left,right}_eye_link (z, l_eye_joint / r_eye_joint)
 -> {left,right}_camera_optical_frame (fixed). Also fixed: base_link -> ego (head-centred,
world-fixed orientation; the thesis's frame E) and eyes_tilt_link -> cyclopean (baseline midpoint).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np

JOINT_NAMES: tuple[str, ...] = (
    'neck_pan_joint', 'neck_tilt_joint', 'eyes_tilt_joint', 'l_eye_joint', 'r_eye_joint')

# Approximate joint limits [rad].
JOINT_LIMITS: dict[str, tuple[float, float]] = {
    'neck_pan_joint': (-0.92, 0.92),
    'neck_tilt_joint': (-0.65, 0.58),
    'eyes_tilt_joint': (-0.60, 0.60),
    'l_eye_joint': (-0.60, 0.60),
    'r_eye_joint': (-0.60, 0.60),
}

NECK_PAN_HEIGHT = 0.30        # base_link -> neck pan axis [m]
NECK_TILT_ABOVE_PAN = 0.07    # neck pan -> neck tilt axis [m] (tilt axis 0.370 m above base)
EYES_ABOVE_NECK_TILT = 0.10   # neck tilt axis -> eyes tilt axis [m]
EYE_OFFSET = 0.102            # each eye's rotation axis from the midplane [m] (baseline 0.204 m)
CAMERA_FORWARD = 0.0275       # camera centre in front of the eye's rotation axis [m]

# Rotation from a REP 103 body frame (x fwd, y left, z up) to an optical frame
# (z fwd, x right, y down), as a quaternion (x, y, z, w): rpy = (-pi/2, 0, -pi/2).
OPTICAL_ROTATION: tuple[float, float, float, float] = (-0.5, 0.5, -0.5, 0.5)
IDENTITY: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)


class Transform(NamedTuple):
    """A parent -> child transform: translation [m] and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def quaternion_about(axis: str, angle: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation by angle [rad] about the 'x', 'y' or 'z' axis."""
    s, c = math.sin(angle / 2.0), math.cos(angle / 2.0)
    return {'x': (s, 0.0, 0.0, c), 'y': (0.0, s, 0.0, c), 'z': (0.0, 0.0, s, c)}[axis]


def joint_vector(positions: Mapping[str, float] | Sequence[float]) -> dict[str, float]:
    """Joint positions by name, from a mapping or a sequence in JOINT_NAMES order."""
    if isinstance(positions, Mapping):
        return {name: float(positions.get(name, 0.0)) for name in JOINT_NAMES}
    if len(positions) != len(JOINT_NAMES):
        raise ValueError(f'expected {len(JOINT_NAMES)} joint positions, got {len(positions)}')
    return {name: float(v) for name, v in zip(JOINT_NAMES, positions)}


def joint_transforms(positions: Mapping[str, float] | Sequence[float]) -> list[Transform]:
    """The transforms that move with the joints (published on /tf)."""
    q = joint_vector(positions)
    return [
        Transform('base_link', 'neck_pan_link', (0.0, 0.0, NECK_PAN_HEIGHT),
                  quaternion_about('z', q['neck_pan_joint'])),
        Transform('neck_pan_link', 'neck_tilt_link', (0.0, 0.0, NECK_TILT_ABOVE_PAN),
                  quaternion_about('y', q['neck_tilt_joint'])),
        Transform('neck_tilt_link', 'eyes_tilt_link', (0.0, 0.0, EYES_ABOVE_NECK_TILT),
                  quaternion_about('y', q['eyes_tilt_joint'])),
        Transform('eyes_tilt_link', 'left_eye_link', (0.0, EYE_OFFSET, 0.0),
                  quaternion_about('z', q['l_eye_joint'])),
        Transform('eyes_tilt_link', 'right_eye_link', (0.0, -EYE_OFFSET, 0.0),
                  quaternion_about('z', q['r_eye_joint'])),
    ]


def static_transforms() -> list[Transform]:
    """The fixed transforms (published once on /tf_static)."""
    return [
        Transform('left_eye_link', 'left_camera_optical_frame', (CAMERA_FORWARD, 0.0, 0.0),
                  OPTICAL_ROTATION),
        Transform('right_eye_link', 'right_camera_optical_frame', (CAMERA_FORWARD, 0.0, 0.0),
                  OPTICAL_ROTATION),
        Transform('base_link', 'ego', (0.0, 0.0, NECK_PAN_HEIGHT + NECK_TILT_ABOVE_PAN), IDENTITY),
        Transform('eyes_tilt_link', 'cyclopean', (0.0, 0.0, 0.0), IDENTITY),
    ]


def _matrix(t: Transform) -> np.ndarray:
    x, y, z, w = t.rotation
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = t.translation
    return m


def frames_in_base(positions: Mapping[str, float] | Sequence[float]) -> dict[str, np.ndarray]:
    """4x4 pose of every frame of the head in base_link, for the given joint positions."""
    poses = {'base_link': np.eye(4)}
    for t in joint_transforms(positions) + static_transforms():  # parents come first
        poses[t.child] = poses[t.parent] @ _matrix(t)
    return poses


def gaze_angles(positions: Mapping[str, float] | Sequence[float]) -> tuple[float, float, float]:
    """(version, vergence, tilt) [rad] as defined in active_vision_msgs/GazeState.

    The eye joints turn about +z (up): converging means l_eye < 0 < r_eye, so
    vergence = r_eye - l_eye and version = (l_eye + r_eye) / 2 (positive to the left).
    tilt = neck_tilt + eyes_tilt (about +y: positive looks down).
    """
    q = joint_vector(positions)
    return ((q['l_eye_joint'] + q['r_eye_joint']) / 2.0,
            q['r_eye_joint'] - q['l_eye_joint'],
            q['neck_tilt_joint'] + q['eyes_tilt_joint'])


def fixation_from_joints(positions: Mapping[str, float] | Sequence[float],
                         max_distance: float = 10.0) -> np.ndarray:
    """The point both optical axes look at, in base_link [m].

    The midpoint of the shortest segment between the two optical axes; when the axes do not
    converge in front of the cameras (parallel or diverging), the point max_distance ahead
    of the cameras' midpoint along the mean viewing direction.
    """
    poses = frames_in_base(positions)
    pl, pr = poses['left_camera_optical_frame'], poses['right_camera_optical_frame']
    ol, dl = pl[:3, 3], pl[:3, 2]   # optical axis = z
    orr, dr = pr[:3, 3], pr[:3, 2]
    w0 = ol - orr
    b = float(dl @ dr)
    denom = 1.0 - b * b
    if denom > 1e-12:
        d, e = float(dl @ w0), float(dr @ w0)
        s, t = (b * e - d) / denom, (e - b * d) / denom
        if 0.0 < s < max_distance and 0.0 < t < max_distance:
            return 0.5 * ((ol + s * dl) + (orr + t * dr))
    mean = dl + dr
    mean /= np.linalg.norm(mean)
    return 0.5 * (ol + orr) + max_distance * mean

"""Kinematic chain of the Vizzy head (the real robot's numbers), in REP 103 frames.

Sources (full table with every number in docs/vizzy_sim_bridge.md):

* [URDF] vislab-tecnico-lisboa/vizzy, vizzy_description/urdf/head/head.urdf.xacro: neck tilt
  axis 0.370 m above the neck pan origin (neck_tilt_joint origin); eyes tilt axis 0.12379 m in
  front of and 0.04755 m above the neck tilt axis (eyes_tilt_joint origin); eyes 0.102 m either
  side of eyes_center_link (l_eye_joint / r_eye_joint origins); camera 0.0275 m in front of each
  eye's rotation axis (l_camera_joint / r_camera_joint); velocity limit 5.0 rad/s on every head
  joint; ego_frame 0.370 m above the waist.
* [fKin] the real robot's kinematics, vizzy_yarp_icub vizzyFwd.cpp (iKin DH chain): the same
  chain (neck tilt 0.37 m above the waist, eyes tilt axis 0.13261 m from the neck tilt axis,
  eyes 0.1015 m either side, camera 0.0275 m ahead: HN) and the real-robot joint limits neck pan
  +-53 deg, neck tilt -18..37 deg, eyes tilt +-38 deg, eye pan +-38 deg.

Frames follow REP 103: links are x forward, y left, z up; optical frames are z forward, x right,
y down. base_link is the waist (the root of both sources); the neck pan axis passes through it.

    base_link -> neck_pan_link   (0, 0, 0),             about +z (neck_pan_joint)
      -> neck_tilt_link          (0, 0, 0.370),         about +y (neck_tilt_joint)
        -> eyes_tilt_link        (0.12379, 0, 0.04755), about +y (eyes_tilt_joint)
          -> left_eye_link       (0, +0.102, 0),        about +z (l_eye_joint)
            -> left_camera_optical_frame  (0.0275, 0, 0), fixed, optical rotation
          -> right_eye_link      (0, -0.102, 0),        about +z (r_eye_joint)
            -> right_camera_optical_frame (0.0275, 0, 0), fixed, optical rotation
          -> cyclopean           (0, 0, 0): midpoint of the eyes' rotation centres
        -> rgbd_camera_link      (RGBD_MOUNT), fixed: the head-mounted Xtion-like RGB-D sensor
          -> rgbd_camera_optical_frame (0, 0, 0), optical rotation
    base_link -> ego             (0, 0, 0.370), fixed: head-centred, world-fixed orientation

Joint signs (right-hand rule about the axes above, the convention of
active_vision_msgs/GazeState):

* neck_pan_joint, l_eye_joint, r_eye_joint: positive turns the gaze to the LEFT (about +z, up);
* neck_tilt_joint, eyes_tilt_joint: positive turns the gaze DOWN (about +y, left);
* version = (l_eye + r_eye) / 2 (positive left), vergence = r_eye - l_eye (positive converging),
  so l_eye = version - vergence / 2 and r_eye = version + vergence / 2 (eye_joints()).

The real robot's encoders count the other way for the pans and the neck tilt (its URDF and fKin
agree: positive neck pan and eye pan look right, positive neck tilt looks up, positive eyes tilt
looks down); there the coupling reads left = version + vergence / 2, right = version -
vergence / 2. ROBOT_SIGNS, to_robot_joints() and from_robot_joints() convert. The real-robot
neck tilt range -18..37 deg (37 deg up) is therefore [-37, +18] deg here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np

from .frames import quaternion_about, rotation_matrix

JOINT_NAMES: tuple[str, ...] = (
    'neck_pan_joint', 'neck_tilt_joint', 'eyes_tilt_joint', 'l_eye_joint', 'r_eye_joint')

# Joint limits [rad] in this module's signs, from the real robot's fKin limits.
JOINT_LIMITS: dict[str, tuple[float, float]] = {
    'neck_pan_joint': (math.radians(-53.0), math.radians(53.0)),
    'neck_tilt_joint': (math.radians(-37.0), math.radians(18.0)),   # 37 deg up, 18 deg down
    'eyes_tilt_joint': (math.radians(-38.0), math.radians(38.0)),
    'l_eye_joint': (math.radians(-38.0), math.radians(38.0)),
    'r_eye_joint': (math.radians(-38.0), math.radians(38.0)),
}

# Velocity limit of every head joint [rad/s] (URDF: velocity="5.0").
VELOCITY_LIMIT = 5.0
VELOCITY_LIMITS: dict[str, float] = {name: VELOCITY_LIMIT for name in JOINT_NAMES}

# Multiply one of our joint positions by this to get the real robot's (and back).
ROBOT_SIGNS: dict[str, float] = {
    'neck_pan_joint': -1.0, 'neck_tilt_joint': -1.0, 'eyes_tilt_joint': 1.0,
    'l_eye_joint': -1.0, 'r_eye_joint': -1.0,
}

NECK_PAN_HEIGHT = 0.0         # base_link (waist) -> neck pan axis origin [m] (URDF: 0)
NECK_TILT_ABOVE_PAN = 0.370   # neck pan origin -> neck tilt axis [m] (URDF, fKin)
EYES_TILT_FORWARD = 0.12379   # neck tilt axis -> eyes tilt axis, forward [m] (URDF)
EYES_TILT_UP = 0.04755        # neck tilt axis -> eyes tilt axis, up [m] (URDF)
EYES_ABOVE_NECK_TILT = EYES_TILT_UP  # kept for older callers
EYE_OFFSET = 0.102            # each eye's rotation axis from the midplane [m] (URDF)
BASELINE = 2.0 * EYE_OFFSET   # 0.204 m between the eyes' rotation axes (fKin: 0.203 m)
CAMERA_FORWARD = 0.0275       # camera centre in front of the eye's rotation axis [m] (URDF, fKin)
EGO_HEIGHT = NECK_PAN_HEIGHT + NECK_TILT_ABOVE_PAN  # ego frame above base_link [m] (URDF ego_joint)
# base_link (the waist) above the floor [m]: vizzy_description torso.urdf.xacro waist_joint origin
# z (base_link on the ground: base_footprint_joint), also fKin's H0 for root "base_link".
WAIST_HEIGHT = 0.535797

# The head-mounted RGB-D sensor (Asus Xtion-like; the thesis's cylinder experiments used one).
# Mounted on the forehead, above the eyes, on neck_tilt_link (it moves with the neck, not the
# eyes), pitched down by RGBD_PITCH so a table in front of the robot is in view. Our choice:
# neither source describes a head-mounted depth sensor.
RGBD_MOUNT = (0.10, 0.0, 0.13)   # in neck_tilt_link [m]
RGBD_PITCH = math.radians(20.0)  # about +y: positive looks down [rad]

# Rotation from a REP 103 body frame (x fwd, y left, z up) to an optical frame
# (z fwd, x right, y down), as a quaternion (x, y, z, w): rpy = (-pi/2, 0, -pi/2).
OPTICAL_ROTATION: tuple[float, float, float, float] = (-0.5, 0.5, -0.5, 0.5)
IDENTITY: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)

CAMERA_FRAMES: dict[str, str] = {'left': 'left_camera_optical_frame',
                                 'right': 'right_camera_optical_frame'}
RGBD_FRAME = 'rgbd_camera_optical_frame'

# Every frame of the head, parents before children.
FRAME_NAMES: tuple[str, ...] = (
    'base_link', 'neck_pan_link', 'neck_tilt_link', 'eyes_tilt_link', 'left_eye_link',
    'right_eye_link', 'left_camera_optical_frame', 'right_camera_optical_frame', 'ego',
    'cyclopean', 'rgbd_camera_link', 'rgbd_camera_optical_frame')


class Transform(NamedTuple):
    """A parent -> child transform: translation [m] and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def joint_vector(positions: Mapping[str, float] | Sequence[float]) -> dict[str, float]:
    """Joint positions by name, from a mapping (missing joints: 0) or a sequence in JOINT_NAMES
    order."""
    if isinstance(positions, Mapping):
        return {name: float(positions.get(name, 0.0)) for name in JOINT_NAMES}
    if len(positions) != len(JOINT_NAMES):
        raise ValueError(f'expected {len(JOINT_NAMES)} joint positions, got {len(positions)}')
    return {name: float(v) for name, v in zip(JOINT_NAMES, positions, strict=True)}


def joint_transforms(positions: Mapping[str, float] | Sequence[float]) -> list[Transform]:
    """The transforms that move with the joints (published on /tf)."""
    q = joint_vector(positions)
    return [
        Transform('base_link', 'neck_pan_link', (0.0, 0.0, NECK_PAN_HEIGHT),
                  quaternion_about('z', q['neck_pan_joint'])),
        Transform('neck_pan_link', 'neck_tilt_link', (0.0, 0.0, NECK_TILT_ABOVE_PAN),
                  quaternion_about('y', q['neck_tilt_joint'])),
        Transform('neck_tilt_link', 'eyes_tilt_link', (EYES_TILT_FORWARD, 0.0, EYES_TILT_UP),
                  quaternion_about('y', q['eyes_tilt_joint'])),
        Transform('eyes_tilt_link', 'left_eye_link', (0.0, EYE_OFFSET, 0.0),
                  quaternion_about('z', q['l_eye_joint'])),
        Transform('eyes_tilt_link', 'right_eye_link', (0.0, -EYE_OFFSET, 0.0),
                  quaternion_about('z', q['r_eye_joint'])),
    ]


def static_transforms() -> list[Transform]:
    """The fixed transforms (published once on /tf_static), parents before children."""
    return [
        Transform('left_eye_link', 'left_camera_optical_frame', (CAMERA_FORWARD, 0.0, 0.0),
                  OPTICAL_ROTATION),
        Transform('right_eye_link', 'right_camera_optical_frame', (CAMERA_FORWARD, 0.0, 0.0),
                  OPTICAL_ROTATION),
        Transform('base_link', 'ego', (0.0, 0.0, EGO_HEIGHT), IDENTITY),
        Transform('eyes_tilt_link', 'cyclopean', (0.0, 0.0, 0.0), IDENTITY),
        Transform('neck_tilt_link', 'rgbd_camera_link', RGBD_MOUNT,
                  quaternion_about('y', RGBD_PITCH)),
        Transform('rgbd_camera_link', 'rgbd_camera_optical_frame', (0.0, 0.0, 0.0),
                  OPTICAL_ROTATION),
    ]


def world_transform() -> Transform:
    """world -> base_link (fixed, on /tf_static): the simulator's world, the floor under the
    waist; the robot's own description starts at base_link."""
    return Transform('world', 'base_link', (0.0, 0.0, WAIST_HEIGHT), IDENTITY)


def transform_matrix(t: Transform) -> np.ndarray:
    """4x4 homogeneous matrix of a Transform (child pose in the parent frame)."""
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(t.rotation)
    m[:3, 3] = t.translation
    return m


_matrix = transform_matrix  # older name


def frames_in_base(positions: Mapping[str, float] | Sequence[float]) -> dict[str, np.ndarray]:
    """4x4 pose of every frame of the head (FRAME_NAMES) in base_link, for the given joints."""
    poses = {'base_link': np.eye(4)}
    transforms = joint_transforms(positions) + static_transforms()
    pending = list(transforms)
    while pending:  # parents first, whatever the list order
        rest = []
        for t in pending:
            if t.parent in poses:
                poses[t.child] = poses[t.parent] @ transform_matrix(t)
            else:
                rest.append(t)
        if len(rest) == len(pending):
            raise RuntimeError(f'frames without a parent chain: {[t.child for t in rest]}')
        pending = rest
    return poses


def camera_poses(positions: Mapping[str, float] | Sequence[float]) -> dict[str, np.ndarray]:
    """{'left': T, 'right': T}: 4x4 pose of each camera's optical frame in base_link.

    Column 3 is the optical centre, column 2 (z) the optical axis, column 0 (x) image right,
    column 1 (y) image down. For inverse kinematics: a point p (base_link) projects through
    CameraInfo K at K @ (inv(T) @ [p, 1])[:3].
    """
    poses = frames_in_base(positions)
    return {eye: poses[frame] for eye, frame in CAMERA_FRAMES.items()}


def eye_joints(version: float, vergence: float) -> tuple[float, float]:
    """(l_eye_joint, r_eye_joint) [rad] for a version and vergence [rad] (inverse of
    gaze_angles)."""
    return version - vergence / 2.0, version + vergence / 2.0


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


def clamp_to_limits(positions: Mapping[str, float]) -> tuple[dict[str, float], list[str]]:
    """Joint positions clamped into JOINT_LIMITS, and one line per clamped joint.

    Names must be in JOINT_NAMES (KeyError otherwise).
    """
    clamped, notes = {}, []
    for name, value in positions.items():
        lo, hi = JOINT_LIMITS[name]
        v = min(max(float(value), lo), hi)
        if v != float(value):
            notes.append(f'{name} target {float(value):.4f} rad outside [{lo:.4f}, {hi:.4f}] '
                         f'rad, clamped to {v:.4f}')
        clamped[name] = v
    return clamped, notes


def to_robot_joints(positions: Mapping[str, float] | Sequence[float]) -> dict[str, float]:
    """Our joint positions in the real Vizzy's encoder signs (URDF / fKin)."""
    q = joint_vector(positions)
    return {name: ROBOT_SIGNS[name] * v for name, v in q.items()}


def from_robot_joints(positions: Mapping[str, float] | Sequence[float]) -> dict[str, float]:
    """The real Vizzy's joint positions (URDF / fKin signs) in this module's signs."""
    return to_robot_joints(positions)  # each sign is its own inverse


def fixation_from_joints(positions: Mapping[str, float] | Sequence[float],
                         max_distance: float = 10.0) -> np.ndarray:
    """The point both optical axes look at, in base_link [m].

    The midpoint of the shortest segment between the two optical axes; when the axes do not
    converge in front of the cameras (parallel or diverging), the point max_distance ahead
    of the cameras' midpoint along the mean viewing direction.
    """
    poses = camera_poses(positions)
    pl, pr = poses['left'], poses['right']
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

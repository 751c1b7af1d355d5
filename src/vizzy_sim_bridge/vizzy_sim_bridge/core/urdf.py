"""URDF of the Vizzy head, generated from the description the simulator uses (no second copy).

Where each part comes from:

* the tree, the frame names and every origin: kinematics.joint_transforms() at the zero posture
  and kinematics.static_transforms(), the functions whose output the sim publishes on /tf and
  /tf_static. A link per frame (kinematics.FRAME_NAMES), a joint per transform: the five
  revolute joints keep kinematics' names, a fixed one is named `<child>_joint`;
* which joint moves which link, and its axis: found by moving each joint of
  kinematics.JOINT_NAMES alone in joint_transforms() (the transform whose rotation changes is
  that joint's; axis = the rotation between the two postures, in the child's frame);
* limits: kinematics.JOINT_LIMITS and VELOCITY_LIMITS;
* visual geometry and inertials: the compiled MuJoCo model of model.py (itself built from
  kinematics.py), the robot's geoms (group ROBOT_GROUP) and bodies. URDF has no capsule or
  ellipsoid (urdfdom of Jazzy): a capsule becomes a cylinder and two spheres, an ellipsoid the
  sphere of the same volume.

REP 103/105: links x forward, y left, z up; the optical frames z forward, x right, y down, as
on /tf. The root is base_link (the waist); with world=True the sim's fixed world -> base_link
(kinematics.world_transform(), on /tf_static) is included as well, as `world_joint`.

Not in the model: joint effort limits. The simulated servos are not torque-limited but URDF
requires the attribute (and some consumers treat 0 as "cannot move"), so every revolute joint
gets EFFORT_LIMIT.
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np

from vizzy_vision.frames import (
    from_wxyz,
    quaternion_conjugate,
    quaternion_multiply,
    rotation_matrix,
)
from vizzy_vision.kinematics import (
    FRAME_NAMES,
    JOINT_LIMITS,
    JOINT_NAMES,
    VELOCITY_LIMITS,
    Transform,
    joint_transforms,
    static_transforms,
    world_transform,
)

from .model import ROBOT_GROUP, compile_model

ROBOT_NAME = 'vizzy_head'
EFFORT_LIMIT = 10.0   # [N m], placeholder: see the module docstring
_PROBE_ANGLE = 1.0    # [rad]: each joint is moved by this to find its link and axis
_ZERO = 1e-15         # values smaller than this are written as 0
VISUAL_DIGITS = 9     # significant digits of visual and inertial numbers (origins: exact)


class JointSpec(NamedTuple):
    """One URDF joint: origin = the child's pose in the parent at the zero posture."""

    name: str
    kind: str                                   # 'revolute' or 'fixed'
    parent: str
    child: str
    xyz: tuple[float, float, float]             # [m]
    rpy: tuple[float, float, float]             # [rad], URDF roll-pitch-yaw
    axis: tuple[float, float, float] | None     # unit, in the child frame; None when fixed


def matrix_to_rpy(r: np.ndarray) -> tuple[float, float, float]:
    """URDF (roll, pitch, yaw) [rad] of a 3x3 rotation: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r = np.asarray(r, dtype=np.float64)
    cos_pitch = math.hypot(r[0, 0], r[1, 0])
    pitch = math.atan2(-r[2, 0], cos_pitch)   # precise near +-pi/2, unlike asin
    if cos_pitch > 1e-9:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock (pitch = +-pi/2): put the whole turn about x
        roll = math.atan2(-r[1, 2], r[1, 1])
        yaw = 0.0
    return roll, pitch, yaw


def _joint_of(name: str, at_zero: list[Transform]) -> tuple[int, tuple[float, float, float]]:
    """(index into joint_transforms(), unit axis in the child frame) of joint name."""
    moved = joint_transforms({name: _PROBE_ANGLE})
    changed = [i for i, (a, b) in enumerate(zip(at_zero, moved, strict=True))
               if not np.allclose(a.rotation, b.rotation, rtol=0.0, atol=1e-12)]
    if len(changed) != 1:
        raise RuntimeError(f'{name} moves {len(changed)} transforms of joint_transforms(), '
                           'expected exactly one')
    i = changed[0]
    if not np.allclose(at_zero[i].translation, moved[i].translation, rtol=0.0, atol=1e-12):
        raise RuntimeError(f'{name} translates its child: not a revolute joint')
    rel = quaternion_multiply(quaternion_conjugate(at_zero[i].rotation), moved[i].rotation)
    if rel[3] < 0.0:
        rel = (-rel[0], -rel[1], -rel[2], -rel[3])
    axis = np.asarray(rel[:3]) / math.sin(_PROBE_ANGLE / 2.0)
    axis /= np.linalg.norm(axis)
    return i, (float(axis[0]), float(axis[1]), float(axis[2]))


def joint_specs(world: bool = False) -> list[JointSpec]:
    """Every joint of the URDF, parents before children, from kinematics' /tf functions."""
    at_zero = joint_transforms({})
    revolute: dict[int, tuple[str, tuple[float, float, float]]] = {}
    for name in JOINT_NAMES:
        i, axis = _joint_of(name, at_zero)
        if i in revolute:
            raise RuntimeError(f'{name} and {revolute[i][0]} move the same transform')
        revolute[i] = (name, axis)

    def spec(t: Transform, name: str, axis: tuple[float, float, float] | None) -> JointSpec:
        x, y, z = t.translation
        return JointSpec(name, 'fixed' if axis is None else 'revolute', t.parent, t.child,
                         (float(x), float(y), float(z)),
                         matrix_to_rpy(rotation_matrix(t.rotation)), axis)

    specs = [spec(world_transform(), 'world_joint', None)] if world else []
    specs += [spec(t, *revolute.get(k, (f'{t.child}_joint', None)))
              for k, t in enumerate(at_zero)]
    specs += [spec(t, f'{t.child}_joint', None) for t in static_transforms()]
    done, ordered, pending = {specs[0].parent}, [], specs
    while pending:  # parents before children, whatever the order of the lists
        ready = [s for s in pending if s.parent in done]
        if not ready:
            raise RuntimeError(f'frames without a parent chain: {[s.child for s in pending]}')
        ordered += ready
        done.update(s.child for s in ready)
        pending = [s for s in pending if s not in ready]
    return ordered


def _num(v: float, digits: int | None = None) -> str:
    """v exactly (shortest repr that reads back the same float), or to digits significant
    digits; -0, 1e-17 and the like as 0, 1.0 as 1."""
    v = float(v)
    if abs(v) < _ZERO:
        return '0'
    if digits is not None:
        v = float(f'{v:.{digits}g}')
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def _nums(values: Sequence[float] | np.ndarray, digits: int | None = None) -> str:
    return ' '.join(_num(v, digits) for v in values)


def _origin(parent: ET.Element, xyz: Sequence[float] | np.ndarray, rpy: Sequence[float],
            digits: int | None = None) -> None:
    ET.SubElement(parent, 'origin', xyz=_nums(xyz, digits), rpy=_nums(rpy, digits))


def _visuals(model: mujoco.MjModel, body: int, materials: dict[str, str]) -> list[ET.Element]:
    """URDF <visual> elements of the robot geoms of one MuJoCo body (frame = the link's)."""
    out = []
    g = mujoco.mjtGeom
    for i in np.flatnonzero((model.geom_bodyid == body) & (model.geom_group == ROBOT_GROUP)):
        kind, size = int(model.geom_type[i]), model.geom_size[i].astype(np.float64)
        pos = model.geom_pos[i].astype(np.float64)
        rot = rotation_matrix(from_wxyz(model.geom_quat[i]))
        parts: list[tuple[np.ndarray, str, dict[str, str]]] = []
        d = VISUAL_DIGITS
        radius = _num(size[0], d)
        if kind == g.mjGEOM_SPHERE:
            parts.append((pos, 'sphere', {'radius': radius}))
        elif kind == g.mjGEOM_BOX:
            parts.append((pos, 'box', {'size': _nums(2.0 * size, d)}))
        elif kind == g.mjGEOM_CYLINDER:
            parts.append((pos, 'cylinder', {'radius': radius, 'length': _num(2 * size[1], d)}))
        elif kind == g.mjGEOM_CAPSULE:
            parts.append((pos, 'cylinder', {'radius': radius, 'length': _num(2 * size[1], d)}))
            for sign in (-1.0, 1.0):
                parts.append((pos + sign * size[1] * rot[:, 2], 'sphere', {'radius': radius}))
        elif kind == g.mjGEOM_ELLIPSOID:
            parts.append((pos, 'sphere', {'radius': _num(float(np.prod(size)) ** (1 / 3), d)}))
        else:
            continue   # planes, meshes, height fields: none on the head
        rgba = _nums(model.geom_rgba[i], 4)
        material = materials.setdefault(rgba, f'vizzy_color_{len(materials)}')
        for center, shape, attrib in parts:
            visual = ET.Element('visual')
            _origin(visual, center, matrix_to_rpy(rot), d)
            ET.SubElement(ET.SubElement(visual, 'geometry'), shape, attrib)
            ET.SubElement(visual, 'material', name=material)
            out.append(visual)
    return out


def _inertial(model: mujoco.MjModel, body: int) -> ET.Element:
    inertial = ET.Element('inertial')
    d = VISUAL_DIGITS
    _origin(inertial, model.body_ipos[body],
            matrix_to_rpy(rotation_matrix(from_wxyz(model.body_iquat[body]))), d)
    ET.SubElement(inertial, 'mass', value=_num(model.body_mass[body], d))
    ixx, iyy, izz = (_num(v, d) for v in model.body_inertia[body])
    ET.SubElement(inertial, 'inertia', ixx=ixx, ixy='0', ixz='0', iyy=iyy, iyz='0', izz=izz)
    return inertial


def head_urdf_element(world: bool = False) -> ET.Element:
    """The <robot> element (see head_urdf)."""
    model, _ = compile_model(None)
    specs = joint_specs(world)
    robot = ET.Element('robot', name=ROBOT_NAME)
    materials: dict[str, str] = {}
    links = [specs[0].parent] + [s.child for s in specs]
    link_elements = []
    for name in links:
        link = ET.Element('link', name=name)
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body > 0:
            link.extend(_visuals(model, body, materials))
            # the root is welded to the world in MuJoCo, its mass an artefact of geom density
            if name != 'base_link' and model.body_mass[body] > 0.0:
                link.append(_inertial(model, body))
        link_elements.append(link)
    for rgba, name in materials.items():
        ET.SubElement(ET.SubElement(robot, 'material', name=name), 'color', rgba=rgba)
    robot.extend(link_elements)
    for s in specs:
        joint = ET.SubElement(robot, 'joint', name=s.name, type=s.kind)
        ET.SubElement(joint, 'parent', link=s.parent)
        ET.SubElement(joint, 'child', link=s.child)
        _origin(joint, s.xyz, s.rpy)
        if s.axis is not None:
            ET.SubElement(joint, 'axis', xyz=_nums(s.axis))
            lo, hi = JOINT_LIMITS[s.name]
            ET.SubElement(joint, 'limit', lower=_num(lo), upper=_num(hi),
                          effort=_num(EFFORT_LIMIT), velocity=_num(VELOCITY_LIMITS[s.name]))
    missing = set(FRAME_NAMES) - set(links)
    if missing:
        raise RuntimeError(f'frames of kinematics.FRAME_NAMES not in the URDF: {sorted(missing)}')
    return robot


@functools.lru_cache(maxsize=2)
def head_urdf(world: bool = False) -> str:
    """The head's URDF as an XML string (what robot_description carries).

    world: include the simulator's world -> base_link joint (root `world`), else the root is
    base_link.
    """
    robot = head_urdf_element(world)
    ET.indent(robot, space='  ')
    return ('<?xml version="1.0"?>\n<!-- Generated by vizzy_sim_bridge.core.urdf from '
            'core/kinematics.py and the MuJoCo model; do not edit. -->\n'
            + ET.tostring(robot, encoding='unicode') + '\n')


__all__ = ['EFFORT_LIMIT', 'JointSpec', 'ROBOT_NAME', 'head_urdf', 'head_urdf_element',
           'joint_specs', 'matrix_to_rpy']

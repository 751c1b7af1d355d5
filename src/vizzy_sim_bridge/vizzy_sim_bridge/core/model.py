"""MuJoCo model of the Vizzy head (primitives only) and its real-time physics.

build_mjcf() writes the MJCF: the head's bodies, joints and frames exactly as kinematics.py
(a test checks MuJoCo's body, site and camera poses against frames_in_base within 1e-6), two
eye cameras at the optical frames, the head-mounted RGB-D camera, and the scene's assets and
bodies. HeadSimulation steps it at 500 Hz in its own thread, following wall time.

Joint dynamics: each joint is driven by a MuJoCo position actuator (a PD servo,
torque = kp (ctrl - q) - kv qdot) whose reference ctrl moves toward the commanded target at no
more than the velocity limit (5 rad/s, a trapezoid-free rate limiter run every physics step).
kp and kv give each joint a critically damped response (damping ratio 1) of natural frequency
omega, computed from the joint-space inertia at home posture (link inertia + armature, the
motor's reflected inertia): kp = I omega^2, kv = 2 I omega. Gravity is compensated on the head
(gravcomp), so a joint settles exactly on its target. With these numbers a 20 deg eye saccade
takes about 90 ms to settle within 0.1 deg (70 ms at 5 rad/s plus the servo's lag), a 20 deg
neck pan about 130 ms; see docs/vizzy_sim_bridge.md for the measured figures.
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from vizzy_vision.camera import (
    EYE_HEIGHT,
    EYE_HFOV_DEG,
    EYE_WIDTH,
    RGBD_HEIGHT,
    RGBD_HFOV_DEG,
    RGBD_WIDTH,
    fovy_deg,
)
from vizzy_vision.frames import quaternion_about, to_wxyz
from vizzy_vision.kinematics import (
    CAMERA_FORWARD,
    EGO_HEIGHT,
    EYE_OFFSET,
    EYES_TILT_FORWARD,
    EYES_TILT_UP,
    JOINT_LIMITS,
    JOINT_NAMES,
    NECK_PAN_HEIGHT,
    NECK_TILT_ABOVE_PAN,
    OPTICAL_ROTATION,
    RGBD_MOUNT,
    RGBD_PITCH,
    VELOCITY_LIMITS,
    WAIST_HEIGHT,
    clamp_to_limits,
)

from .scenes import Scene

TIMESTEP = 0.002   # [s]: physics at 500 Hz
ROBOT_GROUP = 3    # geom group of the robot's own body: hidden from its cameras
SITE_GROUP = 5     # frames as sites, never drawn

# Per joint: (armature [kg m^2], natural frequency omega [rad/s]) of the servo; damping ratio 1.
SERVO: dict[str, tuple[float, float]] = {
    'neck_pan_joint': (0.02, 60.0),
    'neck_tilt_joint': (0.02, 60.0),
    'eyes_tilt_joint': (0.005, 120.0),
    'l_eye_joint': (0.002, 200.0),
    'r_eye_joint': (0.002, 200.0),
}
DAMPING_RATIO = 1.0

# Link masses [kg] from vizzy_description's (older) head URDF inertials (M1..M4 meshes); the
# inertia tensors here are diagonal approximations of the same order.
MASSES = {'neck_pan_link': 0.223, 'neck_tilt_link': 0.298, 'eyes_tilt_link': 0.229,
          'eye': 0.1585, 'rgbd': 0.200}


def _f(*values: float) -> str:
    return ' '.join(f'{float(v):.9g}' for v in values)


def _mj_quat(q: tuple[float, float, float, float]) -> str:
    """MJCF quat attribute (w x y z) of a quaternion (x, y, z, w)."""
    return _f(*to_wxyz(q))


# MuJoCo cameras look along their -z with y up; the optical frame looks along +z with y down:
# in the parent (REP 103 link) frame the camera's x axis is image right (-y) and its y axis is
# image up (+z).
CAMERA_XYAXES = '0 -1 0 0 0 1'


def _camera(name: str, pos: tuple[float, float, float], fovy: float) -> str:
    return f'<camera name="{name}" pos="{_f(*pos)}" xyaxes="{CAMERA_XYAXES}" fovy="{fovy:.9g}"/>'


def _site(name: str, pos: tuple[float, float, float],
          quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)) -> str:
    return (f'<site name="{name}" pos="{_f(*pos)}" quat="{_mj_quat(quat)}" size="0.005" '
            f'group="{SITE_GROUP}"/>')


def _geom(spec: str, rgba: str = '0.85 0.86 0.88 1') -> str:
    return f'<geom {spec} rgba="{rgba}" group="{ROBOT_GROUP}"/>'


def _joint(name: str, axis: str, armature: float) -> str:
    lo, hi = JOINT_LIMITS[name]
    return (f'<joint name="{name}" type="hinge" axis="{axis}" range="{_f(lo, hi)}" '
            f'armature="{armature:.9g}" damping="0"/>')


def head_xml(gains: Mapping[str, tuple[float, float]] | None = None, *,
             eye_fovy: float, rgbd_fovy: float) -> tuple[str, str]:
    """(worldbody XML, actuator XML) of the robot; gains {joint: (kp, kv)} (placeholder if None)."""
    arm = {name: SERVO[name][0] for name in JOINT_NAMES}
    eye_body = ''.join([
        _geom('type="sphere" size="0.022"', '0.95 0.95 0.95 1'),
        _geom('type="cylinder" pos="0.019 0 0" quat="0.7071068 0 0.7071068 0" size="0.009 0.004"',
              '0.05 0.05 0.05 1'),
    ])
    eye_inertial = (f'<inertial pos="0 0 0" mass="{MASSES["eye"]}" '
                    f'diaginertia="1.5e-4 1.5e-4 1.5e-4"/>')
    tilt_inertial = (f'<inertial pos="0.03 0 0.03" mass="{MASSES["neck_tilt_link"]}" '
                     f'diaginertia="8.5e-4 8.2e-4 3.0e-4"/>')
    eyes_bar = _geom(f'type="capsule" fromto="-0.01 {-EYE_OFFSET + 0.03:.9g} -0.025 '
                     f'-0.01 {EYE_OFFSET - 0.03:.9g} -0.025" size="0.008"', '0.2 0.2 0.2 1')
    opt = OPTICAL_ROTATION

    def eye(side: str, joint: str, y: float) -> str:
        return (f'<body name="{side}_eye_link" pos="{_f(0, y, 0)}" gravcomp="1">'
                f'{_joint(joint, "0 0 1", arm[joint])}{eye_inertial}{eye_body}'
                f'{_site(f"{side}_camera_optical_frame", (CAMERA_FORWARD, 0.0, 0.0), opt)}'
                f'{_camera(f"{side}_camera", (CAMERA_FORWARD, 0.0, 0.0), eye_fovy)}</body>')

    rgbd_q = quaternion_about('y', RGBD_PITCH)
    worldbody = f"""
<body name="base_link" pos="0 0 {WAIST_HEIGHT:.9g}">
  {_geom('type="box" pos="-0.02 0 -0.22" size="0.11 0.17 0.22"')}
  {_geom('type="capsule" fromto="-0.02 -0.2 0.02 -0.02 0.2 0.02" size="0.06"')}
  {_site('ego', (0.0, 0.0, EGO_HEIGHT))}
  <body name="neck_pan_link" pos="0 0 {NECK_PAN_HEIGHT:.9g}" gravcomp="1">
    {_joint('neck_pan_joint', '0 0 1', arm['neck_pan_joint'])}
    <inertial pos="0 0 0.2" mass="{MASSES['neck_pan_link']}" diaginertia="3.6e-4 3.7e-4 8.6e-5"/>
    {_geom('type="cylinder" pos="0 0 0.2" size="0.03 0.17"')}
    <body name="neck_tilt_link" pos="0 0 {NECK_TILT_ABOVE_PAN:.9g}" gravcomp="1">
      {_joint('neck_tilt_joint', '0 1 0', arm['neck_tilt_joint'])}
      {tilt_inertial}
      {_geom('type="ellipsoid" pos="0.02 0 0.06" size="0.09 0.13 0.11"')}
      <body name="rgbd_camera_link" pos="{_f(*RGBD_MOUNT)}" quat="{_mj_quat(rgbd_q)}" gravcomp="1">
        <inertial pos="0 0 0" mass="{MASSES['rgbd']}" diaginertia="5.8e-4 3.1e-5 5.9e-4"/>
        {_geom('type="box" size="0.0175 0.0925 0.0125"', '0.1 0.1 0.1 1')}
        {_site('rgbd_camera_optical_frame', (0.0, 0.0, 0.0), opt)}
        {_camera('rgbd_camera', (0.0, 0.0, 0.0), rgbd_fovy)}
      </body>
      <body name="eyes_tilt_link" pos="{_f(EYES_TILT_FORWARD, 0.0, EYES_TILT_UP)}" gravcomp="1">
        {_joint('eyes_tilt_joint', '0 1 0', arm['eyes_tilt_joint'])}
        <inertial pos="0 0 0" mass="{MASSES['eyes_tilt_link']}" diaginertia="1.3e-3 1.3e-4 1.3e-3"/>
        {eyes_bar}
        {_site('cyclopean', (0.0, 0.0, 0.0))}
        {eye('left', 'l_eye_joint', EYE_OFFSET)}
        {eye('right', 'r_eye_joint', -EYE_OFFSET)}
      </body>
    </body>
  </body>
</body>"""
    actuators = []
    for name in JOINT_NAMES:
        kp, kv = (gains or {}).get(name, (1.0, 0.1))
        lo, hi = JOINT_LIMITS[name]
        actuators.append(f'<position name="{name}" joint="{name}" kp="{kp:.9g}" kv="{kv:.9g}" '
                         f'ctrlrange="{_f(lo, hi)}"/>')
    return worldbody, '\n'.join(actuators)


def _mjcf(worldbody_robot: str, actuators: str, scene: Scene | None, offwidth: int,
          offheight: int) -> str:
    scene_assets = scene.assets_xml if scene else ''
    scene_body = scene.worldbody_xml if scene else ''
    sun = ('<light name="sun" directional="true" pos="0 0 6" dir="0.25 0.15 -1" '
           'diffuse="0.55 0.55 0.55" specular="0.1 0.1 0.1" castshadow="false"/>')
    return f"""<mujoco model="vizzy_head{'_' + scene.name if scene else ''}">
<compiler angle="radian" autolimits="true"/>
<option timestep="{TIMESTEP}" integrator="implicitfast">
  <flag contact="disable"/>
</option>
<statistic extent="1" center="1 0 0.8"/>
<visual>
  <global offwidth="{offwidth}" offheight="{offheight}"/>
  <quality shadowsize="0" offsamples="0" numslices="20" numstacks="10"/>
  <map znear="0.01" zfar="60"/>
  <headlight ambient="0.35 0.35 0.35" diffuse="0.45 0.45 0.45" specular="0.05 0.05 0.05"/>
</visual>
<asset>
{scene_assets}
</asset>
<worldbody>
{sun}
{worldbody_robot}
{scene_body}
</worldbody>
<actuator>
{actuators}
</actuator>
</mujoco>
"""


@functools.lru_cache(maxsize=4)
def servo_gains(eye_fovy: float = 60.0, rgbd_fovy: float = 45.0) -> dict[str, tuple[float, float]]:
    """{joint: (kp, kv)} for critically damped servos of SERVO's natural frequencies.

    The inertia each joint sees (dof_M0: link inertias + armature, at home posture) comes from
    compiling the robot alone.
    """
    body, act = head_xml(eye_fovy=eye_fovy, rgbd_fovy=rgbd_fovy)
    model = mujoco.MjModel.from_xml_string(_mjcf(body, act, None, 64, 48))
    gains = {}
    for name in JOINT_NAMES:
        dof = model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)]
        inertia = float(model.dof_M0[dof])
        omega = SERVO[name][1]
        gains[name] = (inertia * omega ** 2, 2.0 * DAMPING_RATIO * inertia * omega)
    return gains


@dataclass(frozen=True)
class CameraSpec:
    """A camera's resolution and horizontal field of view."""

    width: int
    height: int
    hfov_deg: float

    @property
    def fovy_deg(self) -> float:
        return fovy_deg(self.width, self.height, self.hfov_deg)


EYE_CAMERA = CameraSpec(EYE_WIDTH, EYE_HEIGHT, EYE_HFOV_DEG)
RGBD_CAMERA = CameraSpec(RGBD_WIDTH, RGBD_HEIGHT, RGBD_HFOV_DEG)


def build_mjcf(scene: Scene | None, eye: CameraSpec = EYE_CAMERA,
               rgbd: CameraSpec = RGBD_CAMERA) -> str:
    """The whole MJCF: the head (with servo gains), its cameras, and the scene."""
    gains = servo_gains(round(eye.fovy_deg, 9), round(rgbd.fovy_deg, 9))
    body, act = head_xml(gains, eye_fovy=eye.fovy_deg, rgbd_fovy=rgbd.fovy_deg)
    return _mjcf(body, act, scene, max(eye.width, rgbd.width), max(eye.height, rgbd.height))


def compile_model(scene: Scene | None, eye: CameraSpec = EYE_CAMERA,
                  rgbd: CameraSpec = RGBD_CAMERA) -> tuple[mujoco.MjModel, str]:
    """(MjModel, MJCF) of the head in scene."""
    mjcf = build_mjcf(scene, eye, rgbd)
    model = mujoco.MjModel.from_xml_string(mjcf, dict(scene.assets) if scene else None)
    return model, mjcf


@dataclass(frozen=True)
class JointSample:
    """Joint state at sim time [s]: positions [rad], velocities [rad/s], actuator efforts [N m]."""

    time: float
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


class HeadSimulation:
    """The head in a scene: MuJoCo physics at 500 Hz, position targets, real-time stepping.

    Thread-safe: set_targets(), sample() and snapshot_into() may be called from any thread
    while start() runs the physics in its own thread.
    """

    def __init__(self, scene: Scene, initial: Mapping[str, float] | None = None,
                 eye: CameraSpec = EYE_CAMERA, rgbd: CameraSpec = RGBD_CAMERA) -> None:
        self.scene = scene
        self.model, self.mjcf = compile_model(scene, eye, rgbd)
        self.data = mujoco.MjData(self.model)
        m = self.model
        jid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in JOINT_NAMES]
        self.qpos_adr = np.array([m.jnt_qposadr[j] for j in jid])
        self.dof_adr = np.array([m.jnt_dofadr[j] for j in jid])
        self.act_ids = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n)
                                 for n in JOINT_NAMES])
        self.dt = float(m.opt.timestep)
        q0, _ = clamp_to_limits({n: float((initial or {}).get(n, 0.0)) for n in JOINT_NAMES})
        q0v = np.array([q0[n] for n in JOINT_NAMES])
        self.data.qpos[self.qpos_adr] = q0v
        self.data.ctrl[self.act_ids] = q0v
        self._target = q0v.copy()
        self._reference = q0v.copy()
        self._vmax = np.array([VELOCITY_LIMITS[n] for n in JOINT_NAMES])
        self._speed = self._vmax.copy()
        mujoco.mj_forward(m, self.data)
        self.lock = threading.RLock()
        self.steps = 0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.max_catch_up_steps = 50   # beyond 100 ms behind, sim time slows instead of bursting

    # ---- commands
    def set_targets(self, targets: Mapping[str, float],
                    speeds: Mapping[str, float] | None = None) -> list[str]:
        """Set joint position targets [rad] (clamped into the limits); returns one line per clamp.

        speeds [rad/s]: optional per-joint speed to approach the target with (capped at the
        velocity limit); joints without one move at the velocity limit. Unknown names raise
        KeyError and nothing changes.
        """
        unknown = [n for n in targets if n not in JOINT_LIMITS]
        if unknown:
            raise KeyError(f'unknown joints {unknown}; known: {list(JOINT_NAMES)}')
        clamped, notes = clamp_to_limits(targets)
        with self.lock:
            for i, name in enumerate(JOINT_NAMES):
                if name in clamped:
                    self._target[i] = clamped[name]
                    s = (speeds or {}).get(name)
                    self._speed[i] = (min(float(s), self._vmax[i])
                                      if s is not None and math.isfinite(s) and s > 0
                                      else self._vmax[i])
        return notes

    def targets(self) -> dict[str, float]:
        with self.lock:
            return dict(zip(JOINT_NAMES, self._target.tolist(), strict=True))

    # ---- stepping
    def step(self, n: int = 1) -> None:
        """Advance the physics n steps (rate-limited references, then mj_step)."""
        m, d = self.model, self.data
        with self.lock:
            for _ in range(n):
                delta = np.clip(self._target - self._reference, -self._speed * self.dt,
                                self._speed * self.dt)
                self._reference += delta
                d.ctrl[self.act_ids] = self._reference
                mujoco.mj_step(m, d)
            self.steps += n

    def sample(self) -> JointSample:
        """The joints now."""
        with self.lock:
            d = self.data
            return JointSample(float(d.time), d.qpos[self.qpos_adr].copy(),
                               d.qvel[self.dof_adr].copy(), d.actuator_force[self.act_ids].copy())

    @property
    def time(self) -> float:
        return float(self.data.time)

    def snapshot_into(self, out: mujoco.MjData) -> float:
        """Copy the state into out (another MjData of this model) and run forward kinematics
        on it; returns its sim time [s]. Render from out while the physics goes on."""
        d = self.data
        with self.lock:
            out.time = d.time
            out.qpos[:] = d.qpos
            out.qvel[:] = d.qvel
            out.ctrl[:] = d.ctrl
            if self.model.nmocap:
                out.mocap_pos[:] = d.mocap_pos
                out.mocap_quat[:] = d.mocap_quat
            t = float(d.time)
        return t

    # ---- real time
    def start(self) -> None:
        """Step in a background thread, keeping sim time with wall time (real-time factor 1)."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name='vizzy_physics', daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._thread = None

    def _run(self) -> None:
        origin = time.monotonic() - self.data.time   # wall time at sim time 0
        while not self._stop.is_set():
            now = time.monotonic()
            due = int((now - origin - self.data.time) / self.dt)
            if due > self.max_catch_up_steps:
                origin += (due - self.max_catch_up_steps) * self.dt
                due = self.max_catch_up_steps
            if due > 0:
                self.step(due)
            wait = origin + self.data.time + self.dt - time.monotonic()
            if wait > 0:
                self._stop.wait(wait)


__all__ = ['CAMERA_XYAXES', 'CameraSpec', 'DAMPING_RATIO', 'EYE_CAMERA', 'HeadSimulation',
           'JointSample', 'RGBD_CAMERA', 'ROBOT_GROUP', 'SERVO', 'TIMESTEP', 'build_mjcf',
           'compile_model', 'head_xml', 'servo_gains']

"""The `sim` node: the Vizzy head simulated in MuJoCo, with the thesis's scenes.

Physics runs at 500 Hz in its own thread, keeping sim time with wall time; this node publishes
that sim time on /clock (it runs on wall time itself) and stamps everything with it.

Topic names are relative (below: resolved at the root namespace), so `-r __ns:=/head2` moves them
all; cameras and RGB-D publish reliable keep-last 5 as drivers do (REP 2003), so any subscriber
matches, best effort or reliable.
Publishes (frames and QoS in docs/vizzy_sim_bridge.md):
  /vizzy/{left,right}/image_raw (rgb8) + camera_info       every 1/rate_hz
  /vizzy/rgbd/image_raw (rgb8), /vizzy/rgbd/depth/image_raw (32FC1 [m], NaN invalid),
  /vizzy/rgbd/points (organized x y z rgb), /vizzy/rgbd/camera_info   every 1/rgbd_rate_hz
  /vizzy/{left,right,rgbd}/image_raw/compressed (sensor_msgs/CompressedImage, JPEG at
      jpeg_quality, image_transport's format string: compressed.py), with each image, encoded
      only while something subscribes (jpeg_encodes counts them)
  camera_info: computed from MuJoCo's camera, or the calibration file at
      <camera>_camera_info_url (camera_calibration.py) when one is given and usable
  /joint_states, /tf                                       every 1/joint_state_rate_hz, and at
                                                           each image's stamp
  /tf_static (latched), /clock
  /robot_description (std_msgs/String, reliable + transient local, depth 1, once at start-up:
      late joiners get it, as from robot_state_publisher): the head's URDF, core.urdf.head_urdf(),
      generated from core/kinematics.py and the MuJoCo model; its links are the frames of /tf and
      /tf_static below world. RViz's RobotModel and Foxglove's URDF layer read it.
  /diagnostics (diagnostic_msgs/DiagnosticArray, about 1 Hz): this node's input health
  /sim/ground_truth/objects (MarkerArray, latched): every object with its dimensions;
      cylinders also as an axis arrow (ns cylinder_axes)
  /sim/ground_truth/pedestrians (MarkerArray, 3D boxes) and
  /sim/ground_truth/{left,right}/pedestrians (active_vision_msgs/TrackArray: each walker's box
      in that camera's image [px]), pedestrians scene only, with each stereo pair
Subscribes:
  /vizzy/joint_commands (sensor_msgs/JointState): name + position targets [rad]; velocity (if
      given, same length) caps each joint's speed. Out-of-range targets are clamped, with a
      warning per joint at most every 2 s; that is no refusal, the message is processed.

Refused inputs (vizzy_runtime.input_health.InputHealth, self.input_health): every command
rejected whole is counted per (topic, reason), its first occurrence logged (then at most every
5 s per reason, with the count), and the counts are published on /diagnostics (WARN while
refusals happen). Reasons on the resolved /vizzy/joint_commands:
  'no joint names'     name is empty
  'length mismatch'    name and position differ in length
  'unknown joint'      a name that is not one of the five head joints
  'repeated joint'     a name given twice
  'non-finite target'  a NaN or infinite position
  'failed on a command: <ExcType>'  the handler raised (guarded(topic=...))
A processed command (clamped or not) counts as accepted on that topic.
"""

from __future__ import annotations

import contextlib
import os
import threading
from typing import Any

import mujoco
import numpy as np

from vizzy_runtime.convert import stamp_msg
from vizzy_runtime.input_health import InputHealth, ThrottledWarnings
from vizzy_runtime.node_tools import (
    declare_parameters,
    guarded,
    main_for,
    publish_from_thread,
    replace_timer,
)
from vizzy_runtime.ros import (
    Node,
    Parameter,
    QoSProfile,
    SetParametersResult,
    message,
    qos_profile_latched,
)
from vizzy_runtime.tf import TF_STATIC_TOPIC, TF_TOPIC
from vizzy_sim_bridge import compressed
from vizzy_sim_bridge.camera_calibration import (
    CAMERA_NAMES,
    Calibration,
    choose_calibration,
    sim_calibration,
)
from vizzy_sim_bridge.core.commands import command_problem
from vizzy_sim_bridge.core.model import CameraSpec, HeadSimulation
from vizzy_sim_bridge.core.render import RendererUnavailable, select_backend
from vizzy_sim_bridge.core.rgbd import DepthProjector
from vizzy_sim_bridge.core.scenes import SceneUnavailable, build_scene
from vizzy_sim_bridge.core.urdf import head_urdf
from vizzy_sim_bridge.messages import (  # noqa: F401 (box_corners, image_box: re-exported)
    box_corners,
    camera_info,
    float_seq,
    image_box,
    object_markers,
    pedestrian_markers,
    pedestrian_tracks,
    transform_messages,
)
from vizzy_sim_bridge.parameters import (  # noqa: F401 (READ_ONLY, checks: re-exported)
    PARAMETERS,
    READ_ONLY,
    check_parameter,
    check_parameters,
)
from vizzy_sim_bridge.sim_loops import lockstep_loop, render_loop, start_rendering
from vizzy_vision.camera import camera_matrix
from vizzy_vision.kinematics import (
    BASELINE,
    CAMERA_FRAMES,
    JOINT_NAMES,
    RGBD_FRAME,
    joint_transforms,
    static_transforms,
    world_transform,
)

CameraInfo = message('sensor_msgs/msg/CameraInfo')
CompressedImage = message('sensor_msgs/msg/CompressedImage')
Clock = message('rosgraph_msgs/msg/Clock')
Header = message('std_msgs/msg/Header')
Image = message('sensor_msgs/msg/Image')
JointState = message('sensor_msgs/msg/JointState')
MarkerArray = message('visualization_msgs/msg/MarkerArray')
TFMessage = message('tf2_msgs/msg/TFMessage')
TrackArray = message('active_vision_msgs/msg/TrackArray')
String = message('std_msgs/msg/String')

EYES = ('left', 'right')
# Relative names: the node's namespace (or remapping) places them; logs print the resolved ones.
COMMAND_TOPIC = 'vizzy/joint_commands'
IMAGE_TOPICS = {e: f'vizzy/{e}/image_raw' for e in EYES}
INFO_TOPICS = {e: f'vizzy/{e}/camera_info' for e in EYES}
RGBD_IMAGE_TOPIC = 'vizzy/rgbd/image_raw'
RGBD_DEPTH_TOPIC = 'vizzy/rgbd/depth/image_raw'
RGBD_POINTS_TOPIC = 'vizzy/rgbd/points'
RGBD_INFO_TOPIC = 'vizzy/rgbd/camera_info'
JOINT_STATES_TOPIC = 'joint_states'
CLOCK_TOPIC = 'clock'          # nodes with use_sim_time follow /clock: a namespaced graph remaps it
GROUND_TRUTH_TOPIC = 'sim/ground_truth'
ROBOT_DESCRIPTION_TOPIC = 'robot_description'   # relative, like robot_state_publisher's
STEP_TOPIC = 'sim/step'           # lockstep: rosgraph_msgs/Clock, advance until this time
STEPPED_TOPIC = 'sim/stepped'     # lockstep: rosgraph_msgs/Clock, the time reached
STEP_QOS = QoSProfile(depth=10)
# Drivers publish sensor data reliable (REP 2003): best-effort and reliable subscribers both match.
SENSOR_QOS = QoSProfile(depth=5)
# destroy_node() waits at most this for the render thread's frame in flight (one stereo pair or
# RGB-D frame, well under a second); whatever the thread publishes after it is dropped.
RENDER_JOIN_TIMEOUT_S = 2.0


class SimNode(Node):
    """The simulated Vizzy head: physics, cameras, RGB-D, joints, tf, /clock, ground truth."""

    def __init__(self, **kwargs: Any) -> None:
        """kwargs go to Node (context, parameter_overrides, cli_args, ...)."""
        super().__init__('sim', **kwargs)
        p = declare_parameters(self, PARAMETERS, check_parameter, check_all=check_parameters,
                               on_change=self._on_parameters_changed)
        self._p = p
        # refused inputs, per topic and reason, on /diagnostics; before any subscription
        self.input_health = InputHealth(self)
        self._publish_clock = bool(p['publish_clock'])
        # Any order with declare_parameters' callbacks: the table applies changes post-set.
        self.add_on_set_parameters_callback(self._refuse_sim_time)
        if self._publish_clock and self.get_parameter('use_sim_time').value:
            # Following the /clock we publish ourselves would stop every timer at time 0.
            self.get_logger().info('the sim is the /clock source: running on wall time '
                                   '(use_sim_time set to false)')
            self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, False)])
        log = self.get_logger()

        scene_kwargs = ({'count': int(p['pedestrian_count'])} if p['scene'] == 'pedestrians'
                        else {})
        self._scene = build_scene(p['scene'], int(p['seed']), **scene_kwargs)
        eye = CameraSpec(int(p['width']), int(p['height']), float(p['horizontal_fov_deg']))
        rgbd = CameraSpec(int(p['rgbd_width']), int(p['rgbd_height']),
                          float(p['rgbd_horizontal_fov_deg']))
        initial = dict(zip(JOINT_NAMES, (float(v) for v in p['initial_joint_positions']),
                           strict=True))
        self._sim = HeadSimulation(self._scene, initial, eye, rgbd)
        for note in self._sim.set_targets(initial):
            log.warning(f'initial_joint_positions: {note}')
        self._model = self._sim.model
        self._render_data = mujoco.MjData(self._model)
        self._backend = select_backend(p['render_backend'])   # fails here, naming the package
        self._eye, self._rgbd = eye, rgbd
        self._cam_ids = {e: mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_CAMERA,
                                              f'{e}_camera') for e in EYES}
        self._rgbd_cam = mujoco.mj_name2id(self._model, mujoco.mjtObj.mjOBJ_CAMERA, 'rgbd_camera')
        self._k_eye = camera_matrix(eye.width, eye.height, eye.hfov_deg)
        self._k_rgbd = camera_matrix(rgbd.width, rgbd.height, rgbd.hfov_deg)
        # what each camera_info says: MuJoCo's ideal pinhole, or the user's file; the rendering
        # (and the cloud, the ground-truth boxes) stays MuJoCo's camera either way
        computed = {'left': sim_calibration(CAMERA_NAMES['left'], eye.width, eye.height,
                                            eye.hfov_deg),
                    'right': sim_calibration(CAMERA_NAMES['right'], eye.width, eye.height,
                                             eye.hfov_deg, BASELINE),
                    'rgbd': sim_calibration(CAMERA_NAMES['rgbd'], rgbd.width, rgbd.height,
                                            rgbd.hfov_deg)}
        frames = {'left': CAMERA_FRAMES['left'], 'right': CAMERA_FRAMES['right'],
                  'rgbd': RGBD_FRAME}
        self.calibration_sources: dict[str, str] = {}   # camera -> 'computed' or the URL
        self._info = {cam: camera_info(self._calibration(cam, computed[cam]), frames[cam])
                      for cam in computed}
        self.jpeg_encodes = 0                   # <image>/compressed frames encoded
        self._projector = DepthProjector(self._k_rgbd, rgbd.width, rgbd.height)
        self._noise_rng = np.random.default_rng(np.random.SeedSequence([int(p['seed']), 99]))
        self._last_tf_ns = -1
        self._publish_lock = threading.Lock()   # joints and tf go out from two threads
        self._warn_throttled = ThrottledWarnings(self, 2.0)
        self._stop = threading.Event()
        self._render_thread: threading.Thread | None = None

        sensor = SENSOR_QOS
        self._image_pubs = {e: self.create_publisher(Image, IMAGE_TOPICS[e], sensor)
                            for e in EYES}
        # image_transport's compressed transport beside each raw image, encoded when read
        self._compressed_pubs = {e: self.create_publisher(
            CompressedImage, IMAGE_TOPICS[e] + compressed.SUFFIX, sensor) for e in EYES}
        self._info_pubs = {e: self.create_publisher(CameraInfo, INFO_TOPICS[e], sensor)
                           for e in EYES}
        self._rgbd_image_pub = self.create_publisher(Image, RGBD_IMAGE_TOPIC, sensor)
        self._rgbd_compressed_pub = self.create_publisher(
            CompressedImage, RGBD_IMAGE_TOPIC + compressed.SUFFIX, sensor)
        self._rgbd_depth_pub = self.create_publisher(Image, RGBD_DEPTH_TOPIC, sensor)
        self._rgbd_points_pub = self.create_publisher(message('sensor_msgs/msg/PointCloud2'),
                                                      RGBD_POINTS_TOPIC, sensor)
        self._rgbd_info_pub = self.create_publisher(CameraInfo, RGBD_INFO_TOPIC, sensor)
        self._joint_pub = self.create_publisher(JointState, JOINT_STATES_TOPIC, 10)
        self._tf_pub = self.create_publisher(TFMessage, TF_TOPIC, 100)
        self._tf_static_pub = self.create_publisher(TFMessage, TF_STATIC_TOPIC, qos_profile_latched)
        self._description_pub = self.create_publisher(String, ROBOT_DESCRIPTION_TOPIC,
                                                      qos_profile_latched)
        self._clock_pub = (self.create_publisher(Clock, CLOCK_TOPIC, 10)
                           if self._publish_clock else None)
        self._gt_objects_pub = self.create_publisher(
            MarkerArray, f'{GROUND_TRUTH_TOPIC}/objects', qos_profile_latched)
        self._crowd = self._scene.crowd is not None
        if self._crowd:
            self._gt_people_pub = self.create_publisher(
                MarkerArray, f'{GROUND_TRUTH_TOPIC}/pedestrians', 10)
            self._gt_boxes_pubs = {e: self.create_publisher(
                TrackArray, f'{GROUND_TRUTH_TOPIC}/{e}/pedestrians', 10) for e in EYES}
        self._command_topic = self.resolve_topic_name(COMMAND_TOPIC)   # for logs and counters
        self._command_sub = self.create_subscription(JointState, COMMAND_TOPIC, guarded(
            self, 'failed on a command', self._on_joint_command, topic=self._command_topic), 10)

        self._description_pub.publish(String(data=head_urdf()))
        now = self._now(self._sim.time)
        self._tf_static_pub.publish(TFMessage(transforms=transform_messages(
            [world_transform()] + static_transforms(), now)))
        self._publish_ground_truth()

        self._lockstep = bool(p['lockstep'])
        self._step_target = 0.0
        self._step_cond = threading.Condition()
        self.ticks = 0                          # lockstep ticks done
        if self._lockstep:
            # one thread steps the physics, publishes and renders, tick by tick, as asked
            self._stepped_pub = self.create_publisher(Clock, STEPPED_TOPIC, STEP_QOS)
            self._step_sub = self.create_subscription(Clock, STEP_TOPIC, guarded(
                self, 'failed on a step', self._on_step), STEP_QOS)
            start_rendering(self, lambda r: lockstep_loop(self, r))
        else:
            self._sim.start()
            start_rendering(self, lambda r: render_loop(self, r))
            self._joint_timer = self.create_timer(1.0 / float(p['joint_state_rate_hz']), guarded(
                self, 'joint state publishing failed', self._on_joint_tick))
            self._gt_timer = self.create_timer(1.0 / float(p['ground_truth_rate_hz']), guarded(
                self, 'ground truth publishing failed', self._publish_ground_truth))
            if self._clock_pub is not None:
                self._clock_timer = self.create_timer(1.0 / float(p['clock_rate_hz']), guarded(
                    self, '/clock publishing failed', self._on_clock))
        log.info(
            f'scene {p["scene"]} (seed {p["seed"]}): {self._scene.description}; '
            f'{eye.width}x{eye.height} stereo at {p["rate_hz"]} Hz, RGB-D at {p["rgbd_rate_hz"]} '
            f'Hz, physics at {1.0 / self._sim.dt:.0f} Hz, rendering with '
            f'{self._backend} in its own thread; cameras on '
            f'{", ".join(self._image_pubs[e].topic_name for e in EYES)} (+ /compressed, '
            f'camera_info), RGB-D on '
            f'{self._rgbd_points_pub.topic_name}, {self._joint_pub.topic_name}, '
            f'{self._tf_pub.topic_name}, {self._description_pub.topic_name}'
            f'{", " + self._clock_pub.topic_name if self._clock_pub is not None else ""}; '
            f'joint targets on {self._command_sub.topic_name}'
            + (f'; LOCKSTEP: time advances only as asked on {self._step_sub.topic_name}'
               if self._lockstep else ''))

    # ------------------------------------------------------------------ helpers
    def _now(self, t: float) -> Any:
        if self._publish_clock:
            return stamp_msg(t)
        return self.get_clock().now().to_msg()

    def _calibration(self, cam: str, computed: Calibration) -> Calibration:
        """The file at <cam>_camera_info_url if one is set and usable, else computed."""
        cal, self.calibration_sources[cam] = choose_calibration(
            f'{cam}_camera_info_url', str(self._p[f'{cam}_camera_info_url']), computed,
            self.get_logger())
        return cal

    def _compressed(self, image: np.ndarray, header: Any) -> Any:
        self.jpeg_encodes += 1
        return compressed.compressed_image(image, 'rgb8', header, int(self._p['jpeg_quality']))

    def _publish_joints(self, t: float, position: np.ndarray, velocity: np.ndarray,
                        effort: np.ndarray) -> None:
        """/joint_states and /tf at sim time t, unless already published for that instant."""
        ns = int(round(t * 1e9))
        with self._publish_lock:
            if ns <= self._last_tf_ns:
                return
            self._last_tf_ns = ns
            self._send_joints(t, position, velocity, effort)

    def _send_joints(self, t: float, position: np.ndarray, velocity: np.ndarray,
                     effort: np.ndarray) -> None:
        stamp = self._now(t)
        joints = JointState(name=list(JOINT_NAMES))
        joints.header.stamp = stamp
        joints.position = float_seq(position)
        joints.velocity = float_seq(velocity)
        joints.effort = float_seq(effort)
        # from the joint timer or the render thread (see sim_loops.render_loop)
        publish_from_thread(self, self._joint_pub, joints)
        publish_from_thread(self, self._tf_pub, TFMessage(transforms=transform_messages(
            joint_transforms(position.tolist()), stamp)))

    # ------------------------------------------------------------------ timers
    def _on_clock(self) -> None:
        assert self._clock_pub is not None      # its timer exists only with the publisher
        self._clock_pub.publish(Clock(clock=self._now(self._sim.time)))

    def _on_joint_tick(self) -> None:
        s = self._sim.sample()
        self._publish_joints(s.time, s.position, s.velocity, s.effort)

    def _on_step(self, msg: Any) -> None:
        """Lockstep: advance until msg.clock (a request for a past time is done already)."""
        t = msg.clock.sec + 1e-9 * msg.clock.nanosec
        with self._step_cond:
            if t > self._step_target:
                self._step_target = t
                self._step_cond.notify_all()

    def _publish_ground_truth(self) -> None:
        self._gt_objects_pub.publish(object_markers(self._scene.objects,
                                                    self._now(self._sim.time)))

    # ------------------------------------------------------------------ commands

    def _on_joint_command(self, msg: Any) -> None:
        topic = self._command_topic
        names = list(msg.name)
        positions = [float(v) for v in msg.position]
        velocities = [float(v) for v in msg.velocity]
        problem = command_problem(names, positions)
        if problem is not None:
            self.input_health.refuse(topic, *problem)   # logged first time, then throttled
            return
        speeds = (dict(zip(names, velocities, strict=True)) if len(velocities) == len(names)
                  else None)
        for note in self._sim.set_targets(dict(zip(names, positions, strict=True)), speeds):
            self._warn_throttled(note.split()[0], f'{topic}: {note}')   # clamped: no refusal
        self.input_health.accept(topic)

    # ------------------------------------------------------------------ parameters, shutdown
    def _refuse_sim_time(self, params: list[Any]) -> Any:
        for param in params:
            if param.name == 'use_sim_time' and param.value and self._publish_clock:
                return SetParametersResult(
                    successful=False, reason='the sim publishes /clock; it cannot follow it')
        return SetParametersResult(successful=True)

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if getattr(self, '_lockstep', False):
            return                  # the lockstep loop reads the rates at every tick
        if 'joint_state_rate_hz' in changed:
            self._joint_timer = replace_timer(self, self._joint_timer,
                                              1.0 / float(changed['joint_state_rate_hz']),
                                              guarded(self, 'joint state publishing failed',
                                                      self._on_joint_tick))
        if 'ground_truth_rate_hz' in changed:
            self._gt_timer = replace_timer(self, self._gt_timer,
                                           1.0 / float(changed['ground_truth_rate_hz']),
                                           guarded(self, 'ground truth publishing failed',
                                                   self._publish_ground_truth))

    def destroy_node(self) -> Any:
        stop = getattr(self, '_stop', None)
        if stop is not None:
            stop.set()
        cond = getattr(self, '_step_cond', None)
        if cond is not None:
            with cond:
                cond.notify_all()
        thread = getattr(self, '_render_thread', None)
        if thread is not None:  # one frame in flight at most; a later publish is dropped
            thread.join(timeout=RENDER_JOIN_TIMEOUT_S)
        sim = getattr(self, '_sim', None)
        if sim is not None:
            sim.stop()
        return super().destroy_node()


# a missing renderer or scene module ends the sim with one clear line
main = main_for(SimNode, cannot_start=(RendererUnavailable, SceneUnavailable))


def standby_prepare() -> None:
    """For the zygote (`vizzy run --zygote`), before it forks the node: probe the OpenGL backend
    now (in a child process, 0.8 s on a loaded machine); select_backend caches the answer for the
    node's construction."""
    with contextlib.suppress(RendererUnavailable, ValueError):   # the node says why when it starts
        select_backend(os.environ.get('MUJOCO_GL', 'auto') or 'auto')


if __name__ == '__main__':
    main()

"""The sim node's render thread: its two loops, real time (each output paced by its rate on the
monotonic clock) and lockstep (the physics stepped tick by tick as asked on sim/step), and the
frames it renders and publishes (stereo pair, RGB-D, the walkers' ground truth). They work on
the node's state; sim_node.py starts them."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from vizzy_runtime.convert import array_to_pointcloud2, numpy_to_image
from vizzy_runtime.node_tools import has_subscribers, publish_from_thread
from vizzy_runtime.ros import ExternalShutdownException, message
from vizzy_sim_bridge.core.commands import next_due
from vizzy_sim_bridge.core.render import CameraRenderer
from vizzy_sim_bridge.core.rgbd import noisy_depth
from vizzy_sim_bridge.messages import pedestrian_markers, pedestrian_tracks
from vizzy_vision.kinematics import CAMERA_FRAMES, RGBD_FRAME, frames_in_base

if TYPE_CHECKING:
    from vizzy_sim_bridge.sim_node import SimNode

Clock = message('rosgraph_msgs/msg/Clock')
Header = message('std_msgs/msg/Header')

# sim_node.EYES, defined there as well: test_rviz_config reads the node's topics from its source
EYES = ('left', 'right')


def start_rendering(node: SimNode, loop: Callable[[CameraRenderer], Any]) -> None:
    """The render thread: its own GL context, running loop(renderer): render_loop, paced by
    rate_hz and rgbd_rate_hz (the executor stays free for joint commands, /joint_states, /tf
    and /clock), or lockstep_loop."""
    ready = threading.Event()
    failure: list[BaseException] = []

    def run() -> None:
        try:
            renderer = CameraRenderer(node._model, max(node._eye.width, node._rgbd.width),
                                      max(node._eye.height, node._rgbd.height),
                                      node._backend)
        except BaseException as exc:  # reported by the constructor, in its thread
            failure.append(exc)
            ready.set()
            return
        ready.set()
        try:
            loop(renderer)
        finally:
            renderer.close()

    node._render_thread = threading.Thread(target=run, name='vizzy_render', daemon=True)
    node._render_thread.start()
    ready.wait()
    if failure:
        node._sim.stop()
        raise failure[0]


def render_loop(node: SimNode, renderer: CameraRenderer) -> None:
    """Renders and publishes (publish_from_thread) until destroy_node() sets _stop, or
    until the context goes away under it (Ctrl-C under real rclpy): then it ends quietly."""
    node._renderer = renderer
    due = {'stereo': time.monotonic(), 'rgbd': time.monotonic()}
    work = {'stereo': lambda: stereo_frame(node), 'rgbd': lambda: rgbd_frame(node)}
    last_error = {'stereo': -math.inf, 'rgbd': -math.inf}
    while not node._stop.is_set():
        rates = {'stereo': float(node._p['rate_hz']), 'rgbd': float(node._p['rgbd_rate_hz'])}
        now = time.monotonic()
        for key in ('stereo', 'rgbd'):
            if rates[key] <= 0.0:
                due[key] = now + 0.1
                continue
            if now >= due[key]:
                period = 1.0 / rates[key]
                # keep the phase; when late by more than a period, start again from now
                due[key] = due[key] + period if now - due[key] < period else now + period
                try:
                    work[key]()
                except ExternalShutdownException:
                    return
                except Exception as exc:  # one bad frame never stops the rendering
                    if now - last_error[key] > 5.0:
                        last_error[key] = now
                        node.get_logger().error(
                            f'{key} rendering failed: {type(exc).__name__}: {exc}')
        wait = min(due.values()) - time.monotonic()
        if wait > 0:
            node._stop.wait(wait)


def lockstep_loop(node: SimNode, renderer: CameraRenderer) -> None:
    """Lockstep: per /clock tick, step the physics, then publish /joint_states and /tf,
    /clock, the images and clouds due (on the sim-time schedule of their rates) and the
    ground truth; after the last tick asked for, sim/stepped. Ends like render_loop."""
    node._renderer = renderer
    sim = node._sim
    tick = 1.0 / float(node._p['clock_rate_hz'])
    substeps = max(1, int(round(tick / sim.dt)))
    due = {'joints': 0.0, 'stereo': 0.0, 'rgbd': 0.0, 'gt': 0.0}
    work = {'stereo': lambda: stereo_frame(node), 'rgbd': lambda: rgbd_frame(node),
            'gt': node._publish_ground_truth}
    eps = 0.25 * sim.dt
    try:
        while not node._stop.is_set():
            with node._step_cond:
                if node._step_target <= sim.time + eps:
                    node._step_cond.wait(0.1)
                    continue
                target = node._step_target
            while sim.time + eps < target and not node._stop.is_set():
                sim.step(substeps)
                node.ticks += 1
                t = sim.time
                rates = {'joints': float(node._p['joint_state_rate_hz']),
                         'stereo': float(node._p['rate_hz']),
                         'rgbd': float(node._p['rgbd_rate_hz']),
                         'gt': float(node._p['ground_truth_rate_hz'])}
                if t + eps >= due['joints']:
                    due['joints'] = next_due(due['joints'], t, rates['joints'])
                    s = sim.sample()
                    node._publish_joints(s.time, s.position, s.velocity, s.effort)
                if node._clock_pub is not None:
                    publish_from_thread(node, node._clock_pub, Clock(clock=node._now(t)))
                for key in ('stereo', 'rgbd', 'gt'):
                    if rates[key] > 0.0 and t + eps >= due[key]:
                        due[key] = next_due(due[key], t, rates[key])
                        work[key]()
            publish_from_thread(node, node._stepped_pub, Clock(clock=node._now(sim.time)))
    except ExternalShutdownException:
        return


def snapshot(node: SimNode) -> tuple[float, np.ndarray]:
    """Copy the physics state for rendering, pose the walkers; (sim time, joint positions)."""
    d = node._render_data
    t = node._sim.snapshot_into(d)
    node._scene.update(node._model, d, t)
    mujoco.mj_forward(node._model, d)
    q = d.qpos[node._sim.qpos_adr].copy()
    node._publish_joints(t, q, d.qvel[node._sim.dof_adr].copy(),
                         d.actuator_force[node._sim.act_ids].copy())
    return t, q


def stereo_frame(node: SimNode) -> None:
    t, q = snapshot(node)
    stamp = node._now(t)
    for e in EYES:
        rgb, _ = node._renderer.render(node._render_data, node._cam_ids[e],
                                       width=node._eye.width, height=node._eye.height)
        header = Header(stamp=stamp, frame_id=CAMERA_FRAMES[e])
        publish_from_thread(node, node._image_pubs[e], numpy_to_image(rgb, 'rgb8', header))
        if has_subscribers(node._compressed_pubs[e]):    # a JPEG only for a reader
            publish_from_thread(node, node._compressed_pubs[e], node._compressed(rgb, header))
        info = node._info[e]
        info.header.stamp = stamp
        publish_from_thread(node, node._info_pubs[e], info)
    if node._crowd:
        publish_pedestrians(node, q, stamp)


def rgbd_frame(node: SimNode) -> None:
    t, _ = snapshot(node)
    stamp = node._now(t)
    rgb, depth = node._renderer.render(node._render_data, node._rgbd_cam, depth=True,
                                       width=node._rgbd.width, height=node._rgbd.height)
    assert depth is not None                # asked for (depth=True)
    coeff = float(node._p['depth_noise_coefficient'])
    z = noisy_depth(depth, node._noise_rng if coeff > 0 else None, coeff,
                    float(node._p['rgbd_min_range_m']), float(node._p['rgbd_max_range_m']))
    header = Header(stamp=stamp, frame_id=RGBD_FRAME)
    # built only for readers: the depth image is 1.2 MB, the organized cloud 4.9 MB
    for pub, make in ((node._rgbd_image_pub, lambda: numpy_to_image(rgb, 'rgb8', header)),
                      (node._rgbd_compressed_pub, lambda: node._compressed(rgb, header)),
                      (node._rgbd_depth_pub, lambda: numpy_to_image(z, '32FC1', header)),
                      (node._rgbd_points_pub, lambda: array_to_pointcloud2(
                          node._projector.cloud(z, rgb), header, is_dense=False))):
        if has_subscribers(pub):
            publish_from_thread(node, pub, make())
    info = node._info['rgbd']
    info.header.stamp = stamp
    publish_from_thread(node, node._rgbd_info_pub, info)


def publish_pedestrians(node: SimNode, q: np.ndarray, stamp: Any) -> None:
    boxes = node._scene.moving_ground_truth(node._model, node._render_data)
    publish_from_thread(node, node._gt_people_pub, pedestrian_markers(boxes, stamp))
    poses = frames_in_base(q.tolist())
    for e in EYES:
        publish_from_thread(node, node._gt_boxes_pubs[e], pedestrian_tracks(
            boxes, node._k_eye, poses[CAMERA_FRAMES[e]], node._eye.width, node._eye.height,
            stamp, CAMERA_FRAMES[e]))

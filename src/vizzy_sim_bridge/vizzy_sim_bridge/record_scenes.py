"""Record the short scene bags under bags/<scene>/: the sim and the gaze controller, a few saccades.

    .venv/bin/python -m vizzy_sim_bridge.record_scenes [--scenes tabletop visual_search pedestrians]
        [--output bags] [--check]

For each scene it starts `sim` (config/sim.yaml, the scene's reduced rates below, to keep the bag
small) and `gaze_controller` as separate processes (`vizzy run`), waits for images and
/gaze/state, records every topic with `vizzy bag record -a` for the scene's duration and, while
recording, sends GazeCommands (saccades to fixation points taken from the scene's ground truth:
objects on the table, the visual search target, a walker). With --check it also reports how far
from the principal point each fixated object's centre ends up in both images (an end-to-end check
of sim + gaze controller; it is printed, not asserted).
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from vizzy_runtime.launcher import share_dir

REPO = Path(__file__).resolve().parents[3]
VIZZY = [sys.executable, '-m', 'vizzy_runtime.cli']
CONFIG = Path(__file__).resolve().parents[1] / 'config'

# scene: (stereo Hz, RGB-D Hz, seconds recorded, initial joints). 12 s with four saccades, so that
# a replay shows tracks forming and the ego-sphere filling; the rates keep each bag near 25 MB.
PLAN: dict[str, tuple[float, float, float, str]] = {
    'tabletop': (1.5, 0.25, 12.0, '[0.0, 0.2, 0.15, 0.0, 0.0]'),
    # visual_search: rich texture, ~0.9 MB/image
    'visual_search': (0.75, 0.15, 12.0, '[0.0, 0.0, 0.0, 0.0, 0.0]'),
    'pedestrians': (1.5, 0.25, 12.0, '[0.0, 0.0, 0.0, 0.0, 0.0]'),
}
# Not recorded: the depth image is the organized cloud's z (the cylinder detector reads the cloud).
EXCLUDE = ('/vizzy/rgbd/depth/image_raw',)


def _targets(scene: str) -> list[np.ndarray]:
    """Fixation points (base_link) for the saccades: from the scene's ground truth (seed 0)."""
    from vizzy_sim_bridge.core.scenes import build_scene
    if scene == 'pedestrians':   # ahead, at body height, left and right
        return [np.array(p) for p in ([3.0, 0.8, 0.9], [3.5, -0.8, 0.8], [4.0, 1.2, 0.9],
                                      [3.0, -0.2, 0.9])]
    objects = build_scene(scene, 0).objects
    if scene == 'visual_search':
        target = next(o for o in objects if o.role == 'target')
        others = [o for o in objects if o.role != 'target'][:3]
        return [np.array(o.position) for o in others] + [np.array(target.position)]
    cylinders = [o for o in objects if o.is_cylinder]
    return [np.array(o.position) for o in cylinders[:4]]


def record(scene: str, out: Path, check: bool) -> int:
    from vizzy_runtime.ros import Node, message, qos_profile_sensor_data, rclpy
    from vizzy_runtime.testing import wait_until

    rate, rgbd_rate, seconds, initial = PLAN[scene]
    bag = out / scene
    if bag.exists():
        shutil.rmtree(bag)
    env = dict(os.environ)
    gaze_config = share_dir('vizzy_gaze') / 'config' / 'gaze_controller.yaml'
    procs = [
        subprocess.Popen(VIZZY + ['run', 'vizzy_sim_bridge', 'sim', '--ros-args', '--params-file',
                                  str(CONFIG / 'sim.yaml'), '-p', f'scene:={scene}',
                                  '-p', f'rate_hz:={rate}', '-p', f'rgbd_rate_hz:={rgbd_rate}',
                                  '-p', f'initial_joint_positions:={initial}'], env=env),
        subprocess.Popen(VIZZY + ['run', 'vizzy_gaze', 'gaze_controller', '--ros-args',
                                  '--params-file', str(gaze_config),
                                  '-p', 'use_sim_time:=true'], env=env),
    ]
    GazeCommand = message('active_vision_msgs/msg/GazeCommand')
    GazeState = message('active_vision_msgs/msg/GazeState')
    Image = message('sensor_msgs/msg/Image')
    rclpy.init(args=[])
    node = Node('record_scenes')
    images: dict[str, Any] = {}
    states: list[Any] = []
    for side in ('left', 'right'):
        node.create_subscription(Image, f'/vizzy/{side}/image_raw',
                                 lambda m, s=side: images.__setitem__(s, m),
                                 qos_profile_sensor_data)
    node.create_subscription(GazeState, '/gaze/state', states.append, 10)
    joints: list[Any] = []
    node.create_subscription(message('sensor_msgs/msg/JointState'), '/joint_states',
                             joints.append, 10)
    gaze = node.create_publisher(GazeCommand, '/gaze/command', 10)

    def spin_for(s: float) -> None:
        end = time.monotonic() + s
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.02)

    recorder = None
    try:
        up = wait_until(lambda: (rclpy.spin_once(node, timeout_sec=0.02) or True)
                        and len(images) == 2 and len(states) > 0, 120.0)
        if not up:
            print(f'record_scenes: {scene}: the sim or the gaze controller did not come up',
                  file=sys.stderr)
            return 1
        recorder = subprocess.Popen(VIZZY + ['bag', 'record', '-a', '-o', str(bag), '--duration',
                                             str(seconds), '--exclude-topics', *EXCLUDE], env=env)
        spin_for(1.0)
        targets = _targets(scene)
        for k, point in enumerate(targets):
            cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT,
                              motion=GazeCommand.MOTION_SACCADE, source='record_scenes',
                              priority=1, hold_time=0.5)
            cmd.header.frame_id = 'base_link'
            cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = (
                float(v) for v in point)
            gaze.publish(cmd)
            spin_for(max(0.5, (seconds - 1.2) / len(targets)))
            if check:
                _report(scene, k, point, joints[-1], states[-1])
        recorder.wait(timeout=seconds + 60)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        if recorder is not None and recorder.poll() is None:
            recorder.send_signal(signal.SIGINT)
            recorder.wait(30)
        for p in procs:
            p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()
    size = sum(f.stat().st_size for f in bag.rglob('*') if f.is_file())
    print(f'record_scenes: {bag}: {size / 1e6:.1f} MB', flush=True)
    return 0


def _report(scene: str, k: int, point: np.ndarray, joint_state: Any, state: Any) -> None:
    """Where the fixation point projects in both images with the joints the sim reports."""
    from vizzy_vision.camera import camera_matrix, project
    from vizzy_vision.kinematics import camera_poses
    q = dict(zip(joint_state.name, (float(v) for v in joint_state.position), strict=True))
    kk = camera_matrix(640, 480, 85.4)
    offsets = {side: project(kk, pose, point[None])[0] - (319.5, 239.5)
               for side, pose in camera_poses(q).items()}
    print(f'record_scenes: {scene}: saccade {k} to {np.round(point, 3)}: gaze status '
          f'{state.status} {state.status_message!r}; the point is '
          + ', '.join(f'{s} {np.round(o, 2)} px' for s, o in offsets.items())
          + ' from the principal points', flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scenes', nargs='+', default=list(PLAN), choices=list(PLAN))
    parser.add_argument('--output', default=str(REPO / 'bags'))
    parser.add_argument('--check', action='store_true', help='print the gaze outcome per saccade')
    ns = parser.parse_args(argv)
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))
    status = 0
    for scene in ns.scenes:
        status |= record(scene, Path(ns.output), ns.check)
    return status


if __name__ == '__main__':
    sys.exit(main())

"""The sim node's parameters: the table it declares (ranges and choices enforced by the
middleware) and the checks the table cannot express. sim_node.py declares them."""

from __future__ import annotations

import math
from typing import Any

from vizzy_runtime.node_tools import Param
from vizzy_sim_bridge import compressed
from vizzy_sim_bridge.camera_calibration import CAMERA_NAMES
from vizzy_sim_bridge.core.scenes import SCENE_NAMES
from vizzy_vision.kinematics import JOINT_NAMES

# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('scene', 'tabletop', 'Scene: ' + ', '.join(SCENE_NAMES) + ' (read-only).',
          choices=tuple(SCENE_NAMES), read_only=True),
    Param('seed', 0, 'Seed of the scene layout and of the depth noise, >= 0 (read-only).',
          '[0, inf)', read_only=True),
    Param('pedestrian_count', 4, 'Walkers in the pedestrians scene, in [1, 20] (read-only).',
          '[1, 20]', read_only=True),
    Param('rate_hz', 15.0, 'Rate of the stereo images and their camera_info [Hz], in '
          '[0.1, 60].', '[0.1, 60]'),
    Param('rgbd_rate_hz', 5.0, 'Rate of the RGB-D image, depth, points and camera_info [Hz], '
          'in [0, 30]; 0 switches the RGB-D sensor off.', '[0, 30]'),
    Param('joint_state_rate_hz', 100.0, 'Rate of /joint_states and /tf [Hz], in [1, 500].',
          '[1, 500]'),
    Param('width', 640, 'Eye camera image width [px] (read-only).', '[16, 4096]',
          read_only=True),
    Param('height', 480, 'Eye camera image height [px] (read-only).', '[16, 4096]',
          read_only=True),
    Param('horizontal_fov_deg', 85.4, 'Horizontal field of view of each eye camera [deg] '
          '(read-only).', '[1, 170]', read_only=True),
    Param('rgbd_width', 640, 'RGB-D image width [px] (read-only).', '[16, 4096]',
          read_only=True),
    Param('rgbd_height', 480, 'RGB-D image height [px] (read-only).', '[16, 4096]',
          read_only=True),
    Param('rgbd_horizontal_fov_deg', 58.0, 'Horizontal field of view of the RGB-D sensor [deg] '
          '(read-only).', '[1, 170]', read_only=True),
    Param('depth_noise_coefficient', 1.425e-3, 'Depth noise sigma_z = c z^2: c [1/m], in '
          '[0, 0.05]; 0 = noise-free depth (Khoshelham & Elberink 2012: 1.425e-3).',
          '[0, 0.05]'),
    Param('rgbd_min_range_m', 0.5, 'Nearest valid depth [m], in [0, 10); nearer is NaN.',
          '[0, 10)', constraints='below rgbd_max_range_m'),
    Param('rgbd_max_range_m', 3.5, 'Farthest valid depth [m], in (0, 50]; farther is NaN.',
          '(0, 50]', constraints='above rgbd_min_range_m'),
    Param('initial_joint_positions', [0.0, 0.0, 0.0, 0.0, 0.0],
          'Joint targets at start [rad], in the order ' + ', '.join(JOINT_NAMES) +
          '; clamped into the joint limits (read-only).',
          constraints=f'{len(JOINT_NAMES)} finite values', read_only=True),
    Param('render_backend', 'auto', 'OpenGL for rendering: auto (EGL, else OSMesa), egl or '
          'osmesa (read-only).', choices=('auto', 'egl', 'osmesa'), read_only=True),
    Param('jpeg_quality', compressed.DEFAULT_JPEG_QUALITY, 'JPEG quality of the '
          '<image>/compressed streams, in [1, 100] (image_transport\'s default: 95).',
          '[1, 100]'),
    *(Param(f'{cam}_camera_info_url', '', f'camera_info_manager URL of the {cam} camera\'s '
            'calibration (camera_calibration_parsers YAML): file:///<path> or '
            'package://<package>/<path>, ${NAME} = ' + CAMERA_NAMES[cam] + '. Published as its '
            'camera_info instead of the one computed from MuJoCo; empty: the computed one '
            '(read-only).', read_only=True)
      for cam in ('left', 'right', 'rgbd')),
    Param('ground_truth_rate_hz', 1.0, 'Rate of republishing /sim/ground_truth/objects [Hz], '
          'in [0.01, 100].', '[0.01, 100]'),
    Param('publish_clock', True,
          'Publish /clock (simulated time starting at 0) and stamp messages with it '
          '(read-only). The sim itself must run with use_sim_time false.', read_only=True),
    Param('clock_rate_hz', 100.0, 'Rate of /clock [Hz], in [10, 1000] (read-only; slower, '
          'sim-time timers would fire in bursts).', '[10, 1000]', read_only=True),
    Param('lockstep', False,
          'Advance simulated time only as far as asked on sim/step, one /clock tick at a time, '
          'and say how far on sim/stepped (read-only). For benchmarks: whoever asks waits for '
          'the graph to finish each tick, so results do not depend on the machine\'s speed. '
          'Off: real time.', read_only=True),
)
READ_ONLY = frozenset(p.name for p in PARAMETERS if p.read_only)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is: what the table's
    ranges and choices cannot express."""
    if name == 'initial_joint_positions':
        if len(value) != len(JOINT_NAMES):
            return f'initial_joint_positions needs {len(JOINT_NAMES)} values, got {len(value)}'
        if not all(math.isfinite(v) for v in value):
            return f'initial_joint_positions must be finite, got {list(value)}'
    return None


def check_parameters(values: dict[str, Any]) -> str | None:
    """What is wrong with the parameters taken together, or None."""
    if values['rgbd_min_range_m'] >= values['rgbd_max_range_m']:
        return 'rgbd_min_range_m must be < rgbd_max_range_m'
    return None

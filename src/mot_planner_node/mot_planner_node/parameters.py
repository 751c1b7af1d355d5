"""The `mot_planner` node's parameters: the declared table (names, defaults, ranges, help),
what the ranges cannot express (check_parameter), and the tracker, planner and detector settings
they make. ROS-free apart from the Param records; the node (node.py) declares and wires them."""

from __future__ import annotations

import math
from typing import Any

from mot_planner_node.core.detector import Detector, HogDetector
from mot_planner_node.core.planner import PlannerConfig
from mot_planner_node.core.tracker import DEPLOYED
from vizzy_runtime.node_tools import Param

OVERLAY_TOPIC = 'mot/overlay'
GAZE_COMMAND_TOPIC = 'gaze/command'
MIN_RATE_HZ = 0.01                 # a positive max_rate_hz below this stops tracking
# The floor in base_link: -vizzy_vision.kinematics.WAIST_HEIGHT (the waist joint's height
# in vizzy_description), copied so that the node does not depend on the simulator's package.
FLOOR_Z_M = -0.535797

# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('k_max', 3, 'K_max: most search regions processed per frame (section 5.3.4), in '
          '[1, 20].', '[1, 20]'),
    Param('s_max', 0.1, 'S_max: largest fraction of the image\'s pixels the detector reads per '
          'frame (section 5.3.4; counted at the resolution it reads them, full frames paid '
          'from what the regions leave), in (0, 1].', '(0, 1]'),
    Param('alpha_c', 1.0, 'Search-region width in centre stds (Eq. 5.18), in [0, 10].',
          '[0, 10]'),
    Param('alpha_s', 1.0, 'Search-region width in scale stds (Eq. 5.19), in [0, 10].',
          '[0, 10]'),
    Param('max_rate_hz', 0.0, 'Most frames tracked per second, counted in the images\' stamps '
          '(the others are dropped before any work; 0: every frame), in [0, 1000].',
          '[0, 1000]', constraints=f'0 or at least {MIN_RATE_HZ} Hz'),
    Param('budget_ms', 10.0, 'Wall-clock planning budget per frame [ms], in [0.1, 1000].',
          '[0.1, 1000]'),
    Param('horizon', DEPLOYED['horizon'], 'Planning horizon T in frames, the depth of the MCTS '
          'search (section 5.3.5; the thesis used 3), in [1, 8].', '[1, 8]'),
    Param('full_frame_period', DEPLOYED['full_frame_period'], 'Fewest frames between two '
          'full-frame detections (where new tracks are born; each is paid from the S_max '
          'budget the regions leave), in [1, 100000].', '[1, 100000]'),
    Param('birth_share', DEPLOYED['birth_share'], 'Share of each frame\'s S_max saved for '
          'full-frame detections (track births); the regions get the rest, in [0, 0.95].',
          '[0, 0.95]'),
    Param('birth_score', DEPLOYED['birth_score'], 'Least detector score (HOG\'s SVM margin) '
          'of a detection that starts a track or brings back a lost one; weaker detections '
          'still update tracks, in [-10, 10].', '[-10, 10]'),
    Param('report_misses', DEPLOYED['report_misses'], 'A track is published while it has at '
          'most this many consecutive misses (-1: while it lives), in [-1, 1000].',
          '[-1, 1000]'),
    Param('keep_lost', DEPLOYED['keep_lost'], 'Frames a deleted track is remembered; a '
          'detection in its gate brings it back under its id (0: never), in [0, 1000].',
          '[0, 1000]'),
    Param('occluded_share', DEPLOYED['occluded_share'], 'A track whose box is covered by at '
          'least this share by a nearer track\'s is occluded: no region is spent on it and it '
          'is not missed while hidden (0: no occlusion reasoning), in [0, 1].', '[0, 1]'),
    Param('tentative_misses', DEPLOYED['tentative_misses'], 'Consecutive misses a new track '
          'survives before it is confirmed (0: dropped on its first), in [0, 100].', '[0, 100]'),
    Param('hit_threshold', 0.0, 'HOG SVM hit threshold (higher: fewer detections), in '
          '[-10, 10].', '[-10, 10]'),
    Param('region_hit_threshold', DEPLOYED['region_hit_threshold'], 'HOG SVM hit threshold '
          'inside the tracks\' regions, where a person is predicted (lower: a weaker window '
          'there still updates the track), in [-10, 10].', '[-10, 10]'),
    Param('read_upsample', DEPLOYED['read_upsample'], 'A region is read at this many times its '
          'smallest scale and enlarged back before HOG scans it (fewer pixels read per region; '
          '1: read at that scale), in [1, 2].', '[1, 2]'),
    # step 8 from 8: the multiples of 8 (the HOG block stride)
    Param('win_stride', 8, 'HOG window stride [px], a multiple of 8 in [8, 64].', '[8, 64]',
          step=8),
    Param('scale', 1.05, 'HOG pyramid scale step, in (1, 2].', '(1, 2]'),
    Param('full_frame_scale', 0.0, 'HOG pyramid scale step on full frames only (the births\' '
          'scans; 0: scale), 0 or in (1, 2].', '[0, 2]',
          constraints='0 or in (1, 2]'),
    Param('publish_overlay', True, f'Publish the overlay image on {OVERLAY_TOPIC}.'),
    Param('publish_gaze', True,
          f'Send pursuit commands on {GAZE_COMMAND_TOPIC} to keep the tracks in view.'),
    Param('gaze_priority', 10, 'Priority of the gaze commands (below the other nodes\' '
          'saccades), in [0, 1000].', '[0, 1000]'),
    Param('gaze_depth_m', 3.0, 'Nominal depth of the fixation point along the group\'s ray '
          '[m], in (0.1, 100].', '(0.1, 100]'),
    Param('gaze_rate_hz', 2.0, 'Most gaze commands per second, in [0.01, 30].', '[0.01, 30]'),
    Param('gaze_min_hits', 3, 'Only tracks detected at least this many times steer the gaze, '
          'in [1, 1000].', '[1, 1000]'),
    Param('gaze_min_age', 5, 'Only tracks at least this many frames old steer the gaze, in '
          '[0, 100000].', '[0, 100000]'),
    Param('person_check', True,
          'Only tracks whose box stands on the floor at a person\'s height steer the gaze '
          '(needs camera_info and the camera\'s pose in world_frame).'),
    Param('person_height_m', [1.3, 2.5],
          'Range [min, max] of the height [m] a box standing on the floor must imply, 0 < min '
          '< max <= 10.', constraints='[min, max] with 0 < min < max <= 10'),
    Param('floor_z_m', FLOOR_Z_M, 'Height of the floor in world_frame [m] (base_link, the '
          'waist, stands WAIST_HEIGHT above it), in [-100, 100].', '[-100, 100]'),
    Param('person_check_frames', 5, 'The implied height must be in range on each of a '
          'track\'s last this many frames, in [1, 1000].', '[1, 1000]'),
    Param('person_height_ratio', 1.3, 'Largest max/min of a track\'s implied heights over '
          'those frames (a person\'s stays put; a box above the floor sweeps as the head '
          'moves), in [1, 10].', '[1, 10]'),
    Param('ego_motion', True, 'Compensate the camera\'s rotation between images (from /tf).'),
    Param('world_frame', 'base_link', 'A frame that does not rotate with the head, for '
          'ego-motion.', constraints='a frame id, not empty'),
)
PLANNER_PARAMETERS = ('k_max', 's_max', 'alpha_c', 'alpha_s', 'budget_ms', 'horizon',
                      'full_frame_period')
TRACK_PARAMETERS = ('full_frame_period', 'birth_share', 'birth_score', 'report_misses',
                    'keep_lost', 'occluded_share', 'tentative_misses')
DETECTOR_PARAMETERS = ('hit_threshold', 'region_hit_threshold', 'read_upsample', 'win_stride',
                       'scale', 'full_frame_scale')


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is: what the table's
    ranges cannot express (types and ranges are the descriptors', see PARAMETERS)."""
    if name == 'person_height_m':
        values = [float(v) for v in value]      # a double array (the descriptor's type)
        ok = (len(values) == 2 and all(math.isfinite(v) for v in values)
              and 0.0 < values[0] < values[1] <= 10.0)
        return None if ok else f'person_height_m must be [min, max] with 0 < min < max <= 10, ' \
                               f'got {values!r}'
    if name == 'max_rate_hz' and 0.0 < value < MIN_RATE_HZ:
        return (f'max_rate_hz must be 0 (every frame) or at least {MIN_RATE_HZ} Hz, got {value:g} '
                '(a frame every few hours is tracking switched off)')
    if name == 'full_frame_scale' and 0.0 < value <= 1.0:
        return f'full_frame_scale must be 0 (the scale parameter) or in (1, 2], got {value:g}'
    if name == 'world_frame' and not value.strip('/'):
        return f'world_frame must be a frame id, got {value!r}'
    return None



def make_hog_detector(params: dict[str, Any]) -> Detector:
    """The default detector: OpenCV's HOG people detector with the node's settings."""
    return HogDetector(win_stride=int(params['win_stride']), scale=float(params['scale']),
                       hit_threshold=float(params['hit_threshold']),
                       region_hit_threshold=float(params['region_hit_threshold']),
                       upsample=float(params['read_upsample']),
                       full_frame_scale=float(params['full_frame_scale']) or None)



def track_settings(params: dict[str, Any]) -> dict[str, Any]:
    """The TrackerConfig fields the node's track parameters set (births, reporting)."""
    misses = int(params['report_misses'])
    return {'full_frame_period': int(params['full_frame_period']),
            'birth_share': float(params['birth_share']),
            'birth_score': float(params['birth_score']),
            'report_misses': None if misses < 0 else misses,
            'keep_lost': int(params['keep_lost']),
            'occluded_share': float(params['occluded_share']) or None,
            'tentative_misses': int(params['tentative_misses'])}


def planner_config(params: dict[str, Any]) -> PlannerConfig:
    return PlannerConfig(k_max=int(params['k_max']), s_max=float(params['s_max']),
                         alpha_c=float(params['alpha_c']), alpha_s=float(params['alpha_s']),
                         budget_ms=float(params['budget_ms']), area=str(DEPLOYED['area']),
                         depth=int(params['horizon']))

PERSON_PARAMETERS = ('person_height_m', 'person_check_frames', 'person_height_ratio')

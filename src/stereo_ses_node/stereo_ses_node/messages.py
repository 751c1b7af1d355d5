"""What the stereo_ses node reads and writes, as messages: its topic names, the reasons an input
is refused (InputHealth counter keys), the image check, and the /stereo/points and /ses/cells
structured arrays. The node (node.py) only wires these to its topics.

Refused inputs are counted by vizzy_runtime.input_health.InputHealth (self.input_health;
logging and /diagnostics as its docstring says). The reasons (counter keys):
  on /vizzy/{left,right}/image_raw, one image at a time (IMAGE_REASONS): 'unsupported encoding'
    (not rgb8/bgr8), 'empty image', 'step shorter than a row', 'size inconsistent with data'
    (fewer data bytes than height x step); 'no partner image' (no image of the other eye came
    within max_stamp_skew_s of its stamp: dropped unpaired, images_unpaired);
  on both image topics, once per image of a pair the worker took (PAIR_REASONS): 'left and right
    sizes differ', 'no camera_info' (none usable yet for an eye), 'size differs from
    camera_info', 'no frame_id', 'no camera pose' (tf lacks ego <- left or left <- right, or the
    rig is degenerate), 'no valid correspondences' (e.g. textureless: NaN disparities),
    'failed on a pair: <ExcType>' (an exception in the worker); these count in frames_skipped;
    'not newer than the last fused pair' (REPEATED_STAMP: a pair stamped at or before the last
    fused one, e.g. the same pair sent twice: one observation is fused once; counted in
    pairs_repeated, not frames_skipped; when the node's clock itself went back before that
    stamp, a restarted simulation or bag, it is fused);
  on /vizzy/{left,right}/camera_info: 'unusable K' (not 9 finite values with fx, fy in
    [1, 1e6] px; the last good K stays in use);
  for an exception escaping a subscription callback (node_tools.guarded): 'failed on an image:
    <ExcType>' (or a camera_info, a state) on that callback's topic.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stereo_ses_node.core.decision import reward_statistics
from stereo_ses_node.core.information import information_from_precision
from stereo_ses_node.core.ses import SensoryEgoSphere
from stereo_ses_node.core.stereo import StereoFrame
from vizzy_runtime.convert import image_refusal
from vizzy_runtime.ros import message
from vizzy_vision.pointcloud import pack_rgb

GazeCommand = message('active_vision_msgs/msg/GazeCommand')

EYES = ('left', 'right')
# Relative names: the graph remaps the generic inputs (left/image_raw:=vizzy/left/image_raw, ...)
# and the node's namespace places everything; logs print the resolved names.
IMAGE_TOPICS = {'left': 'left/image_raw', 'right': 'right/image_raw'}
INFO_TOPICS = {'left': 'left/camera_info', 'right': 'right/camera_info'}
GAZE_STATE_TOPIC = 'gaze/state'
GAZE_COMMAND_TOPIC = 'gaze/command'
POINTS_TOPIC = 'stereo/points'
CELLS_TOPIC = 'ses/cells'
SOURCE = 'stereo_ses'
ENCODINGS = ('rgb8', 'bgr8')
# Refusal reasons (InputHealth counter keys: short and stable; the values go in the detail).
NO_PARTNER = 'no partner image'
# a pair the worker could not fuse: counted on both image topics
SIZES_DIFFER = 'left and right sizes differ'
NO_CAMERA_INFO = 'no camera_info'
INFO_SIZE_MISMATCH = 'size differs from camera_info'
NO_FRAME_ID = 'no frame_id'
NO_CAMERA_POSE = 'no camera pose'
NO_CORRESPONDENCES = 'no valid correspondences'
PAIR_FAILED = 'failed on a pair'           # + ': <ExcType>'
PAIR_REASONS = (SIZES_DIFFER, NO_CAMERA_INFO, INFO_SIZE_MISMATCH, NO_FRAME_ID, NO_CAMERA_POSE,
                NO_CORRESPONDENCES)
REPEATED_STAMP = 'not newer than the last fused pair'
UNUSABLE_K = 'unusable K'
# Held, not refused (the pair is set aside by design; /diagnostics shows `held (<reason>)`).
IN_SACCADE = 'in saccade'
RATE_CAP = 'max_rate_hz'

POINT_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('rgb', '<f4'),
                        ('cxx', '<f4'), ('cxy', '<f4'), ('cxz', '<f4'), ('cyy', '<f4'),
                        ('cyz', '<f4'), ('czz', '<f4'), ('information', '<f4')])
CELL_DTYPE = np.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('information', '<f4'),
                       ('sigma_r', '<f4'), ('observations', '<f4')])


def image_problem(msg: Any) -> tuple[str, str] | None:
    """(reason, detail) of why an input image cannot be used, or None if it can (reason: one of
    IMAGE_REASONS, a counter key)."""
    return image_refusal(msg, dict.fromkeys(ENCODINGS, 3))


def points_array(frame: StereoFrame, info: np.ndarray) -> np.ndarray:
    """The /stereo/points structured array of a frame (left optical frame)."""
    out = np.empty(frame.means.shape[0], POINT_DTYPE)
    for i, axis in enumerate('xyz'):
        out[axis] = frame.means[:, i]
    out['rgb'] = pack_rgb(frame.colors)
    for name, (a, b) in (('cxx', (0, 0)), ('cxy', (0, 1)), ('cxz', (0, 2)), ('cyy', (1, 1)),
                         ('cyz', (1, 2)), ('czz', (2, 2))):
        out[name] = frame.covs[:, a, b]
    out['information'] = info
    return out


def cells_array(ses: SensoryEgoSphere, observed_only: bool) -> np.ndarray:
    """The /ses/cells structured array (ego frame)."""
    idx = np.nonzero(ses.n_obs > 0)[0] if observed_only else np.arange(ses.n_cells)
    out = np.empty(idx.size, CELL_DTYPE)
    mean = ses.mean[idx]
    for i, axis in enumerate('xyz'):
        out[axis] = mean[:, i]
    out['information'] = information_from_precision(ses.info[idx])
    out['sigma_r'] = reward_statistics(mean, ses.cov[idx])[1]
    out['observations'] = ses.n_obs[idx]
    return out


def gaze_command(point: np.ndarray, p: dict[str, Any], stamp: Any) -> Any:
    """The saccade to fixate point (ego_frame) that the node sends, from its parameters p."""
    cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT, motion=GazeCommand.MOTION_SACCADE,
                      source=SOURCE, priority=int(p['gaze_priority']),
                      hold_time=float(p['hold_time']))
    cmd.header.frame_id = p['ego_frame']
    cmd.header.stamp = stamp
    cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = (float(v) for v in point)
    return cmd


def pair_problem(left_shape: tuple[int, ...], right_shape: tuple[int, ...],
                 k: dict[str, np.ndarray], sizes: dict[str, tuple[int, int]],
                 frames: dict[str, str], info_topics: dict[str, str]) -> tuple[str, str] | None:
    """(reason, detail) of why a pair cannot be fused before its poses are looked up, or None:
    image shapes, each eye's K and camera_info size (k, sizes by eye), the images' frame_ids;
    info_topics: the resolved camera_info topics, for the details."""
    if left_shape != right_shape:
        return SIZES_DIFFER, (f'left image {left_shape[1]}x{left_shape[0]} and '
                              f'right {right_shape[1]}x{right_shape[0]} differ')
    missing = [e for e in EYES if e not in k]
    if missing:
        return NO_CAMERA_INFO, f'waiting for {" and ".join(info_topics[e] for e in missing)}'
    h, w = left_shape[:2]
    for eye in EYES:
        if sizes[eye] not in ((w, h), (0, 0)):
            return INFO_SIZE_MISMATCH, (f'{info_topics[eye]} is for {sizes[eye][0]}x'
                                        f'{sizes[eye][1]} images, got {w}x{h}')
    if not all(frames.values()):
        return NO_FRAME_ID, 'an image has no frame_id: no camera pose'
    return None

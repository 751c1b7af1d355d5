"""The stereo_ses node's per-pair set-up, ROS-free: the images in RGB, the stereo rig from K and
the camera poses, the pipeline and the disparity window the parameters ask for, and whether a
pair's stamp may be fused. The node (node.py) calls these from its worker thread."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

from stereo_ses_node.core.multires import DisparityWindow, disparity_window
from stereo_ses_node.core.stereo import SGBMParams, StereoPipeline
from stereo_ses_node.core.ut import StereoRig, UTParams

# stamp_verdict's answers
NEW, RESTARTED, REPEATED = 'new', 'restarted', 'repeated'


class Transforms(Protocol):
    """What stereo_rig needs of a transform buffer (vizzy_runtime.tf.TransformBuffer)."""

    def lookup_transform(self, target_frame: str, source_frame: str, stamp: Any = None, *,
                         timeout_s: float = 0.0,
                         max_extrapolation_s: float | None = None) -> np.ndarray: ...


def as_rgb(image: np.ndarray, encoding: str) -> np.ndarray:
    """The image as a contiguous RGB array (the pipeline's colours and grey conversion expect
    RGB)."""
    return np.ascontiguousarray(image[..., ::-1] if encoding == 'bgr8' else image)


def stereo_rig(tf: Transforms, ego_frame: str, frames: Mapping[str, str], stamp: float,
               k: Mapping[str, np.ndarray], timeout_s: float) -> tuple[StereoRig, np.ndarray]:
    """(the rig in the left optical frame, ego <- left) at stamp; LookupError (no transform) or
    ValueError (a degenerate rig) otherwise."""
    # the poses when the images were taken, not the latest: the head may have moved on
    # (1 rad/s of pursuit is 2.9 deg per 50 ms); both at the left image's stamp (the
    # right one's is within max_stamp_skew_s)
    ego_left = tf.lookup_transform(ego_frame, frames['left'], stamp, timeout_s=timeout_s)
    left_right = tf.lookup_transform(frames['left'], frames['right'], stamp, timeout_s=timeout_s)
    return StereoRig.create(k['left'], k['right'], np.eye(4), left_right), ego_left


def new_pipeline(p: Mapping[str, Any], width: int, height: int) -> StereoPipeline:
    """The stereo pipeline the parameters p ask for, on width x height images."""
    n = int(p['n_rf'])
    return StereoPipeline(width, height, p['sensor'], (n, n),
                          sgbm=SGBMParams(num_disparities=int(p['num_disparities']),
                                          min_disparity=int(p['min_disparity'])),
                          ut=UTParams(float(p['ut_alpha']), float(p['ut_beta']),
                                      float(p['ut_kappa'])))


def geometry_window(p: Mapping[str, Any], rig: StereoRig, width: int,
                    height: int) -> DisparityWindow | None:
    """The disparities of points at depth_range_m on this rig (None: disparity_range is not
    'geometry', so the fixed SGBM parameters' range); ValueError when the geometry gives none."""
    if p['disparity_range'] != 'geometry':
        return None
    near, far = (float(v) for v in p['depth_range_m'])
    return disparity_window(rig.k_left, rig.k_right, rig.pose_left, rig.pose_right,
                            width, height, near, far)


def stamp_verdict(stamp: float, last_fused: float, now: float) -> str:
    """NEW: stamp is after the last fused pair's; REPEATED: at or before it (one observation is
    fused once); RESTARTED: at or before it, but the clock (now) went back before the last fused
    stamp: the simulation or a bag restarted, so these are new observations."""
    if stamp > last_fused:
        return NEW
    return RESTARTED if now < last_fused else REPEATED


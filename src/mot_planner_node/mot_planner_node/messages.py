"""What the MOT planner node reads and writes, as messages: the input image's and camera_info's
checks; the TrackArray of the reported tracks, the AttentionRegions of the regions read this
frame, the overlay image and the pursuit GazeCommand. The node (node.py) only wires these."""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from mot_planner_node.core.bookkeeping import TrackBook
from mot_planner_node.core.tracker import FrameResult
from vizzy_runtime.convert import camera_k as usable_k
from vizzy_runtime.convert import image_refusal
from vizzy_runtime.ros import message

RegionOfInterest = message('sensor_msgs/msg/RegionOfInterest')
Track = message('active_vision_msgs/msg/Track')
TrackArray = message('active_vision_msgs/msg/TrackArray')
AttentionRegions = message('active_vision_msgs/msg/AttentionRegions')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')

SOURCE = 'mot_planner'
LABEL_PERSON = 'person'
LABEL_IMPLAUSIBLE = 'person_implausible'     # a person box that does not stand on the floor
ENCODINGS = ('rgb8', 'bgr8')


def image_problem(msg: Any) -> tuple[str, str] | None:
    """(reason, detail) of why an input image cannot be used, or None if it can (reason: one of
    IMAGE_REASONS, a counter key)."""
    return image_refusal(msg, dict.fromkeys(ENCODINGS, 3))


def _k_text(k: Any) -> str:
    return 'K [' + ', '.join(f'{float(v):g}' for v in k) + ']'


def camera_k(msg: Any) -> list[float] | None:
    """The 9 values of a CameraInfo's K if usable (vizzy_runtime.convert.camera_k), else None."""
    k = usable_k(msg)
    return None if k is None else k.ravel().tolist()


def track_array(header: Any, result: FrameResult, persons: np.ndarray, frame_period: float,
                book: TrackBook) -> Any:
    """The reported tracks, velocities and covariances in px/s (frame_period [s])."""
    out = TrackArray(header=header)
    fps = 1.0 / frame_period
    jac = np.diag([1.0, 1.0, 1.0, fps, fps, fps])       # px/frame -> px/s
    attended = set(result.attended_ids.tolist())
    tracks = []
    for i, tid in enumerate(result.ids.tolist()):
        x = result.states[i]
        box = result.boxes[i]
        cov = jac @ result.covariances[i] @ jac
        tracks.append(Track(
            id=int(tid), label=LABEL_PERSON if persons[i] else LABEL_IMPLAUSIBLE,
            center_u=float(box[0] + box[2] / 2), center_v=float(box[1] + box[3] / 2),
            width=float(box[2]), height=float(box[3]), scale=float(x[2]),
            velocity_u=float(x[3] * fps), velocity_v=float(x[4] * fps),
            velocity_scale=float(x[5] * fps), covariance=[float(c) for c in cov.ravel()],
            attended=tid in attended,
            age=int(book.age(tid, result.frame)),
            frames_lost=int(book.frames_lost(tid))))
    out.tracks = tracks
    return out


def attention(header: Any, result: FrameResult, size: tuple[int, int], k_max: int,
              s_max: float) -> Any:
    """The regions read this frame (clipped to the image of size (width, height))."""
    width, height = size
    rois, ids = [], []
    for k, reg in enumerate(result.regions):
        x0, y0 = int(max(math.floor(reg[0]), 0)), int(max(math.floor(reg[1]), 0))
        x1, y1 = int(min(math.ceil(reg[2]), width)), int(min(math.ceil(reg[3]), height))
        rois.append(RegionOfInterest(x_offset=x0, y_offset=y0, width=max(x1 - x0, 0),
                                     height=max(y1 - y0, 0)))
        ids.append(0 if result.full_frame or k >= len(result.attended_ids)
                   else int(result.attended_ids[k]))
    fraction = 1.0 if result.full_frame else result.processed_fraction
    return AttentionRegions(header=header, regions=rois, track_ids=ids,
                            budget_fraction=float(fraction), k_max=int(k_max),
                            s_max=float(s_max), planning_time_ms=1e3 * result.plan_s)


def overlay(image: np.ndarray, encoding: str, result: FrameResult,
            persons: np.ndarray) -> np.ndarray:
    """rgb8 copy of image with the regions (yellow; cyan for a full frame) and track boxes."""
    rgb = cv2.cvtColor(image, cv2.COLOR_BGR2RGB) if encoding == 'bgr8' else image.copy()
    colour = (0, 255, 255) if result.full_frame else (255, 220, 0)
    for reg in result.regions:
        x0, y0 = int(reg[0]), int(reg[1])
        x1, y1 = int(min(reg[2], rgb.shape[1])) - 1, int(min(reg[3], rgb.shape[0])) - 1
        cv2.rectangle(rgb, (x0, y0), (x1, y1), colour, 1)
    for tid, box, person in zip(result.ids.tolist(), result.boxes, persons.tolist(),
                                strict=True):
        x, y, w, h = (int(round(v)) for v in box)
        colour = (0, 255, 0) if person else (150, 150, 150)   # grey: not on the floor
        cv2.rectangle(rgb, (x, y), (x + w, y + h), colour, 2)
        cv2.putText(rgb, str(tid), (x + 2, max(y - 4, 10)), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                    colour, 1, cv2.LINE_AA)
    return rgb


def gaze_command(frame_id: str, stamp: Any, priority: int,
                 point: tuple[float, float, float]) -> Any:
    """A pursuit of the fixation point (in frame_id)."""
    cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT,
                      motion=GazeCommand.MOTION_PURSUIT, source=SOURCE,
                      priority=int(priority), hold_time=0.0)
    cmd.header.frame_id = frame_id
    cmd.header.stamp = stamp
    cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = point
    return cmd

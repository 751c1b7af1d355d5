"""What the foveation node reads and writes, as messages: the input image and CameraInfo checked
(with the reasons one is refused), the JPEG CompressedImage, the FoveatedDetectionArray and
Detection2DArray of a recognition, the overlay's boxes and the saccade GazeCommand. The node
(node.py) only wires these to its topics.

  /foveation/detections_2d     vision_msgs/Detection2DArray (reliable, depth 10), the frame's
                               header (on the array and on each detection): one Detection2D per
                               pass-2 detection, bbox in full-resolution pixels of the frame
                               (center = box centre ((x0+x1)/2, (y0+y1)/2), theta 0, size_x/y =
                               x1-x0+1, y1-y0+1 for inclusive pixel bounds x0..x1, y0..y1; see
                               core.detections_2d), results = at most top_k
                               ObjectHypothesisWithPose: its own label (class_id = the label
                               string) and score first, then the other classes of the pass-2 image
                               it was found in by decreasing probability (pose unset); id empty
  /foveation/overlay           sensor_msgs/Image rgb8 (if publish_overlay), the frame foveated at
                               its fixation with both passes' boxes, labels and scores (one colour
                               per pass), the fixation and the fovea (radius f0), a legend
                               (core.overlay), the frame's header
"""

from __future__ import annotations

import array
from typing import Any

import cv2
import numpy as np

from foveation_node.core.detections_2d import box_centre_size, ranked_hypotheses
from foveation_node.core.overlay import Box
from foveation_node.core.recognition import Detection
from vizzy_runtime.convert import camera_k as usable_k
from vizzy_runtime.convert import image_refusal
from vizzy_runtime.ros import USING_REAL_ROS, message

CompressedImage = message('sensor_msgs/msg/CompressedImage')
GazeCommand = message('active_vision_msgs/msg/GazeCommand')
FoveatedDetection = message('active_vision_msgs/msg/FoveatedDetection')
FoveatedDetectionArray = message('active_vision_msgs/msg/FoveatedDetectionArray')
Detection2D = message('vision_msgs/msg/Detection2D')
Detection2DArray = message('vision_msgs/msg/Detection2DArray')
ObjectHypothesisWithPose = message('vision_msgs/msg/ObjectHypothesisWithPose')

ENCODINGS = ('rgb8', 'bgr8')


def image_problem(msg: Any, max_width: int, max_height: int) -> tuple[str, str] | None:
    """(reason, detail) of why an input image cannot be used, or None if it can (reason: one of
    IMAGE_REASONS, a counter key)."""
    return image_refusal(msg, dict.fromkeys(ENCODINGS, 3), max_size=(max_width, max_height))


def k_text(k: Any) -> str:
    return 'K [' + ', '.join(f'{float(v):g}' for v in k) + ']'


def camera_k(msg: Any) -> tuple[float, ...] | None:
    """The 9 values of a CameraInfo's K if usable (vizzy_runtime.convert.camera_k), else None."""
    k = usable_k(msg)
    return None if k is None else tuple(k.ravel().tolist())


def encode_jpeg(image: np.ndarray, encoding: str, quality: int) -> bytes:
    """JPEG bytes of an rgb8/bgr8 image (cv2 expects BGR; the file holds the true colours)."""
    bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if encoding == 'rgb8' else image
    ok, buf = cv2.imencode('.jpg', bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError('cv2.imencode failed to encode a JPEG')
    return buf.tobytes()


def detection_2d_array(header: Any, detections: list[Detection], probs_second: np.ndarray,
                       labels: list[str], top_k: int) -> Any:
    """The vision_msgs/Detection2DArray of pass-2 detections (TwoPassResult.second, with their
    probs_second): one Detection2D each, header on the array and on each detection, the box as
    centre and size (core.detections_2d.box_centre_size), results the ranked hypotheses
    (core.detections_2d.ranked_hypotheses, at most top_k), id empty."""
    out = Detection2DArray()
    out.header = header
    for d in detections:
        det = Detection2D()
        det.header = header
        u, v, width, height = box_centre_size(d.box)
        det.bbox.center.position.x, det.bbox.center.position.y = u, v
        det.bbox.center.theta = 0.0
        det.bbox.size_x, det.bbox.size_y = width, height
        for label, score in ranked_hypotheses(d, probs_second, labels, top_k):
            hyp = ObjectHypothesisWithPose()
            hyp.hypothesis.class_id, hyp.hypothesis.score = label, score
            det.results.append(hyp)
        out.detections.append(det)
    return out


def compressed_image(header: Any, encoding: str, jpeg: bytes) -> Any:
    """The CompressedImage of JPEG bytes of an image of that encoding, with its header."""
    # image_transport's format string: its subscribers (republish, RViz) decode by it
    compressed = CompressedImage(format=f'{encoding}; jpeg compressed bgr8')
    compressed.header = header
    compressed.data = (array.array('B', jpeg) if USING_REAL_ROS
                       else np.frombuffer(jpeg, np.uint8))
    return compressed


def detection_array(header: Any, fixation: tuple[float, float], f0: float,
                    detections: list[Detection]) -> Any:
    """The FoveatedDetectionArray of one pass's detections at fixation (fovea size f0)."""
    out = FoveatedDetectionArray()
    out.header = header
    out.fixation_u, out.fixation_v = float(fixation[0]), float(fixation[1])
    out.fovea_size = float(f0)
    for d in detections:
        det = FoveatedDetection(label=d.label, class_id=d.class_id, score=d.score,
                                fixation_u=d.fixation[0], fixation_v=d.fixation[1],
                                pass_index=d.pass_index)
        x0, y0, x1, y1 = d.box
        det.box.x_offset, det.box.y_offset = x0, y0
        det.box.width, det.box.height = x1 - x0 + 1, y1 - y0 + 1
        out.detections.append(det)
    return out


def overlay_boxes(detections: list[Detection]) -> list[Box]:
    """The overlay's boxes (core.overlay.Box) of detections' inclusive pixel boxes."""
    return [Box(d.box[0], d.box[1], d.box[2] - d.box[0] + 1, d.box[3] - d.box[1] + 1,
                d.label, d.score, d.pass_index) for d in detections]


def saccade_command(stamp: Any, frame_id: str, point: tuple[float, float, float],
                    source: str, priority: int, hold_time: float) -> Any:
    """The GazeCommand of a saccade (MODE_FIXATION_POINT, MOTION_SACCADE) to point in frame_id."""
    cmd = GazeCommand(mode=GazeCommand.MODE_FIXATION_POINT,
                      motion=GazeCommand.MOTION_SACCADE, source=source,
                      priority=priority, hold_time=float(hold_time))
    cmd.header.stamp = stamp
    cmd.header.frame_id = frame_id
    cmd.fixation_point.x, cmd.fixation_point.y, cmd.fixation_point.z = point
    return cmd

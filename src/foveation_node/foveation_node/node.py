"""The `foveation` node (thesis chapter 2): smooth foveal vision of the left camera stream.

Subscribes /vizzy/left/image_raw (sensor data QoS, rgb8 or bgr8), foveates each image at the
current fixation with core.foveation.Foveator (section 2.3.1) and publishes

  /foveation/image             sensor_msgs/Image, same encoding and header as the input
  /foveation/image/compressed  sensor_msgs/CompressedImage, format 'jpeg' (cv2.imencode at
                               jpeg_quality), same header

Every ~10 s it logs the bandwidth: the foveated frame's JPEG against the raw frame's JPEG at the
same quality (the raw one is encoded only for that one frame, not for every frame).

Fixation: (fixation_u, fixation_v) px, a negative coordinate meaning the image centre. With
follow_gaze, the fixation is the left camera's principal point (from /vizzy/left/camera_info):
the gaze controller points the optical axes at the fixation point of /gaze/state, so that point
projects onto the principal point; for the simulator's ideal cameras this is the image centre,
i.e. the default is already right for a head that fixates.

While /gaze/state says in_saccade, frames are dropped (saccadic suppression) if
suppress_during_saccades. Bad input (an unsupported encoding, zero size, a fixation outside the
image, too many levels for the image) is logged (throttled) and the frame skipped.
Algorithms live in foveation_node.core; this module only wires them to topics and parameters.
"""

from __future__ import annotations

import array
import math
import time
from typing import Any

import cv2
import numpy as np

from foveation_node.core.foveation import DEFAULT_F0, DEFAULT_LEVELS, PYRAMID_SIGMA_1, Foveator
from foveation_node.core.image_checks import check_fixation
from vizzy_runtime.convert import ConversionError, image_to_numpy, numpy_to_image
from vizzy_runtime.node_tools import declare_parameters, guarded, main_for
from vizzy_runtime.ros import USING_REAL_ROS, Node, message, qos_profile_sensor_data

Image = message('sensor_msgs/msg/Image')
CompressedImage = message('sensor_msgs/msg/CompressedImage')
CameraInfo = message('sensor_msgs/msg/CameraInfo')
GazeState = message('active_vision_msgs/msg/GazeState')

INPUT_TOPIC = '/vizzy/left/image_raw'
CAMERA_INFO_TOPIC = '/vizzy/left/camera_info'
GAZE_STATE_TOPIC = '/gaze/state'
OUTPUT_TOPIC = '/foveation/image'
COMPRESSED_TOPIC = '/foveation/image/compressed'
ENCODINGS = ('rgb8', 'bgr8')
BANDWIDTH_LOG_PERIOD_S = 10.0
WARN_PERIOD_S = 5.0
MAX_LEVELS = 10

# (name, default, description): the node declares exactly these.
PARAMETERS: tuple[tuple[str, Any, str], ...] = (
    ('levels', DEFAULT_LEVELS,
     f'Number of Laplacian pyramid levels K, in [1, {MAX_LEVELS}] (the image needs at least '
     '2^K px a side).'),
    ('f0', DEFAULT_F0, 'Fovea size f_0 [px] (level-k kernel size f_k = 2^k f_0), in (0, 1e5].'),
    ('sigma_1', PYRAMID_SIGMA_1,
     f'Gaussian sigma of pyramid level 1 [px], in [{PYRAMID_SIGMA_1:.4f}, 64] (the subsampled '
     'pyramid cannot realise less).'),
    ('fixation_u', -1.0, 'Fixation column [px]; negative: the image centre.'),
    ('fixation_v', -1.0, 'Fixation row [px]; negative: the image centre.'),
    ('follow_gaze', False,
     f'Fixate the principal point of {CAMERA_INFO_TOPIC} (where the gaze fixation point of '
     f'{GAZE_STATE_TOPIC} projects) instead of fixation_u/v.'),
    ('suppress_during_saccades', True,
     f'Drop frames while {GAZE_STATE_TOPIC} says in_saccade (saccadic suppression).'),
    ('jpeg_quality', 90, f'JPEG quality of {COMPRESSED_TOPIC}, in [1, 100].'),
    ('max_width', 4096, 'Widest accepted input image [px], in [1, 16384]; wider are dropped.'),
    ('max_height', 4096, 'Tallest accepted input image [px], in [1, 16384]; taller are dropped.'),
)
# Parameters whose change needs a new Foveator.
FOVEATOR_PARAMETERS = ('levels', 'f0', 'sigma_1')


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is."""
    if name in ('follow_gaze', 'suppress_during_saccades'):
        return None if isinstance(value, bool) else f'{name} must be true or false, got {value!r}'
    if not _is_number(value):
        return f'{name} must be a number, got {value!r}'
    if name in ('max_width', 'max_height') and not 1 <= value <= 16384:
        return f'{name} must be in [1, 16384] px, got {value}'
    if name == 'levels' and not 1 <= value <= MAX_LEVELS:
        return f'levels must be in [1, {MAX_LEVELS}], got {value}'
    if name == 'f0' and not (math.isfinite(value) and 0.0 < value <= 1e5):
        return f'f0 must be in (0, 1e5] px, got {value}'
    if name == 'sigma_1' and not (math.isfinite(value)
                                  and PYRAMID_SIGMA_1 - 1e-9 <= value <= 64.0):
        return (f'sigma_1 must be in [{PYRAMID_SIGMA_1:.4f}, 64] px (a subsampled pyramid '
                f'realises no less), got {value}')
    if name in ('fixation_u', 'fixation_v') and not math.isfinite(value):
        return f'{name} must be finite, got {value}'
    if name == 'jpeg_quality' and not 1 <= value <= 100:
        return f'jpeg_quality must be in [1, 100], got {value}'
    return None


def image_problem(msg: Any, max_width: int, max_height: int) -> str | None:
    """Why an input image cannot be used, or None if it can."""
    if msg.encoding not in ENCODINGS:
        return f'encoding {msg.encoding!r} is not one of {", ".join(ENCODINGS)}'
    if msg.width == 0 or msg.height == 0:
        return f'empty image ({msg.width}x{msg.height})'
    if msg.width > max_width or msg.height > max_height:
        return f'{msg.width}x{msg.height} exceeds max_width x max_height {max_width}x{max_height}'
    try:
        image_to_numpy(msg)
    except ConversionError as exc:
        return str(exc)
    return None


def fixation_for(width: int, height: int, u: float, v: float) -> tuple[float, float]:
    """The fixation (u0, v0) for a width x height image: a negative coordinate is the centre.

    Raises ValueError if the result lies outside the image.
    """
    u0 = (width - 1) / 2.0 if u < 0 else float(u)
    v0 = (height - 1) / 2.0 if v < 0 else float(v)
    return check_fixation((u0, v0), width, height)


def encode_jpeg(image: np.ndarray, encoding: str, quality: int) -> bytes:
    """JPEG bytes of an rgb8/bgr8 image (cv2 expects BGR; the file holds the true colours)."""
    bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if encoding == 'rgb8' else image
    ok, buf = cv2.imencode('.jpg', bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError('cv2.imencode failed to encode a JPEG')
    return buf.tobytes()


class FoveationNode(Node):
    """Foveates left images at the fixation; publishes them raw and as JPEG."""

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__('foveation', **node_kwargs)
        self._p = declare_parameters(self, PARAMETERS, check_parameter,
                                     on_change=self._on_parameters_changed)
        self._foveator: Foveator | None = None
        self._in_saccade = False
        self._principal_point: tuple[float, float] | None = None
        self._warned: dict[str, float] = {}
        self.frames_published = 0
        self.frames_suppressed = 0
        self._last_bandwidth_log = -math.inf
        self.last_bandwidth: tuple[int, int] | None = None   # (foveated, raw) JPEG bytes

        self._pub = self.create_publisher(Image, OUTPUT_TOPIC, qos_profile_sensor_data)
        self._jpeg_pub = self.create_publisher(CompressedImage, COMPRESSED_TOPIC,
                                               qos_profile_sensor_data)
        self.create_subscription(
            Image, INPUT_TOPIC, guarded(self, f'{INPUT_TOPIC}: failed on an image', self._on_image),
            qos_profile_sensor_data)
        self.create_subscription(
            GazeState, GAZE_STATE_TOPIC,
            guarded(self, f'{GAZE_STATE_TOPIC}: failed on a state', self._on_gaze_state), 10)
        self.create_subscription(
            CameraInfo, CAMERA_INFO_TOPIC,
            guarded(self, f'{CAMERA_INFO_TOPIC}: failed on a camera_info', self._on_camera_info),
            qos_profile_sensor_data)
        p = self._p
        self.get_logger().info(
            f'foveating {"/".join(ENCODINGS)} images from {INPUT_TOPIC} onto {OUTPUT_TOPIC} and '
            f'{COMPRESSED_TOPIC}: {p["levels"]} levels, f0 {p["f0"]:g} px, sigma_1 '
            f'{p["sigma_1"]:.4g} px, JPEG quality {p["jpeg_quality"]}')

    # --- inputs ---------------------------------------------------------------------------------

    def _on_parameters_changed(self, changed: dict[str, Any]) -> None:
        if any(name in changed for name in FOVEATOR_PARAMETERS):
            self._foveator = None   # rebuilt on the next frame, for that frame's size

    def _on_gaze_state(self, msg: Any) -> None:
        self._in_saccade = bool(msg.in_saccade)

    def _on_camera_info(self, msg: Any) -> None:
        k = list(msg.k)
        if len(k) == 9 and k[0] > 0 and math.isfinite(k[2]) and math.isfinite(k[5]):
            self._principal_point = (float(k[2]), float(k[5]))

    def _warn(self, kind: str, text: str) -> None:
        """A warning at most once every WARN_PERIOD_S per kind of problem."""
        now = time.monotonic()
        if now - self._warned.get(kind, -math.inf) >= WARN_PERIOD_S:
            self._warned[kind] = now
            self.get_logger().warning(text)

    def _fixation(self, width: int, height: int) -> tuple[float, float]:
        if self._p['follow_gaze'] and self._principal_point is not None:
            return check_fixation(self._principal_point, width, height)
        return fixation_for(width, height, self._p['fixation_u'], self._p['fixation_v'])

    def _get_foveator(self, width: int, height: int) -> Foveator:
        fov = self._foveator
        if fov is None or (fov.width, fov.height) != (width, height):
            fov = Foveator(width, height, self._p['levels'], self._p['f0'], self._p['sigma_1'])
            self._foveator = fov
        return fov

    def _on_image(self, msg: Any) -> None:
        if self._in_saccade and self._p['suppress_during_saccades']:
            self.frames_suppressed += 1
            return
        problem = image_problem(msg, self._p['max_width'], self._p['max_height'])
        if problem:
            self._warn('image', f'{INPUT_TOPIC}: dropped image: {problem}')
            return
        image = image_to_numpy(msg)
        height, width = image.shape[:2]
        try:
            fixation = self._fixation(width, height)
            foveator = self._get_foveator(width, height)
        except ValueError as exc:
            self._warn('setup', f'{INPUT_TOPIC}: dropped image: {exc}')
            return
        out = foveator.foveate(image, fixation)
        self._pub.publish(numpy_to_image(out, msg.encoding, header=msg.header))

        quality = self._p['jpeg_quality']
        jpeg = encode_jpeg(out, msg.encoding, quality)
        compressed = CompressedImage(format='jpeg')
        compressed.header = msg.header
        compressed.data = (array.array('B', jpeg) if USING_REAL_ROS
                           else np.frombuffer(jpeg, np.uint8))
        self._jpeg_pub.publish(compressed)
        self.frames_published += 1
        self._report_bandwidth(image, msg.encoding, len(jpeg), quality, fixation)

    def _report_bandwidth(self, image: np.ndarray, encoding: str, foveated_bytes: int,
                          quality: int, fixation: tuple[float, float]) -> None:
        """Every BANDWIDTH_LOG_PERIOD_S: this frame's JPEG size, foveated vs raw."""
        now = time.monotonic()
        if now - self._last_bandwidth_log < BANDWIDTH_LOG_PERIOD_S:
            return
        self._last_bandwidth_log = now
        raw_bytes = len(encode_jpeg(image, encoding, quality))
        self.last_bandwidth = (foveated_bytes, raw_bytes)
        saved = 100.0 * (1.0 - foveated_bytes / raw_bytes) if raw_bytes else 0.0
        height, width = image.shape[:2]
        self.get_logger().info(
            f'bandwidth: {width}x{height} JPEG q{quality}: foveated {foveated_bytes} B vs raw '
            f'{raw_bytes} B ({saved:.0f}% saved), f0 {self._p["f0"]:g} px at '
            f'({fixation[0]:g}, {fixation[1]:g}); {self.frames_published} frames published, '
            f'{self.frames_suppressed} suppressed during saccades')


main = main_for(FoveationNode)


if __name__ == '__main__':
    main()

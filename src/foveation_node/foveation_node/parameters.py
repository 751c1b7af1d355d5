"""The foveation node's topic names and parameter table, with the rules the table's ranges cannot
express (check_parameter) and the package:// paths of model_path / labels_path (resolve_path).
The node (node.py) declares these.

model_path / labels_path: a TorchScript file and
its labels (package://foveation_node/... means inside the installed package; an empty
model_path disables recognition); a path that is no file is refused like any bad parameter value
(at start-up: one line and exit 2); a file that does not load is logged and recognition stays off.
The default model (fovea_cnn, a window model: it sees the 160 px window around each pass's
fixation) knows the simulator's 7 object classes and 'background' (the reject class,
core.recognition.BACKGROUND_LABEL: never published as a detection, localised or saccaded to; a
pass-2 label must beat it on its own image, so a view of a wall gives no pass-2 detection); for
real scenes, point model_path / labels_path at an ImageNet network written by
export_imagenet_classifier (EfficientNet-Lite).
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from typing import Any

from foveation_node.core.foveation import DEFAULT_F0, DEFAULT_LEVELS, PYRAMID_SIGMA_1
from foveation_node.core.recognition import DEFAULT_THRESHOLD, DEFAULT_TOP_K, ModelError
from vizzy_runtime.node_tools import Param

# Relative names: the graph remaps the generic inputs (image_raw:=vizzy/left/image_raw, ...) and
# the node's namespace places everything; logs print the resolved names.
INPUT_TOPIC = 'image_raw'
CAMERA_INFO_TOPIC = 'camera_info'
GAZE_STATE_TOPIC = 'gaze/state'
OUTPUT_TOPIC = '~/image'
COMPRESSED_TOPIC = '~/image/compressed'
DETECTIONS_TOPIC = '~/detections'
DETECTIONS_2D_TOPIC = '~/detections_2d'
OVERLAY_TOPIC = '~/overlay'
GAZE_COMMAND_TOPIC = 'gaze/command'
GAZE_SOURCE = 'foveation'
GAZE_PRIORITY = 30          # saccades: above stereo_ses (20) and mot_planner (10)
# the window model (sees the 160 px around each pass's fixation; docs/foveation.md, "The window
# model"); the whole-frame model foveation_cnn.pt stays beside it
DEFAULT_MODEL = 'package://foveation_node/models/fovea_cnn.pt'
DEFAULT_LABELS = 'package://foveation_node/models/fovea_cnn.labels'
MAX_LEVELS = 10

# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('levels', DEFAULT_LEVELS,
          f'Number of Laplacian pyramid levels K, in [1, {MAX_LEVELS}] (the image needs at '
          'least 2^K px a side).', f'[1, {MAX_LEVELS}]'),
    Param('f0', DEFAULT_F0,
          'Fovea size f_0 [px] (level-k kernel size f_k = 2^k f_0), in (0, 1e5].', '(0, 1e5]'),
    Param('sigma_1', PYRAMID_SIGMA_1,
          f'Gaussian sigma of pyramid level 1 [px], in [{PYRAMID_SIGMA_1:.4f}, 64] (the '
          'subsampled pyramid cannot realise less).', f'[{PYRAMID_SIGMA_1!r}, 64]',
          constraints='the lower bound is exact (no 1e-6 edge tolerance)'),
    Param('fixation_u', -1.0, 'Fixation column [px], in [-16384, 16384] (max_width\'s '
          'bound); negative: the image centre.', '[-16384, 16384]'),
    Param('fixation_v', -1.0, 'Fixation row [px], in [-16384, 16384] (max_height\'s '
          'bound); negative: the image centre.', '[-16384, 16384]'),
    Param('space_variant', True,
          'Foveate (thesis chapter 2). False: the uniform-resolution baseline: the published '
          'image and recognition use the unfoveated frame (a window model: every window of a '
          'grid over it, see uniform_stride_px; bench/active_perception.py\'s uniform '
          'configuration).'),
    Param('uniform_stride_px', 40,
          'With space_variant false and a window model: the stride [px] of the grid of windows '
          'recognised over the whole frame (the uniform baseline), in [8, 1024].', '[8, 1024]'),
    Param('follow_gaze', False,
          f'Fixate the principal point of {CAMERA_INFO_TOPIC} (where the gaze fixation point of '
          f'{GAZE_STATE_TOPIC} projects) instead of fixation_u/v.'),
    Param('suppress_during_saccades', True,
          f'Drop frames while {GAZE_STATE_TOPIC} says in_saccade (saccadic suppression).'),
    Param('jpeg_quality', 90, f'JPEG quality of {COMPRESSED_TOPIC}, in [1, 100].', '[1, 100]'),
    Param('publish_overlay', True, f'Publish each recognised frame, foveated, with both passes\' '
          f'boxes, the fixation and the fovea drawn on it, on {OVERLAY_TOPIC}.'),
    Param('max_width', 4096, 'Widest accepted input image [px], in [1, 16384]; wider are '
          'dropped.', '[1, 16384]'),
    Param('max_height', 4096, 'Tallest accepted input image [px], in [1, 16384]; taller are '
          'dropped.', '[1, 16384]'),
    Param('model_path', DEFAULT_MODEL,
          'TorchScript classifier (preprocessing from the .json beside it, else ImageNet '
          '227x227); package://<pkg>/<path> is inside an installed package; empty: no '
          'recognition.'),
    Param('labels_path', DEFAULT_LABELS, 'Class labels of model_path, one per line.'),
    Param('saliency_threshold', DEFAULT_THRESHOLD,
          'Saliency mask threshold th (fraction of the map maximum), in (0, 1].', '(0, 1]'),
    Param('top_k', DEFAULT_TOP_K, 'Classes localised per pass (top-k), in [1, 100].',
          '[1, 100]'),
    Param('recognition_rate_hz', 2.0,
          'Most recognitions (two passes) started per second, in [0.01, 100]; the newest frame '
          'wins.', '[0.01, 100]'),
    Param('recognition_threads', 1, 'Torch CPU threads for recognition, in [1, 64].',
          '[1, 64]'),
    Param('saccades_enabled', True,
          f'Send saccades to the best detected object on {GAZE_COMMAND_TOPIC} (priority '
          f'{GAZE_PRIORITY}).'),
    Param('saccade_hold_time_s', 1.0, 'hold_time of the saccade GazeCommands [s], in [0, 60].',
          '[0, 60]'),
    Param('saccade_min_interval_s', 2.0, 'Least time between two saccades [s], in [0, 600].',
          '[0, 600]'),
    Param('saccade_distance_m', 1.0,
          'Distance along the pixel ray of the fixation point sent [m], in [0.1, 20].',
          '[0.1, 20]'),
    Param('saccade_min_score', 0.3, 'Least class probability worth a saccade, in [0, 1].',
          '[0, 1]'),
    Param('saccade_min_offset_px', 20.0,
          'No saccade to a box centre this near the principal point [px], in [0, 10000].',
          '[0, 10000]'),
)
# Parameters whose change needs a new Foveator.
FOVEATOR_PARAMETERS = ('levels', 'f0', 'sigma_1')
MODEL_PARAMETERS = ('model_path', 'labels_path', 'recognition_threads')


def resolve_path(path: str) -> Path:
    """A file path; package://<pkg>/<rest> is <rest> inside Python package <pkg>'s directory."""
    if path.startswith('package://'):
        pkg, _, rest = path[len('package://'):].partition('/')
        spec = importlib.util.find_spec(pkg) if pkg else None
        if spec is None or not spec.submodule_search_locations:
            raise ModelError(f'{path}: no installed package {pkg!r}')
        return Path(list(spec.submodule_search_locations)[0]) / rest
    return Path(path).expanduser()


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name, or None if it is: the rules the table's
    ranges cannot express (types and ranges are the descriptors', see PARAMETERS)."""
    if name == 'sigma_1' and value < PYRAMID_SIGMA_1 - 1e-9:
        # the Foveator's own floor, without the range's 1e-6 relative edge tolerance
        return (f'sigma_1 must be at least {PYRAMID_SIGMA_1:.4f} px (a subsampled pyramid '
                f'realises no less), got {value}')
    if name in ('fixation_u', 'fixation_v') and not math.isfinite(value):
        return f'{name} must be finite, got {value}'
    if name in ('model_path', 'labels_path') and value:
        try:
            path = resolve_path(value)
        except ModelError as exc:
            return str(exc)
        if not path.is_file():
            return f'no such file {path}'
    return None

"""The `object_map` node's parameters: the declared table (names, defaults, ranges, help) and what
the ranges cannot express (check_parameter, check_all). ROS-free apart from the Param records; the
node (node.py) declares and wires them."""

from __future__ import annotations

from typing import Any

from vizzy_object_map.core.object_map import MapConfig
from vizzy_runtime.node_tools import Param

STEREO_TOPIC = 'stereo/points'
GAZE_COMMAND_TOPIC = 'gaze/command'

_DEFAULTS = MapConfig()
# The node declares exactly these; each range is the descriptor's, enforced by the middleware.
PARAMETERS: tuple[Param, ...] = (
    Param('map_frame', 'base_link', 'Frame of the map (fixed to the robot, z up).',
          constraints='not empty'),
    Param('publish_period_s', 0.5, 'Publish the map (and forget faded objects) this often [s], '
          'in [0.05, 60].', '[0.05, 60]'),
    Param('association_radius_m', _DEFAULTS.association_radius_m,
          'An observation within this of an object\'s centre is that object [m], in (0, 1].',
          '(0, 1]'),
    Param('merge_radius_m', _DEFAULTS.merge_radius_m,
          'Objects whose centres come closer than this become one [m], in (0, 1].', '(0, 1]'),
    Param('merge_overlap', _DEFAULTS.merge_overlap,
          'Objects whose boxes overlap by at least this share of the smaller box become one, '
          'in (0, 1].', '(0, 1]'),
    Param('min_recognition_score', _DEFAULTS.min_recognition_score,
          'Recognitions scoring less are ignored, in [0, 1].', '[0, 1]'),
    Param('min_pass', 0, 'Use the detections of foveation passes min_pass to max_pass (0: the '
          'first, at the gaze fixation; 1: the refined one at each box centre), in [0, 255].',
          '[0, 255]'),
    Param('max_pass', 0, 'The last foveation pass used (see min_pass), in [0, 255]: the first '
          'pass names the object the eyes fixate; the second pass\'s fixations land on object '
          'edges and neighbours.', '[0, 255]', constraints='at least min_pass'),
    Param('min_recognitions', _DEFAULTS.min_recognitions,
          'An object geometry has seen is confirmed after this many recognitions named it, in '
          '[1, 1000].', '[1, 1000]'),
    Param('min_recognitions_without_geometry', _DEFAULTS.min_recognitions_without_geometry,
          'An object only recognitions placed (stereo depth) is confirmed after this many, in '
          '[1, 1000].', '[1, 1000]'),
    Param('min_label_share', _DEFAULTS.min_label_share,
          'A confirmed object\'s name holds at least this share of its name evidence (the '
          'reject label counting against it), in [0, 1].', '[0, 1]'),
    Param('established_geometry', _DEFAULTS.established_geometry,
          'Objects segmented this many times are kept while out of view, in [1, 1000].',
          '[1, 1000]'),
    Param('tentative_timeout_s', _DEFAULTS.tentative_timeout_s,
          'Objects neither established nor confirmed are forgotten this long after they were '
          'last seen [s], in [0.1, 3600].', '[0.1, 3600]'),
    Param('reject_label', _DEFAULTS.reject_label,
          'The recogniser\'s "nothing here" label: it names nothing and counts against names.'),
    Param('use_stereo_depth', False,
          f'Place recognitions that fall on no known object with the depth of {STEREO_TOPIC} '
          '(off by default: the surface under the pixel is often not the object the window '
          'names, e.g. the floor seen past a thin handle; for scenes without segmentation).'),
    Param('stereo_max_age_s', 3.0,
          f'Use a {STEREO_TOPIC} cloud for at most this long after its stamp [s], in (0, 60].',
          '(0, 60]'),
    Param('depth_radius_px', 6.0, 'Depth points within this of a recognition\'s pixel place it '
          '[px], in (0, 100].', '(0, 100]'),
    Param('tf_history_s', 5.0, 'How long the sensors\' poses are kept for inputs stamped in the '
          'past [s], in (0, 60].', '(0, 60]'),
    Param('looks_enabled', True,
          f'Send saccades on {GAZE_COMMAND_TOPIC} to the objects placed but not yet named '
          '(core.attention: the task bias, with inhibition of return).'),
    Param('gaze_priority', 35, 'Priority of those saccades, in [0, 1000] (foveation 30, '
          'stereo_ses 20, mot_planner 10).', '[0, 1000]'),
    Param('dwell_s', 1.0, 'Time on a settled fixation before the next look [s] (the '
          'recogniser needs about two results), in [0, 60].', '[0, 60]'),
    Param('max_looks', 3, 'Looks at an object that stays unnamed before it is given up, in '
          '[1, 100].', '[1, 100]'),
)
MAP_PARAMETERS = ('association_radius_m', 'merge_radius_m', 'merge_overlap',
                  'min_recognition_score',
                  'min_recognitions', 'min_recognitions_without_geometry', 'min_label_share',
                  'established_geometry', 'tentative_timeout_s', 'reject_label')


def check_parameter(name: str, value: Any) -> str | None:
    """Why value is not acceptable for parameter name (beyond the table's ranges), or None."""
    if name == 'map_frame' and not value.strip('/'):
        return 'map_frame must be a frame id'
    return None


def check_all(values: dict[str, Any]) -> str | None:
    """What is wrong with the parameters taken together, or None."""
    if values['max_pass'] < values['min_pass']:
        return f'max_pass ({values["max_pass"]}) must be at least min_pass ({values["min_pass"]})'
    return None

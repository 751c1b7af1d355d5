"""The Foxglove layout for the graph (config/foxglove_layout.json), built with foxglove-sdk's layout
types so that it stays valid for the app.

    python -m vizzy_runtime.foxglove_layout [-o config/foxglove_layout.json]

Left: both cameras, the foveation overlay (detections of both passes, fixation, fovea), the
tracker's overlay, the cylinders on the RGB-D image and the foveated stream. Middle: a 3D view in
base_link with the head model (robot_description), tf, the stereo points and the ego-sphere cells
coloured by information (-log|Sigma|, Eq. 3.45), the cylinders and the simulator's ground-truth
objects. Right: the gaze state over time (version, vergence, tilt; saccades), diagnostics and
the log.
test_foxglove.py checks that the file is what this module writes and names only topics of the graph.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import foxglove.layouts as fl

FIXED_FRAME = 'base_link'
LAYOUT_FILE = Path(__file__).resolve().parent.parent / 'config' / 'foxglove_layout.json'

IMAGES = (('/vizzy/left/image_raw', 'Left camera'), ('/vizzy/right/image_raw', 'Right camera'),
          ('/foveation/overlay', 'Foveated image: detections by pass, fixation, fovea'),
          ('/mot/overlay', 'Tracks and attention regions'),
          ('/cylinders/overlay', 'Cylinders on the RGB-D image'),
          ('/foveation/image', 'Foveated stream'))
GAZE_SERIES = (('/gaze/state.version', 'version [rad]'), ('/gaze/state.vergence', 'vergence [rad]'),
               ('/gaze/state.tilt', 'tilt [rad]'), ('/gaze/state.in_saccade', 'in saccade'))


def _image(topic: str, title: str) -> fl.ImagePanel:
    return fl.ImagePanel(title=title,
                         config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=topic)))


def _by_information(size: float) -> fl.BaseRendererPointCloudTopicSettings:
    return fl.BaseRendererPointCloudTopicSettings(
        visible=True, point_size=size, color_mode='colormap', color_field='information',
        color_map='turbo')


def scene() -> fl.ThreeDeePanel:
    topics: dict[str, fl.BaseRendererTopicSettings] = {
        '/stereo/points': _by_information(3.0),
        '/ses/cells': _by_information(8.0),
        '/cylinders/markers': fl.BaseRendererRosMarkerTopicSettings(visible=True),
        '/objects/markers': fl.BaseRendererRosMarkerTopicSettings(visible=True),
        '/sim/ground_truth/objects': fl.BaseRendererRosMarkerTopicSettings(
            visible=True, color='#ffffff55'),
    }
    layers: dict[str, fl.BaseRendererCustomLayerSettings] = {
        'grid': fl.BaseRendererGridLayerSettings(frame_id=FIXED_FRAME, size=4, divisions=8),
        'head': fl.BaseRendererUrdfLayerSettings(source_type='topic', topic='/robot_description'),
    }
    return fl.ThreeDeePanel(title='Head, 3D points, ego-sphere, cylinders, object map',
                            config=fl.ThreeDeeConfig(
        follow_tf=FIXED_FRAME, fixed_frame=FIXED_FRAME, topics=topics, layers=layers))


def layout() -> fl.Layout:
    images = fl.SplitContainer(direction='column', items=[
        fl.SplitItem(content=fl.SplitContainer(direction='row', items=[
            fl.SplitItem(content=_image(*IMAGES[i])),
            fl.SplitItem(content=_image(*IMAGES[i + 1]))]))
        for i in range(0, len(IMAGES), 2)
    ])
    gaze = fl.PlotPanel(title='Gaze state', config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=value, label=label) for value, label in GAZE_SERIES]))
    side = fl.SplitContainer(direction='column', items=[
        fl.SplitItem(content=gaze),
        fl.SplitItem(content=fl.DiagnosticsSummaryPanel(title='Diagnostics')),
        fl.SplitItem(content=fl.LogPanel(title='/rosout')),
    ])
    return fl.Layout(content=fl.SplitContainer(direction='row', items=[
        fl.SplitItem(proportion=2, content=images), fl.SplitItem(proportion=2, content=scene()),
        fl.SplitItem(proportion=1, content=side),
    ]))


def layout_json() -> str:
    """The layout as the file holds it (indented, so that a diff of it can be read)."""
    return json.dumps(json.loads(layout().to_json()), indent=2) + '\n'


def topics_named(data: object) -> set[str]:
    """Every topic a layout JSON names (image topics, 3D topics and layers, plot paths)."""
    found: set[str] = set()

    def walk(node: object, key: str = '') -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                if k == 'topics' and isinstance(v, dict):
                    found.update(v)
                walk(v, k)
        elif isinstance(node, list):
            for v in node:
                walk(v, key)
        elif isinstance(node, str) and node.startswith('/'):
            if key in ('imageTopic', 'topic'):
                found.add(node)
            elif key == 'value':
                found.add(node.split('.', 1)[0])
    walk(data)
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('-o', '--output', type=Path, default=None,
                        help='write here (default: stdout)')
    ns = parser.parse_args(argv)
    if ns.output is None:
        sys.stdout.write(layout_json())
    else:
        ns.output.write_text(layout_json())
    return 0


if __name__ == '__main__':
    sys.exit(main())

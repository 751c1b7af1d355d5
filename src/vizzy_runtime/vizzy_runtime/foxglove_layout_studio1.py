"""The shipped Foxglove layout in the layout format of Foxglove Studio 1.x and of Lichtblick
(config/foxglove_layout_studio1.json), converted from foxglove_layout.py's.

    python -m vizzy_runtime.foxglove_layout_studio1 [-o config/foxglove_layout_studio1.json]

config/foxglove_layout.json is written with foxglove-sdk's layout types, the format of the current
Foxglove app (a tree of "split" and "panel" nodes, panel types such as ThreeDee and Log): Studio 1.x
and Lichtblick cannot import it. They take {configById, layout, globalVariables, userNodes,
playbackConfig}, where layout is a binary react-mosaic tree of panel ids ("3D!...") and each panel's
config is keyed by its id. The same panels, titles and topics, in that format: Image becomes
ImageViewPanel (its cameraTopic; the 3D-based image panel reads the same key), ThreeDee 3D
(layers keyed by their instanceId; the URDF layer reading a topic becomes that topic's entry, the
only way Studio 1.x draws a URDF topic), DiagnosticsSummary DiagnosticSummary, Log RosOut, Plot
Plot (series on receive time). test_live_view_browser.py loads it into Foxglove Studio 1.48 in
headless Chromium.
"""

from __future__ import annotations

import argparse
import copy
import json
import re
import sys
from pathlib import Path
from typing import Any

from .foxglove_layout import LAYOUT_FILE, layout_json

STUDIO1_LAYOUT_FILE = LAYOUT_FILE.with_name('foxglove_layout_studio1.json')
# Studio 1.x's key for a panel's own title in its config.
TITLE_KEY = 'foxglovePanelTitle'
# The current app's panel type -> Studio 1.x's.
PANEL_TYPES = {'Image': 'ImageViewPanel', 'ThreeDee': '3D', 'Plot': 'Plot',
               'DiagnosticsSummary': 'DiagnosticSummary', 'Log': 'RosOut'}


def _panel_config(panel_type: str, config: dict[str, Any]) -> dict[str, Any]:
    config = copy.deepcopy(config)
    if panel_type == 'Image':
        topic = config.get('imageMode', {}).get('imageTopic')
        return {'cameraTopic': topic, **config}
    if panel_type == 'ThreeDee':
        config.pop('fixedFrame', None)   # Studio 1.x's display frame is followTf
        layers = config.get('layers', {})
        for key, layer in list(layers.items()):
            if layer.get('layerId') == 'foxglove.Urdf' and layer.get('sourceType') == 'topic':
                # Studio 1.x draws a URDF topic as a topic entry; its URDF layers take only a URL
                del layers[key]
                config.setdefault('topics', {})[layer.get('topic', '/robot_description')] = {
                    'visible': True}
            else:
                layer.setdefault('instanceId', key)
        return config
    if panel_type == 'Plot':
        config['paths'] = [{'enabled': True, 'timestampMethod': 'receiveTime', **path}
                           for path in config.get('paths', [])]
        return config
    return config


def convert(data: dict[str, Any]) -> dict[str, Any]:
    """A layout of the current Foxglove app (as foxglove_layout.json holds it) in Studio 1.x's
    format. ValueError names a node this cannot convert (an unknown panel type, an empty split)."""
    config_by_id: dict[str, dict[str, Any]] = {}

    def panel(node: dict[str, Any]) -> str:
        kind = node.get('panelType', '')
        if kind not in PANEL_TYPES:
            raise ValueError(f'panel type {kind!r} has no Studio 1.x counterpart here '
                             f'(known: {", ".join(sorted(PANEL_TYPES))})')
        slug = re.sub(r'[^a-z0-9]+', '_', str(node.get('title') or kind).lower()).strip('_')[:32]
        panel_id = f'{PANEL_TYPES[kind]}!{slug}'
        n = 2
        while panel_id in config_by_id:
            panel_id, n = f'{PANEL_TYPES[kind]}!{slug}_{n}', n + 1
        config = _panel_config(kind, node.get('config') or {})
        if node.get('title'):
            config[TITLE_KEY] = node['title']
        config_by_id[panel_id] = config
        return panel_id

    def tree(node: dict[str, Any]) -> Any:
        if node.get('type') == 'panel':
            return panel(node)
        if node.get('type') != 'split':
            raise ValueError(f'layout node of type {node.get("type")!r}: expected split or panel')
        items = node.get('items') or []
        if not items:
            raise ValueError('a split with no items')
        return split(items, node.get('direction', 'row'))

    def split(items: list[dict[str, Any]], direction: str) -> Any:
        first = tree(items[0]['content'])
        if len(items) == 1:
            return first
        weights = [float(item.get('proportion', 1)) for item in items]
        return {'direction': direction, 'first': first, 'second': split(items[1:], direction),
                'splitPercentage': round(100 * weights[0] / sum(weights), 3)}

    layout = tree(data['content'])
    return {'configById': config_by_id, 'globalVariables': {}, 'userNodes': {},
            'playbackConfig': {'speed': 1.0}, 'layout': layout}


def studio1_layout_json() -> str:
    """The file's text: the shipped layout converted (indented, so that a diff can be read)."""
    return json.dumps(convert(json.loads(layout_json())), indent=2) + '\n'


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('-o', '--output', type=Path, default=None,
                        help='write here (default: stdout)')
    ns = parser.parse_args(argv)
    if ns.output is None:
        sys.stdout.write(studio1_layout_json())
    else:
        ns.output.write_text(studio1_layout_json())
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""ONE-OFF (issue 16): add the `protocol` object to results JSON files committed before it existed.

Scripts write `protocol` themselves since issue 16. For the committed files that were not re-run,
this states it with each script's own `protocol_of` function (the same one the script calls when
it writes), applied to the file's own fields, so nothing is typed here except what a file does
not record: which mot_budget command wrote each mot_budget file (from docs/mot_planner.md) and
the detect_file outputs' provenance. No number is invented; `cpu_s` is left out where the file
did not record CPU time. Files that already carry a protocol are left alone. Nothing else in a
file changes (same keys, values and indentation).

    .venv/bin/python experiments/patch_protocols.py [--dry-run]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / 'results'
sys.path.insert(0, str(HERE))

# what the files do not record: the mot_budget command lines (docs/mot_planner.md, "Budget sweep")
MOT_MODES = {'mot_budget_mot17-mini.json': ('none', 'centres'),
             'mot_budget_sim_pedestrians.json': ('periodic', 'centres'),
             'mot_budget_sim_pedestrians_thesis_protocol.json': ('none', 'centres'),
             'mot_budget_synthetic.json': (None, None)}


def protocol_for(name: str, d: dict) -> dict | None:
    """The protocol of committed file `name` with content `d`, from its script's protocol_of."""
    if name == 'active_search.json':
        import active_search
        return active_search.protocol_of(d)
    if name == 'cylinder_pipeline.json':
        import cylinder_pipeline
        return cylinder_pipeline.protocol_of(d)
    if name == 'cylinder_plane_choice.json':
        import cylinder_plane_choice
        return cylinder_plane_choice.protocol_of(d)
    if name == 'fovea_information.json':
        import fovea_information
        return fovea_information.protocol_of(d)
    if name == 'sensor_characterization.json':
        import sensor_characterization
        return sensor_characterization.protocol_of(d)
    if name.startswith('pedestrian_hog_check'):
        import pedestrian_hog_check
        return pedestrian_hog_check.protocol_of(d)
    if name in MOT_MODES:
        import mot_budget
        new_tracks, area = MOT_MODES[name]
        return mot_budget.protocol_of(d, new_tracks=new_tracks, area=area)
    if name == 'foveated_recognition.json':
        import foveated_recognition
        return foveated_recognition.protocol_views(d)
    if name.startswith('foveated_recognition_tabletop'):
        import foveated_recognition
        p = foveated_recognition.protocol_tabletop(d)
        if 'note' in d:
            p['differs_from_thesis'].append(d['note'])
        return p
    if name == 'foveated_recognition_imagenet.json':
        import foveated_recognition
        return foveated_recognition.protocol_folder(d, sum(d['cpu_s'].values()))
    if name.startswith('detect_file_') or name.startswith('cylinder_detect_file_'):
        from protocol import protocol
        return protocol(
            data=f"one point-cloud file ({d['file']}; {d['n_points']} points)",
            repetitions=1, thesis_repetitions=None,
            models=('packaged pre-attention patch CNN' if d.get('classifier') else 'none')
            + f" + Hough fitting ({d['method']}, {d['bias']} prior)",
            differs_from_thesis=['written by `detect_file` (src/cylinder_detector_node), not by '
                                 'experiments/: a qualitative example in the spirit of Fig. 4.6'])
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--dry-run', action='store_true')
    args = ap.parse_args()
    for path in sorted(RESULTS.glob('*.json')):
        text = path.read_text()
        d = json.loads(text)
        if 'protocol' in d:
            print(f'{path.name}: has a protocol')
            continue
        p = protocol_for(path.name, d)
        if p is None:
            print(f'{path.name}: NO protocol_of for this file', file=sys.stderr)
            continue
        d['protocol'] = p
        lines = text.splitlines()
        indent = len(lines[1]) - len(lines[1].lstrip(' ')) if len(lines) > 1 else 1
        out = json.dumps(d, indent=indent) + ('\n' if text.endswith('\n') else '')
        print(f'{path.name}: {json.dumps(p)[:160]}...')
        if not args.dry_run:
            path.write_text(out)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

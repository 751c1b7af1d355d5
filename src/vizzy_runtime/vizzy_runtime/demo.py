"""`make demo`: run the graph in simulation for a while, record everything to a bag, say what
happened.

    .venv/bin/python -m vizzy_runtime.demo [--duration 20] [--output bags/demo_<time>]
                                           [--view-port 8765 | --no-view]

The graph is vizzy_runtime's config/graph.yaml (the one `ros2 launch vizzy_runtime graph.launch.py`
starts). The bag is a rosbag2 (MCAP) directory; the summary lists each topic's type, count and
rate, each node's exit status, the perception outputs, and saves a picture of both cameras and a
one-page summary (demo_summary.py). Meanwhile the graph is served to Foxglove (live_view.py).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from . import msgs
from .bag import BagReader, Recorder
from .convert import image_to_numpy
from .launcher import Launcher, LaunchStopped, default_graph_file, load_graph, stop_on_signals

REPO = Path(__file__).resolve().parents[3]
# Topics whose appearance means the graph is up (the camera stream and the gaze loop).
READY_TOPICS = ('/vizzy/left/image_raw', '/gaze/state')
# Not recorded by the demo: 4.9 MB per organized cloud would make most of the bag, and the cloud
# is the depth image (recorded) back-projected with the recorded RGB-D camera_info.
# The cloud (4.9 MB a frame) and the cameras' JPEG copies of images the bag holds raw (recording
# them would make the sim encode ~32 JPEGs a second for nothing).
DEMO_EXCLUDE = ('/vizzy/rgbd/points', '/vizzy/left/image_raw/compressed',
                '/vizzy/right/image_raw/compressed', '/vizzy/rgbd/image_raw/compressed')


def _wait_for_graph(timeout: float) -> bool:
    from . import dds
    disc = dds.Discovery()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        writers = {ep.topic for ep in disc.endpoints() if ep.is_writer}
        if all(t in writers for t in READY_TOPICS):
            return True
        time.sleep(0.1)
    return False


def _describe(typename: str, msg: Any) -> str:
    """One line about a perception output."""
    short = typename.split('/')[-1]
    for field in ('tracks', 'cylinders', 'detections', 'regions'):
        if hasattr(msg, field):
            return f'{len(getattr(msg, field))} {field}'
    if short == 'GazeState':
        p = msg.fixation_point
        return (f'fixation ({p.x:.2f}, {p.y:.2f}, {p.z:.2f}) in {msg.header.frame_id or "?"}, '
                f'in_saccade={msg.in_saccade}')
    if short == 'PointCloud2':
        return f'{msg.width * msg.height} points'
    if short == 'Image':
        return f'{msg.width}x{msg.height} {msg.encoding}'
    return short


class _Story:
    """What the graph did, from the messages that say so: who held the gaze, what was found."""

    def __init__(self) -> None:
        self.commands: Counter[str] = Counter()        # GazeCommands per source
        self.holder: Counter[str] = Counter()          # GazeStates per active_source
        self.saccades = 0
        self._was_in_saccade = False
        self.most: dict[str, int] = {}                 # topic -> most items in one message
        self.labels: Counter[str] = Counter()          # foveation's best final-pass label
        self.last_map: Any = None                      # the last /objects/map

    def add(self, topic: str, msg: Any) -> None:
        if topic == '/gaze/command':
            self.commands[msg.source or '?'] += 1
        elif topic == '/gaze/state':
            self.holder[msg.active_source or 'idle'] += 1
            self.saccades += msg.in_saccade and not self._was_in_saccade
            self._was_in_saccade = msg.in_saccade
        elif topic == '/objects/map':
            self.last_map = msg
        for field in ('tracks', 'cylinders', 'detections'):
            items = getattr(msg, field, None)
            if items is not None:
                self.most[topic] = max(self.most.get(topic, 0), len(items))
                if field == 'detections' and len(items):
                    last_pass = max(d.pass_index for d in items)
                    best = max((d for d in items if d.pass_index == last_pass),
                               key=lambda d: d.score)
                    self.labels[best.label] += 1

    def lines(self) -> list[str]:
        out = []
        if self.holder:
            total = sum(self.holder.values())
            shares = ', '.join(f'{k} {100 * v / total:.0f}%' for k, v in self.holder.most_common())
            out.append(f'gaze held by: {shares} of the time; {self.saccades} saccades')
        if self.commands:
            out.append('gaze commands: '
                       + ', '.join(f'{k} {v}' for k, v in self.commands.most_common()))
        for topic, n in sorted(self.most.items()):
            out.append(f'{topic}: at most {n} in one message')
        if self.labels:
            out.append('foveation best label per recognition: '
                       + ', '.join(f'{k} x{v}' for k, v in self.labels.most_common(5)))
        if self.last_map is not None:
            objects = list(self.last_map.objects)
            named = Counter(o.label for o in objects if o.confirmed)
            unnamed = sum(o.established and not o.confirmed for o in objects)
            out.append(f'object map at the end: {sum(named.values())} confirmed'
                       + (' (' + ', '.join(f'{k} x{v}' for k, v in sorted(
                           named.items(), key=lambda kv: (-kv[1], kv[0]))) + ')'
                          if named else '')
                       + f', {unnamed} established unconfirmed, '
                       f'{len(objects) - sum(named.values()) - unnamed} tentative '
                       '(scored against the ground truth on summary.png)')
        return out


STORY_TOPICS = ('/gaze/command', '/gaze/state', '/cylinders', '/mot/tracks',
                '/foveation/detections', '/objects/map')


def summarize(bag_dir: Path, out_dir: Path) -> dict[str, Any]:
    reader = BagReader(bag_dir)
    last: dict[str, tuple[str, bytes]] = {}
    first_images: dict[str, np.ndarray] = {}
    stamps: dict[str, list[int]] = {}
    story = _Story()
    for topic, typename, data, log_ns, _pub_ns in reader.messages():
        stamps.setdefault(topic, []).append(log_ns)
        last[topic] = (typename, data)
        if topic in STORY_TOPICS:
            try:
                story.add(topic, msgs.deserialize(data, typename))
            except Exception as err:  # noqa: BLE001 - the summary goes on without it
                print(f'demo: cannot decode a {topic} message: {err}', file=sys.stderr)
        if topic in ('/vizzy/left/image_raw',
                     '/vizzy/right/image_raw') and topic not in first_images:
            try:
                first_images[topic] = image_to_numpy(msgs.deserialize(data, typename))
            except Exception as err:  # noqa: BLE001 - a picture is a nicety, not the point
                print(f'demo: cannot decode {topic}: {err}', file=sys.stderr)
    topics = {}
    for topic, times in sorted(stamps.items()):
        span = (times[-1] - times[0]) / 1e9
        typename, data = last[topic]
        try:
            about = _describe(typename, msgs.deserialize(data, typename))
        except Exception as err:  # noqa: BLE001
            about = f'undecodable: {err}'
        topics[topic] = {'type': typename, 'count': len(times),
                         'rate_hz': round((len(times) - 1) / span, 1) if span > 0 else 0.0,
                         'last': about}
    picture = None
    if len(first_images) == 2:
        import cv2
        both = np.hstack([first_images['/vizzy/left/image_raw'],
                          first_images['/vizzy/right/image_raw']])
        out_dir.mkdir(parents=True, exist_ok=True)
        picture = out_dir / 'cameras.png'
        cv2.imwrite(str(picture), cv2.cvtColor(both, cv2.COLOR_RGB2BGR))
    return {'topics': topics, 'picture': str(picture) if picture else None, 'story': story.lines()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--duration', type=float, default=20.0,
                        help='seconds to record (default 20)')
    parser.add_argument('--output', help='bag directory (default bags/demo_<time>)')
    parser.add_argument('--graph', help='graph YAML (default: vizzy_runtime config/graph.yaml)')
    parser.add_argument('--view-port', type=int, default=8765, metavar='PORT',
                        help='watch it live in Foxglove on ws://127.0.0.1:PORT (default 8765)')
    parser.add_argument('--no-view', action='store_true', help='no Foxglove live view')
    ns = parser.parse_args(argv)
    bag_dir = Path(ns.output or REPO / 'bags' / time.strftime('demo_%Y%m%d_%H%M%S'))
    out_dir = REPO / 'demo_output'

    graph = load_graph(ns.graph or default_graph_file())
    print(f'demo: starting {len(graph.nodes)} nodes: {", ".join(n.name for n in graph.nodes)}',
          flush=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    log = open(out_dir / 'launch.log', 'w')  # noqa: SIM115 - the launcher's log, closed below
    launcher = Launcher(graph, output=log)
    counts: dict[str, int] = {}
    view = None
    with stop_on_signals():  # SIGTERM/SIGHUP stop the demo like Ctrl-C: no node left running
        try:
            if not ns.no_view:
                from .live_view import start_or_warn
                view = start_or_warn(ns.view_port)
            launcher.start()
            if not _wait_for_graph(60):
                print('demo: the graph did not come up within 60 s; see demo_output/launch.log',
                      file=sys.stderr)
            print(f'demo: recording all topics for {ns.duration:g} s into {bag_dir}', flush=True)
            counts = Recorder(bag_dir, exclude=DEMO_EXCLUDE).run(duration=ns.duration)
        except KeyboardInterrupt as stop:
            why = stop if isinstance(stop, LaunchStopped) else 'Ctrl-C'
            print(f'demo: interrupted ({why}); finishing the bag', file=sys.stderr)
        finally:
            codes = launcher.stop()
            log.close()
            if view is not None:
                view.stop()

    summary = summarize(bag_dir, out_dir)
    print(f'\n== Vizzy demo: {sum(counts.values())} messages on {len(summary["topics"])} topics, '
          f'bag {bag_dir}'
          f' (not recorded: {", ".join(DEMO_EXCLUDE)})')
    print(f'{"topic":34} {"type":42} {"count":>6} {"Hz":>7}  last message')
    for topic, row in summary['topics'].items():
        print(f'{topic:34} {row["type"]:42} {row["count"]:6d} {row["rate_hz"]:7.1f}  {row["last"]}')
    if summary['story']:
        print('\nwhat happened:')
        for line in summary['story']:
            print(f'  {line}')
    print('\nnodes (exit code after SIGINT; 0 = clean shutdown):')
    for name, code in codes.items():
        extra = f'  (needed {launcher.escalated[name]})' if name in launcher.escalated else ''
        took = launcher.stop_seconds.get(name)
        extra += f'  stopped {took:.2f} s after SIGINT' if took is not None else ''
        print(f'  {name:20} {code}{extra}')
    if summary['picture']:
        print(f'\nboth cameras: {summary["picture"]}')
    try:
        from .demo_summary import summarize_bag
        page = summarize_bag(bag_dir, out_dir / 'summary.png')
        empty = f' (no data for: {", ".join(page["empty"])})' if page['empty'] else ''
        print(f'one-page summary: {page["path"]}{empty}')
    except Exception as err:  # noqa: BLE001 - the page is a nicety; the demo's verdict stands
        print(f'demo: summary page not written: {type(err).__name__}: {err}', file=sys.stderr)
    print(f'node output: {out_dir / "launch.log"}')
    return 1 if launcher.failed(codes) or not summary['topics'] else 0


if __name__ == '__main__':
    from .loopback import exec_loopback_bound
    from .process_exit import run_then_exit
    exec_loopback_bound()   # the demo's own recorder binds 127.0.0.1 too
    run_then_exit(main)     # its recorder's DDS entities must not be deleted in finalization

"""Each perception node produces its outputs from each scene bag shipped in bags/ (the sim's
recordings, played at half speed with their /clock, the nodes on sim time): what a user replaying
a recording sees. The nodes start first; the bag plays once their outputs are advertised."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import pytest

from vizzy_runtime import dds, msgs
from vizzy_runtime.bag import Player
from vizzy_runtime.launcher import Launcher, load_graph
from vizzy_runtime.testing import STOP_GRACE_S, repo_root, scaled, wait_until

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mixed_support import graph_subset  # noqa: E402

pytestmark = pytest.mark.slow  # starts processes or a whole graph, or takes more than ~5 s

OUTPUTS = {   # node -> its main output (one message per input frame, pair or cloud)
    'foveation': ('/foveation/image', 'sensor_msgs/msg/Image'),
    'stereo_ses': ('/stereo/points', 'sensor_msgs/msg/PointCloud2'),
    'cylinder_detector': ('/cylinders', 'active_vision_msgs/msg/CylinderArray'),
    'mot_planner': ('/mot/tracks', 'active_vision_msgs/msg/TrackArray'),
}
BAGS = ('tabletop', 'visual_search', 'pedestrians')
# what each scene must show beyond "every node answers": (node, list field, at least)
SHOWS = {'tabletop': ('cylinder_detector', 'cylinders', 1),
         'pedestrians': ('mot_planner', 'tracks', 1)}


@pytest.mark.parametrize('scene', BAGS)
def test_every_perception_node_answers_a_shipped_bag(tmp_path: Path, scene: str) -> None:
    bag = repo_root() / 'bags' / scene
    path = graph_subset(tmp_path / 'graph.yaml', list(OUTPUTS), use_sim_time=True)
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(load_graph(path), output=log, grace_s=STOP_GRACE_S)
    readers = {n: dds.RawReader(t, ty, dds.QoS(reliable=False, depth=100))
               for n, (t, ty) in OUTPUTS.items()}
    disc = dds.Discovery()
    got: dict[str, int] = dict.fromkeys(OUTPUTS, 0)
    kept: dict[str, list[bytes]] = {n: [] for n in OUTPUTS}
    player = Player(bag, rate=0.5)
    played: dict[str, int] = {}
    try:
        launcher.start()
        topics = {t for t, _ in OUTPUTS.values()}
        assert wait_until(lambda: topics <= {e.topic for e in disc.endpoints() if e.is_writer},
                          scaled(120)), \
            'the nodes did not come up'
        thread = threading.Thread(target=lambda: played.update(player.run(handle_signals=False)))
        thread.start()

        def answered() -> bool:
            for name, reader in readers.items():
                samples = reader.take(100)
                got[name] += len(samples)
                if name in ('cylinder_detector', 'mot_planner'):
                    kept[name] += [data for data, _ in samples]
            return all(got.values()) and not thread.is_alive()
        wait_until(answered, scaled(90))
        player.stop()
        thread.join(scaled(30))
    finally:
        codes = launcher.stop()
        for r in readers.values():
            dds.delete(r)
    log.seek(0)
    text = log.read()
    assert played.get('/vizzy/left/image_raw', 0) > 0, played
    silent = [n for n, c in got.items() if not c]
    assert not silent, f'{scene}: no output from {silent} (got {got}); log:\n{text[-3000:]}'
    assert launcher.failed(codes) == {}, text[-3000:]
    if scene in SHOWS:
        node, field, least = SHOWS[scene]
        most = max(len(getattr(msgs.deserialize(raw, OUTPUTS[node][1]), field))
                   for raw in kept[node])
        assert most >= least, f'{scene}: {node} never reported {field} ({len(kept[node])} messages)'

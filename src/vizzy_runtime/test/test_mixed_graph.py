"""The whole graph split across vendors: part of it on the real rclpy (rmw_fastrtps_cpp, a
`vizzy launch` of a subset of graph.yaml run by .venv-ros's python) and the rest on the bundled
runtime (Cyclone DDS, a Launcher in this process), both ways round. Every output of the graph
must flow, which needs each side's inputs to cross the vendor boundary: the sim's camera images,
camera_info, /clock, /tf and /joint_states to the perception nodes, their /gaze/command back to
the gaze controller, and /gaze/state to them."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from vizzy_runtime.launcher import Launcher, load_graph
from vizzy_runtime.rclpy_compat import graph
from vizzy_runtime.testing import real_rclpy_python, scaled

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mixed_support import (  # noqa: E402
    GRACE_S,
    Flow,
    expect_clean_real_exit,
    graph_subset,
    real_launch,
    stop_all,
    wait_state,
)

pytestmark = pytest.mark.slow  # the whole graph, across vendors

HEAD = ('sim', 'gaze_controller')
PERCEPTION = ('foveation', 'stereo_ses', 'cylinder_detector', 'mot_planner')

# a message on each means every node is up and fed across the boundary
OUTPUTS = {
    '/clock', '/joint_states', '/tf', '/vizzy/left/image_raw', '/vizzy/right/image_raw',
    '/vizzy/left/camera_info', '/vizzy/rgbd/points',                 # sim
    '/gaze/state', '/vizzy/joint_commands',                          # gaze_controller
    '/foveation/image', '/foveation/detections', '/foveation/detections_2d',  # foveation
    '/stereo/points', '/ses/cells',                                  # stereo_ses
    '/cylinders',                                                    # cylinder_detector
    '/mot/tracks',                                                   # mot_planner
}
# a DDS GUID starts with its vendor's id: who really runs each node
VENDORS = {b'\x01\x0f': 'real rclpy (Fast DDS)', b'\x01\x10': 'bundled (Cyclone DDS)'}
# waits on state, never on time: generous for a loaded 2-core machine starting 6 nodes
DEADLINE_S = scaled(150.0)


@pytest.mark.parametrize('real_side', ['head', 'perception'])
def test_whole_graph_across_vendors(tmp_path, real_side):
    real_rclpy_python()  # skips without .venv-ros
    real_nodes, bundled_nodes = (HEAD, PERCEPTION) if real_side == 'head' else (PERCEPTION, HEAD)
    bundled_log = open(tmp_path / 'bundled.log', 'w+')  # noqa: SIM115 - the launcher's log
    bundled = Launcher(load_graph(graph_subset(tmp_path / 'bundled.yaml', bundled_nodes)),
                       output=bundled_log, grace_s=GRACE_S)
    # vision_msgs/Detection2DArray decoded too: the bundled definitions read what either side sent
    flow = Flow(OUTPUTS, decode={'/gaze/state', '/foveation/detections_2d'})

    def sources() -> set[str]:  # who the gaze controller serves: commands crossed the boundary
        return {m.active_source for m in flow.messages['/gaze/state']} - {''}

    def runtimes() -> dict[str, str]:  # node -> runtime, from ros_discovery_info
        return {n.name: VENDORS.get(n.participant_gid[:2], n.participant_gid[:2].hex())
                for n in graph.snapshot() if n.name in HEAD + PERCEPTION}

    expected = {**{n: VENDORS[b'\x01\x0f'] for n in real_nodes},
                **{n: VENDORS[b'\x01\x10'] for n in bundled_nodes}}
    graph.snapshot()  # listen from now on
    real = real_launch(graph_subset(tmp_path / 'real.yaml', real_nodes), tmp_path / 'real.log')
    try:
        bundled.start()
        up = wait_state(lambda: (flow.all_heard() and sources() and runtimes() == expected)
                        or not real.alive() or any(c is not None for c in bundled.poll().values()),
                        DEADLINE_S)
        real_alive, bundled_states, found = real.alive(), bundled.poll(), runtimes()
    finally:
        codes: dict = {}
        stop_all(flow.close, lambda: codes.update(bundled.stop()),
                 lambda: codes.update(real=real.stop()))
    bundled_log.seek(0)
    logs = (f'--- real ({", ".join(real_nodes)}):\n{real.log()}\n'
            f'--- bundled:\n{bundled_log.read()[-3000:]}')
    assert real_alive and all(c is None for c in bundled_states.values()), (
        f'a side died: real alive {real_alive}, bundled {bundled_states}\n{logs}')
    assert up and not flow.missing(), (
        f'no messages on {sorted(flow.missing())} (heard {flow.counts})\n{logs}')
    assert found == expected, f'nodes on the wrong runtime (or not seen): {found}\n{logs}'
    frames = {m.header.frame_id for m in flow.messages['/foveation/detections_2d']}
    assert frames == {'left_camera_optical_frame'}, f'detections_2d frames {frames}\n{logs}'
    assert sources() <= {'foveation', 'stereo_ses', 'mot_planner'} and sources(), (
        f'no gaze command from the perception nodes was served: {sources()}\n{logs}')
    # both launchers stop their nodes cleanly (SIGINT; the real launcher exits 0 once they have)
    real_code = codes.pop('real')
    assert codes == {n: 0 for n in bundled_nodes}, f'unclean exit {codes}\n{logs}'
    expect_clean_real_exit(real_code, real.log(100000),
                           f'the real launcher ({", ".join(real_nodes)})')

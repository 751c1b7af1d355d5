"""ROS-native names: nodes use relative topic names, so `__ns` moves every topic of every node, and
two whole heads in /head1 and /head2 on one domain do not talk to each other.

Both tests run on the bundled runtime and on the real rclpy (marked live: scripts/test_ros.sh).
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from vizzy_runtime.launcher import Launcher, default_graph_file, load_graph
from vizzy_runtime.ros import (
    Node,
    Parameter,
    SingleThreadedExecutor,
    message,
    qos_profile_sensor_data,
)
from vizzy_runtime.testing import STOP_GRACE_S, no_renderer, publish_until, scaled, wait_until

pytestmark = [pytest.mark.live, pytest.mark.slow]

GazeCommand = message('active_vision_msgs/msg/GazeCommand')
GazeState = message('active_vision_msgs/msg/GazeState')
Image = message('sensor_msgs/msg/Image')
JointState = message('sensor_msgs/msg/JointState')

# Topics every node has outside its namespace, as in any ROS 2 node.
# /diagnostics: absolute, as diagnostic_updater's
ABSOLUTE = {'/parameter_events', '/rosout', '/diagnostics'}
TF = {('sub', '/tf'), ('sub', '/tf_static')}
# The resolved names in the default graph (docs/architecture.md), per node: what users see.
DEFAULT_NAMES: dict[str, set[tuple[str, str]]] = {
    'sim': {('pub', t) for t in (
        '/vizzy/left/image_raw', '/vizzy/right/image_raw', '/vizzy/left/camera_info',
        '/vizzy/right/camera_info', '/vizzy/rgbd/image_raw', '/vizzy/rgbd/depth/image_raw',
        '/vizzy/rgbd/points', '/vizzy/rgbd/camera_info', '/joint_states', '/tf', '/tf_static',
        '/clock', '/sim/ground_truth/objects', '/robot_description',
        '/vizzy/left/image_raw/compressed', '/vizzy/right/image_raw/compressed',
        '/vizzy/rgbd/image_raw/compressed')}
        | {('sub', '/vizzy/joint_commands')},
    'gaze_controller': TF | {('sub', '/gaze/command'), ('sub', '/joint_states'),
                             ('pub', '/gaze/state'), ('pub', '/vizzy/joint_commands')},
    'foveation': {('sub', '/vizzy/left/image_raw'), ('sub', '/vizzy/left/camera_info'),
                  ('sub', '/gaze/state'), ('pub', '/foveation/image'),
                  ('pub', '/foveation/image/compressed'), ('pub', '/foveation/detections'),
                  ('pub', '/foveation/detections_2d'), ('pub', '/foveation/overlay'),
                  ('pub', '/gaze/command')},
    'stereo_ses': TF | {('sub', f'/vizzy/{e}/{t}') for e in ('left', 'right')
                        for t in ('image_raw', 'camera_info')}
    | {('sub', '/gaze/state'), ('pub', '/stereo/points'), ('pub', '/ses/cells'),
       ('pub', '/gaze/command')},
    'cylinder_detector': TF | {('sub', '/vizzy/rgbd/points'), ('sub', '/vizzy/rgbd/image_raw'),
                               ('pub', '/cylinders'), ('pub', '/cylinders/markers'),
                               ('pub', '/cylinders/overlay'), ('pub', '/cylinders/clusters')},
    'mot_planner': TF | {('sub', '/vizzy/left/image_raw'), ('sub', '/vizzy/left/camera_info'),
                         ('sub', '/gaze/state'), ('pub', '/mot/tracks'), ('pub', '/mot/attention'),
                         ('pub', '/mot/overlay'), ('pub', '/gaze/command')},
    'object_map': TF | {('sub', '/foveation/detections'), ('sub', '/vizzy/left/camera_info'),
                        ('sub', '/cylinders/clusters'), ('sub', '/cylinders'),
                        ('sub', '/gaze/state'), ('pub', '/objects'),
                        ('pub', '/objects/markers'), ('pub', '/objects/map'),
                        ('pub', '/gaze/command')},
}
SMALL_SIM = {'width': 160, 'height': 120, 'rgbd_width': 64, 'rgbd_height': 48, 'rate_hz': 10.0,
             'rgbd_rate_hz': 1.0}


def _factory(name: str) -> tuple[Callable[..., Any], list[Any]]:
    """The node class of a graph node and the parameter overrides that keep it light."""
    if name == 'sim':
        from vizzy_sim_bridge.core import render
        from vizzy_sim_bridge.sim_node import SimNode
        try:
            render.select_backend()
        except render.RendererUnavailable as exc:
            no_renderer(str(exc))
        return SimNode, [Parameter(k, value=v) for k, v in SMALL_SIM.items()]
    if name == 'gaze_controller':
        from vizzy_gaze.gaze_controller_node import GazeControllerNode
        return GazeControllerNode, []
    if name == 'foveation':
        from foveation_node.node import FoveationNode
        return FoveationNode, [Parameter('model_path', value='')]
    if name == 'stereo_ses':
        from stereo_ses_node.node import StereoSesNode
        return StereoSesNode, []
    if name == 'cylinder_detector':
        from cylinder_detector_node.node import CylinderDetectorNode
        return CylinderDetectorNode, []
    if name == 'object_map':
        from vizzy_object_map.node import ObjectMapNode
        return ObjectMapNode, []
    from mot_planner_node.node import MotPlannerNode
    return MotPlannerNode, []


def _topics(node: Any) -> set[tuple[str, str]]:
    return ({('pub', p.topic_name) for p in node.publishers}
            | {('sub', s.topic_name) for s in node.subscriptions})


@pytest.mark.parametrize('name', list(DEFAULT_NAMES))
def test_ns_moves_every_topic(context, name) -> None:
    spec = next(n for n in load_graph(default_graph_file()).nodes if n.name == name)
    remaps = [a for src, dst in spec.remappings.items() for a in ('-r', f'{src}:={dst}')]
    cls, overrides = _factory(name)
    found = {}
    for ns in ('', '/h2'):
        args = ['--ros-args', *(['-r', f'__ns:={ns}'] if ns else []), *remaps]
        node = cls(context=context, cli_args=args, parameter_overrides=overrides)
        try:
            found[ns] = _topics(node)
        finally:
            node.destroy_node()
    # with the graph's remappings, the documented names; every one moves into /h2
    assert {(k, t) for k, t in found[''] if t not in ABSOLUTE} == DEFAULT_NAMES[name]
    assert found['/h2'] == {(k, t if t in ABSOLUTE else '/h2' + t)
                            for k, t in found['']}


# --- two heads ------------------------------------------------------------------------------------

HEADS = {'/head1': 160, '/head2': 192}      # each head's image width (4:3) tells their frames apart


def _head_graph(tmp_path: Path, ns: str) -> Path:
    """sim + gaze_controller + foveation of the default graph, light: small images, no CNN."""
    width = HEADS[ns]
    params = tmp_path / f'{ns.strip("/")}_params.yaml'
    params.write_text(yaml.safe_dump({
        'sim': {'ros__parameters': {**SMALL_SIM, 'width': width, 'height': width * 3 // 4}},
        'foveation': {'ros__parameters': {'model_path': ''}}}))
    graph = yaml.safe_load(default_graph_file().read_text())
    graph['nodes'] = [dict(n, parameters=[*n.get('parameters', []), str(params)])
                      for n in graph['nodes']
                      if n['name'] in ('sim', 'gaze_controller', 'foveation')]
    path = tmp_path / f'{ns.strip("/")}_graph.yaml'
    path.write_text(yaml.safe_dump(graph))
    return path


class Probe(Node):
    """Listens to both heads and to the root namespace; commands head1's gaze."""

    def __init__(self, context: Any) -> None:
        super().__init__('cross_talk_probe', context=context, start_parameter_services=False)
        self.widths: dict[str, set[int]] = {ns: set() for ns in HEADS}
        self.joints: dict[str, Any] = {}
        self.states: dict[str, Any] = {}
        self.at_root: list[str] = []
        for ns in HEADS:
            self.create_subscription(Image, f'{ns}/foveation/image',
                                     lambda m, ns=ns: self.widths[ns].add(m.width),
                                     qos_profile_sensor_data)
            self.create_subscription(JointState, f'{ns}/joint_states',
                                     lambda m, ns=ns: self.joints.__setitem__(ns, m),
                                     qos_profile_sensor_data)
            self.create_subscription(GazeState, f'{ns}/gaze/state',
                                     lambda m, ns=ns: self.states.__setitem__(ns, m), 10)
        for topic, kind in (('/foveation/image', Image), ('/vizzy/left/image_raw', Image),
                            ('/joint_states', JointState), ('/gaze/state', GazeState)):
            self.create_subscription(kind, topic, lambda m, t=topic: self.at_root.append(t),
                                     qos_profile_sensor_data)
        self.gaze = self.create_publisher(GazeCommand, '/head1/gaze/command', 10)

    def neck_pan(self, ns: str) -> float:
        js = self.joints.get(ns)
        if js is None or 'neck_pan_joint' not in js.name:
            return math.nan
        return float(js.position[list(js.name).index('neck_pan_joint')])


def test_two_heads_in_two_namespaces_do_not_cross_talk(context, tmp_path) -> None:
    logs = {ns: io.StringIO() for ns in HEADS}
    launchers = {ns: Launcher(load_graph(_head_graph(tmp_path, ns)), namespace=ns,
                              output=logs[ns], grace_s=STOP_GRACE_S) for ns in HEADS}
    probe = Probe(context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(probe)
    try:
        for launcher in launchers.values():
            launcher.start()
        # gaze states flow only if each gaze controller (use_sim_time) follows its own head's clock
        up = wait_until(lambda: all(probe.widths[ns] and ns in probe.states
                                    and not math.isnan(probe.neck_pan(ns)) for ns in HEADS),
                        scaled(90), spin=executor)
        running = {ns: launcher.poll() for ns, launcher in launchers.items()}
        report = {ns: logs[ns].getvalue()[-2500:] for ns in HEADS}
        assert up, f'not flowing: widths {probe.widths}, states {set(probe.states)}; {report}'
        assert all(code is None for codes in running.values() for code in codes.values()), running

        # each head's foveated images come from its own simulator's frames
        assert probe.widths == {ns: {width} for ns, width in HEADS.items()}, probe.widths
        # a gaze command to head1 moves head1 only
        assert wait_until(lambda: probe.gaze.get_subscription_count() > 0, scaled(30),
                          spin=executor)
        head2_before = probe.neck_pan('/head2')
        command = GazeCommand(mode=GazeCommand.MODE_JOINT_TARGETS, joint_names=['neck_pan_joint'],
                              joint_positions=[0.4], motion=GazeCommand.MOTION_SACCADE,
                              source='cross_talk_probe', priority=100, hold_time=0.0)
        assert publish_until(lambda: probe.gaze.publish(command),
                             lambda: abs(probe.neck_pan('/head1') - 0.4) < 0.02, executor,
                             scaled(30), period=0.5), f'head1 neck pan {probe.neck_pan("/head1")}'
        assert wait_until(lambda: probe.states['/head1'].active_source == 'cross_talk_probe',
                          scaled(5), spin=executor)
        wait_until(lambda: False, 0.5, spin=executor)
        assert abs(probe.neck_pan('/head2') - head2_before) < 1e-3, probe.neck_pan('/head2')
        assert probe.states['/head2'].active_source != 'cross_talk_probe'

        # nothing of either head is published in the root namespace
        assert not probe.at_root, sorted(set(probe.at_root))
        stray = {t for t, _ in probe.get_topic_names_and_types()
                 if not t.startswith(('/head1/', '/head2/')) and t not in ABSOLUTE
                 and probe.count_publishers(t) > 0}
        assert not stray, stray
        # the start-up logs print the resolved names
        for ns in HEADS:
            assert f'onto {ns}/foveation/image and {ns}/foveation/image/compressed' in \
                logs[ns].getvalue()
    finally:
        codes = {ns: launcher.stop() for ns, launcher in launchers.items()}
        executor.remove_node(probe)
        probe.destroy_node()
    assert all(code == 0 for c in codes.values() for code in c.values()), (
        codes, {ns: logs[ns].getvalue()[-8000:] for ns in HEADS})

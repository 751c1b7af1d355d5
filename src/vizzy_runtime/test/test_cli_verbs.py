"""Issue 29 items 1 and 6, without a graph: `vizzy topic echo`'s YAML is ros2's (valid YAML for
message arrays, `false`, '...' after --truncate-length), `topic pub`/`service call` values,
`vizzy interface list/show` as ros2 interface prints them, and one-line errors for mistyped
input (a type, a port, a --ros-args parameter, an evaluate --detector, a bag path)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from vizzy_runtime import cli, cli_interface, msg_yaml, msgs
from vizzy_runtime.loopback import WILDCARD_V4
from vizzy_runtime.rclpy_compat import arguments
from vizzy_runtime.testing import scaled

VIZZY = [sys.executable, '-m', 'vizzy_runtime.cli']
REAL_SHARE = Path(__file__).resolve().parents[3] / '.venv-ros' / 'share'   # ROS 2's .msg files


def vizzy(*args: str, timeout: float = scaled(60)) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*VIZZY, *args], capture_output=True, text=True, timeout=timeout)


def one_line_error(proc: subprocess.CompletedProcess[str]) -> str:
    assert proc.returncode != 0 and 'Traceback' not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    return lines[0]


# --- topic echo: ros2's YAML ---------------------------------------------------------------------

def _cylinders() -> object:
    C = msgs.get_message('active_vision_msgs/msg/Cylinder')
    arr = msgs.get_message('active_vision_msgs/msg/CylinderArray')(
        cylinders=[C(id=1, label='cup', radius=0.04), C(id=2, label='true')])
    arr.header.frame_id = 'base_link'
    arr.cylinders[0].center.x = 0.5
    return arr


def test_echo_of_a_message_array_is_ros2_yaml() -> None:
    """cli.py's to_yaml indented items by indent + 2 and printed Python's True/False: not YAML
    (issue 29 item 6). The text is now rosidl_runtime_py.message_to_yaml's, to the byte."""
    text = msg_yaml.to_yaml(_cylinders())
    assert text == (
        'header:\n  stamp:\n    sec: 0\n    nanosec: 0\n  frame_id: base_link\n'
        'cylinders:\n'
        '- id: 1\n  label: cup\n'
        '  center:\n    x: 0.5\n    y: 0.0\n    z: 0.0\n'
        '  axis:\n    x: 0.0\n    y: 0.0\n    z: 0.0\n'
        '  radius: 0.04\n  height: 0.0\n  confidence: 0.0\n  fit_quality: 0.0\n'
        "- id: 2\n  label: 'true'\n"
        '  center:\n    x: 0.0\n    y: 0.0\n    z: 0.0\n'
        '  axis:\n    x: 0.0\n    y: 0.0\n    z: 0.0\n'
        '  radius: 0.0\n  height: 0.0\n  confidence: 0.0\n  fit_quality: 0.0\n')


def plain(value: object) -> object:
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return [plain(v) for v in value] if isinstance(value, list) else value


@pytest.mark.parametrize('typename, field', [
    ('active_vision_msgs/msg/FoveatedDetectionArray', 'detections'),
    ('active_vision_msgs/msg/CylinderArray', 'cylinders'),
    ('active_vision_msgs/msg/TrackArray', 'tracks'),
    ('visualization_msgs/msg/MarkerArray', 'markers'),
])
def test_every_array_topic_echoes_as_yaml_that_reads_back(typename: str, field: str) -> None:
    cls = msgs.get_message(typename)
    item_type = dict(msg_yaml.fields_of(typename))[field][1][0][1]
    items = [msgs.get_message(item_type)() for _ in range(3)]
    if field == 'tracks':
        items[0].attended = True
        items[1].covariance = np.arange(36, dtype=float)
    if field == 'markers':
        items[0].frame_locked = True
    msg = cls(**{field: items})
    text = msg_yaml.to_yaml(msg)
    back = yaml.safe_load(text)
    assert len(back[field]) == 3
    assert back == plain(msg_yaml.to_ordereddict(msg))   # what was printed is what reads back
    assert 'True' not in text and 'False' not in text   # YAML's true/false, as ros2 prints
    if field == 'tracks':
        assert back['tracks'][0]['attended'] is True
        assert back['tracks'][1]['covariance'] == list(range(36))
    if field == 'markers':
        assert back['markers'][0]['frame_locked'] is True


def test_echo_truncates_and_abbreviates_as_ros2() -> None:
    joints = msgs.get_message('sensor_msgs/msg/JointState')(
        name=['a' * 5, 'b'], position=np.arange(200, dtype=float))
    back = yaml.safe_load(msg_yaml.to_yaml(joints, truncate_length=3))
    assert back['name'] == ['aaa...', 'b']
    assert back['position'] == [0.0, 1.0, 2.0, '...']
    assert len(yaml.safe_load(msg_yaml.to_yaml(joints))['position']) == 129   # 128 + '...'
    assert len(yaml.safe_load(msg_yaml.to_yaml(joints, truncate_length=None))['position']) == 200
    info = yaml.safe_load(msg_yaml.to_yaml(msgs.get_message('sensor_msgs/msg/CameraInfo')(),
                                           no_arr=True, no_str=True))
    assert info['d'] == '<sequence type: double, length: 0>'
    assert info['k'] == '<array type: double[9]>'
    assert info['distortion_model'] == '<string length: <0>>'
    assert msg_yaml.to_yaml(msgs.get_message('std_msgs/msg/Empty')()) == '{}\n'


# --- topic pub / service call: YAML -> message ----------------------------------------------------

def test_values_fill_a_message_and_refuse_what_cannot_go_in() -> None:
    image = msgs.get_message('sensor_msgs/msg/Image')()
    stamps = msg_yaml.set_fields(image, msg_yaml.parse_values(
        '{header: auto, height: 2, encoding: rgb8, data: [1, 2, 3]}'))
    assert (image.height, image.encoding, image.data.tolist()) == (2, 'rgb8', [1, 2, 3])
    stamp = msgs.get_message('builtin_interfaces/msg/Time')(sec=7, nanosec=8)
    for setter in stamps:        # 'auto': the header's stamp is set at each publish
        setter(stamp)
    assert (image.header.stamp.sec, image.header.stamp.nanosec) == (7, 8)
    tracks = msgs.get_message('active_vision_msgs/msg/TrackArray')()
    msg_yaml.set_fields(tracks, {'tracks': [{'id': 4, 'attended': True}, {'label': 'person'}]})
    assert [(t.id, t.attended, t.label) for t in tracks.tracks] == [(4, True, ''),
                                                                    (0, False, 'person')]
    for text, said in (('{foo: 1}', "foo: sensor_msgs/msg/Image has no such field"),
                       ('{height: -1}', 'out of the range of uint32'),
                       ('{height: 1.5}', 'expected an integer'),
                       ('{header: {stamp: {sec: x}}}', 'header.stamp.sec'),
                       ('[1, 2]', 'needs to be a dictionary'),
                       ('{a', 'not YAML')):
        with pytest.raises(msg_yaml.FieldError, match=said):
            msg_yaml.set_fields(msgs.get_message('sensor_msgs/msg/Image')(),
                                msg_yaml.parse_values(text))


def test_repr_is_rclpy_s() -> None:
    """What `topic pub` and `service call` print ('publishing #1: ...', 'response:')."""
    from vizzy_runtime.rclpy_compat.param_services import register_types
    register_types()
    request = msgs.get_message('rcl_interfaces/srv/GetParameters_Request')(names=['levels'])
    assert repr(request) == "rcl_interfaces.srv.GetParameters_Request(names=['levels'])"
    joints = msgs.get_message('sensor_msgs/msg/JointState')(position=[1.0, 2.0])
    assert 'position=[1.0, 2.0]' in repr(joints)   # a sequence as a list, as rclpy's repr


# --- interface list / show ---------------------------------------------------------------------

@pytest.mark.slow
def test_interface_show_expands_nested_types_with_tabs() -> None:
    proc = vizzy('interface', 'show', 'active_vision_msgs/msg/CylinderArray')
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    # the top level as its file has it, comments and blank lines included
    assert lines[0] == '# Cylinders found in one point cloud, on /cylinders.'
    assert lines[lines.index('std_msgs/Header header') + 1:][:4] == [
        '\tbuiltin_interfaces/Time stamp', '\t\tint32 sec', '\t\tuint32 nanosec',
        '\tstring frame_id']
    nested = lines[lines.index('Cylinder[] cylinders') + 1:]
    # a nested type without its comments, trailing ones cut, one tab per level
    assert nested[:4] == ['\tuint32 id', '\tstring label', '\tgeometry_msgs/Point center',
                          '\t\tfloat64 x']
    assert nested[-1] == '\tfloat64 fit_quality'
    assert not any(line.lstrip('\t').startswith('#') for line in nested)
    bare = cli_interface.show_lines('active_vision_msgs/msg/CylinderArray', comments=False)
    assert next(iter(bare)) == 'std_msgs/Header header'
    every = list(cli_interface.show_lines('active_vision_msgs/msg/CylinderArray',
                                          nested_comments=True))
    assert '\tuint32 id            # index within this CylinderArray (not a persistent track ' \
           'id)' in every


@pytest.mark.slow
def test_interface_show_of_standard_types_and_services() -> None:
    lines = list(cli_interface.show_lines('geometry_msgs/msg/PoseStamped'))
    assert lines[:5] == ['std_msgs/Header header', '\tbuiltin_interfaces/Time stamp',
                         '\t\tint32 sec', '\t\tuint32 nanosec', '\tstring frame_id']
    assert lines[5:8] == ['Pose pose', '\tPoint position', '\t\tfloat64 x']
    assert lines[-1] == '\t\tfloat64 w 1'
    srv = list(cli_interface.show_lines('rcl_interfaces/srv/ListParameters'))
    assert srv[srv.index('---') + 1:] == ['ListParametersResult result', '\tstring[] names',
                                          '\tstring[] prefixes']
    assert cli_interface.split_name('std_msgs/String') == ('std_msgs', 'msg', 'String')
    said = one_line_error(vizzy('interface', 'show', 'foo_msgs/msg/Nope'))
    assert said == ("vizzy: Could not find the interface 'foo_msgs/msg/Nope' (`vizzy interface "
                    'list` lists the known ones)')


def test_generated_definitions_match_ros2_s_files() -> None:
    """A standard type's text comes from the typestore: the same fields and constants, with the
    same types, as the .msg files ROS 2 ships (where .venv-ros has them)."""
    if not REAL_SHARE.is_dir():
        pytest.skip('no .venv-ros (make setup-ros) with ROS 2 .msg files')

    def declarations(text: str, pkg: str) -> set[tuple[str, ...]]:
        out = set()
        for line in text.splitlines():
            code = line.split('#', 1)[0].strip()
            if not code:
                continue
            kind, rest = code.split(None, 1)
            if kind.split('[')[0].startswith(pkg + '/'):
                kind = kind[len(pkg) + 1:]       # same-package types: bare or qualified
            out.add((kind, rest.replace(' ', '')) if '=' in rest else (kind, rest.split()[0]))
        return out

    compared = 0
    for path in sorted(REAL_SHARE.glob('*/msg/*.msg')):
        name = f'{path.parts[-3]}/msg/{path.stem}'
        if name in msgs.registry().store.fielddefs:
            compared += 1
            assert declarations(cli_interface.generated_text(name), path.parts[-3]) == \
                declarations(path.read_text(), path.parts[-3]), name
    assert compared > 100


@pytest.mark.slow
def test_interface_list_sections() -> None:
    proc = vizzy('interface', 'list')
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == 'Messages:' and 'Services:' in lines and lines[-1] == 'Actions:'
    assert '    active_vision_msgs/msg/CylinderArray' in lines
    assert '    rcl_interfaces/srv/GetParameters' in lines
    only = vizzy('interface', 'list', '-s').stdout.splitlines()
    assert only[0] == 'Services:' and 'Messages:' not in only


# --- one-line errors (issue 29 item 6) ------------------------------------------------------------

@pytest.mark.slow
def test_an_unknown_type_is_named_not_a_keyerror_repr() -> None:
    said = one_line_error(vizzy('topic', 'echo', '/nope', 'foo/Bar', '--timeout', '0.5'))
    assert said.startswith("vizzy: The passed message type 'foo/Bar' is invalid"), said
    said = one_line_error(vizzy('topic', 'echo', '/nope', '--type', 'foo/Bar', '--timeout', '0.5'))
    assert "'foo/Bar' is invalid" in said   # before: vizzy: 'foo/msg/Bar'
    said = one_line_error(vizzy('topic', 'pub', '/x', 'std_msgs/msg/Strin', '{}'))
    assert "'std_msgs/msg/Strin' is invalid" in said


@pytest.mark.slow
def test_hz_waits_no_longer_than_its_duration() -> None:
    said = one_line_error(vizzy('topic', 'hz', '/nope_issue29', '--duration', '1.5'))
    assert said == ('vizzy: no publisher on /nope_issue29 after 1.5 s (give its type to wait '
                    'anyway)')   # before: after 10 s, whatever --duration


@pytest.mark.slow
@pytest.mark.parametrize('argv', [['view', '--port', '70000'], ['view', '--port', '-1'],
                                  ['launch', '--view-port', '70000']])
def test_ports_out_of_range_are_refused_by_the_parser(argv: list[str]) -> None:
    said = one_line_error(vizzy(*argv))
    assert "'70000': a port is 0..65535" in said or "'-1': a port is 0..65535" in said, said


def test_view_says_when_it_serves_loopback_only(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv('VIZZY_DDS_LAN', raising=False)
    monkeypatch.setenv('VIZZY_RUNTIME', 'bundled')
    note = cli.loopback_note(WILDCARD_V4)
    assert note is not None and 'serves on 127.0.0.1 only' in note and 'VIZZY_DDS_LAN=1' in note
    assert cli.loopback_note(None) is None and cli.loopback_note('127.0.0.1') is None
    monkeypatch.setenv('VIZZY_DDS_LAN', '1')
    assert cli.loopback_note(WILDCARD_V4) is None     # the opt-in: it does bind every interface


def test_a_parameter_without_a_value_says_name_value() -> None:
    with pytest.raises(arguments.RosArgumentError) as err:
        arguments.parse(['--ros-args', '-p', 'k_max'])
    assert str(err.value) == "-p 'k_max': expected 'name:=value' (e.g. k_max:=1)"


@pytest.mark.slow
def test_demo_summary_of_a_mistyped_bag_is_one_line(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, '-m', 'vizzy_runtime.demo_summary',
                           str(tmp_path / 'typo'), '-o', str(tmp_path / 'page.png')],
                          capture_output=True, text=True, timeout=scaled(120))
    assert proc.returncode == 2
    assert one_line_error(proc) == f'demo_summary: {tmp_path / "typo"}: no such bag directory'

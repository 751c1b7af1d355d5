"""Issue 29 item 1: `vizzy topic info/pub/echo`, `node info`, `service list/type/call` against a
running node (a bundled-runtime talker with a publisher, a subscription and a parameter), each
run as a user runs it and compared with the layout ros2 prints. Loopback, a random
ROS_DOMAIN_ID unless one is set."""

from __future__ import annotations

import os
import random
import re
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from vizzy_runtime.testing import scaled, wait_until

pytestmark = pytest.mark.slow  # starts processes or a whole graph, or takes more than ~5 s

os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(100, 200)))

VIZZY = [sys.executable, '-m', 'vizzy_runtime.cli']
TALKER = textwrap.dedent('''
    from vizzy_runtime.ros import rclpy
    from vizzy_runtime import msgs
    rclpy.init()
    node = rclpy.create_node('talker', namespace='/issue29')
    String = msgs.get_message('std_msgs/msg/String')
    pub = node.create_publisher(String, '/chatter', 10)
    node.create_subscription(String, '/heard', lambda m: print('heard', m.data, flush=True), 10)
    node.declare_parameter('levels', 5)
    count = [0]
    def tick():
        count[0] += 1
        pub.publish(String(data=f'hello {count[0]}'))
    node.create_timer(0.1, tick)
    print('up', flush=True)
    rclpy.spin(node)
''')
STRING_HASH = 'RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18'
DEFAULT_QOS = ['QoS profile:', '  Reliability: RELIABLE', '  History (Depth): KEEP_LAST (10)',
               '  Durability: VOLATILE', '  Lifespan: Infinite', '  Deadline: Infinite',
               '  Liveliness: AUTOMATIC', '  Liveliness lease duration: Infinite']


def vizzy(*args: str, code: int = 0, stdin: str | None = None) -> str:
    proc = subprocess.run([*VIZZY, *args], capture_output=True, text=True, timeout=scaled(120),
                          input=stdin, env={**os.environ, 'VIZZY_RUNTIME': 'bundled'})
    assert proc.returncode == code, f'vizzy {" ".join(args)}: {proc.returncode}\n{proc.stderr}'
    assert 'Traceback' not in proc.stderr, proc.stderr
    return proc.stdout if code == 0 else proc.stderr


def until(check: object, timeout: float = scaled(60.0)) -> object:
    """Run a CLI check until it holds (discovery on a loaded machine can take a second try)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return check()  # type: ignore[operator]
        except AssertionError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)


@pytest.fixture(scope='module')
def talker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    log = tmp_path_factory.mktemp('talker') / 'talker.log'
    with open(log, 'w') as out:
        proc = subprocess.Popen([sys.executable, '-c', TALKER], stdout=out,
                                stderr=subprocess.STDOUT,
                                env={**os.environ, 'VIZZY_RUNTIME': 'bundled'})
    try:
        assert wait_until(lambda: 'up' in log.read_text() or proc.poll() is not None, scaled(60)), \
            log.read_text()
        assert proc.poll() is None, log.read_text()
        yield log
    finally:
        proc.terminate()
        proc.wait(scaled(30))


def test_topic_info_counts_and_verbose_endpoints(talker: Path) -> None:
    def check() -> None:
        assert vizzy('topic', 'info', '/chatter') == (
            'Type: std_msgs/msg/String\nPublisher count: 1\nSubscription count: 0\n')
    until(check)

    def verbose() -> str:
        out = vizzy('topic', 'info', '-v', '/chatter')
        assert 'Node name: talker' in out, out
        return out
    out = until(verbose)
    blocks = out.split('\n\n')
    assert blocks[:2] == ['Type: std_msgs/msg/String', 'Publisher count: 1']
    lines = blocks[2].splitlines()
    assert lines[:5] == ['Node name: talker', 'Node namespace: /issue29',
                         'Topic type: std_msgs/msg/String', f'Topic type hash: {STRING_HASH}',
                         'Endpoint type: PUBLISHER']
    assert re.fullmatch(r'GID: ([0-9a-f]{2}\.){15}[0-9a-f]{2}', lines[5]), lines[5]
    assert lines[6:] == DEFAULT_QOS
    assert blocks[3:] == ['Subscription count: 0', '']
    out = until(lambda: vizzy('topic', 'info', '-v', '/heard'))
    assert 'Endpoint type: SUBSCRIPTION' in out and 'Publisher count: 0' in out, out
    assert vizzy('topic', 'info', '/nowhere', code=1) == "vizzy: Unknown topic '/nowhere'\n"


def test_node_info_lists_what_ros2_node_info_lists(talker: Path) -> None:
    params = ['describe_parameters', 'get_parameter_types', 'get_parameters', 'list_parameters',
              'set_parameters', 'set_parameters_atomically']
    types = ['DescribeParameters', 'GetParameterTypes', 'GetParameters', 'ListParameters',
             'SetParameters', 'SetParametersAtomically']
    expected = '\n'.join([
        '/issue29/talker',
        '  Subscribers:',
        '    /heard: std_msgs/msg/String',
        '  Publishers:',
        '    /chatter: std_msgs/msg/String',
        '    /parameter_events: rcl_interfaces/msg/ParameterEvent',
        '    /rosout: rcl_interfaces/msg/Log',
        '  Service Servers:',
        *[f'    /issue29/talker/{p}: rcl_interfaces/srv/{t}' for p, t in zip(params, types,
                                                                             strict=True)],
        '  Service Clients:', '',
        '  Action Servers:', '',
        '  Action Clients:', '', ''])

    def check() -> None:
        assert vizzy('node', 'info', '/issue29/talker') == expected
    until(check)
    assert vizzy('node', 'info', '/nobody', code=1) == "vizzy: Unable to find node '/nobody'\n"


def test_service_list_type_and_call(talker: Path) -> None:
    def listed() -> str:
        out = vizzy('service', 'list', '-t')
        assert '/issue29/talker/get_parameters [rcl_interfaces/srv/GetParameters]' in out, out
        return out
    out = until(listed)
    assert len(out.splitlines()) == 6, out       # the talker's six parameter services
    assert vizzy('service', 'list', '-c') == '6\n'
    assert vizzy('service', 'type', '/issue29/talker/list_parameters') == \
        'rcl_interfaces/srv/ListParameters\n'
    out = vizzy('service', 'call', '/issue29/talker/get_parameters',
                'rcl_interfaces/srv/GetParameters', '{names: [levels]}',
                '--timeout', str(scaled(30)))
    request, response = out.split('\n\nresponse:\n')
    assert request.endswith("making request: rcl_interfaces.srv.GetParameters_Request("
                            "names=['levels'])")
    assert response.startswith('rcl_interfaces.srv.GetParameters_Response(values=['
                               'rcl_interfaces.msg.ParameterValue(type=2, bool_value=False, '
                               'integer_value=5,'), response
    out = vizzy('service', 'call', '/issue29/talker/set_parameters',
                'rcl_interfaces/srv/SetParameters', '--stdin', '--timeout', str(scaled(30)),
                stdin='{parameters: [{name: levels, value: {type: 2, integer_value: 7}}]}')
    assert 'SetParametersResult(successful=True' in out, out
    assert vizzy('param', 'get', '/issue29/talker', 'levels') == 'Integer value is: 7\n'
    said = vizzy('service', 'call', '/x', 'std_srvs/srv/Trigger', code=2)
    assert "The passed service type 'std_srvs/srv/Trigger' is invalid" in said


def test_topic_pub_reaches_a_subscriber_and_echo_prints_yaml(talker: Path) -> None:
    out = vizzy('topic', 'pub', '/heard', 'std_msgs/msg/String', 'data: issue 29', '-t', '2',
                '-r', '20', '--max-wait-time-secs', '60')
    assert out.endswith('publisher: beginning loop\n'
                        "publishing #1: std_msgs.msg.String(data='issue 29')\n\n"
                        "publishing #2: std_msgs.msg.String(data='issue 29')\n\n"), out
    assert wait_until(lambda: talker.read_text().count('heard issue 29') >= 2, scaled(30)), \
        talker.read_text()
    out = vizzy('topic', 'echo', '/chatter', '-n', '2')
    docs = out.split('---\n')
    assert docs[2:] == [''] and all(re.fullmatch(r'data: hello \d+\n', d) for d in docs[:2]), out
    assert [yaml.safe_load(d)['data'].startswith('hello') for d in docs[:2]] == [True, True]
    said = vizzy('topic', 'pub', '/heard', 'std_msgs/msg/String', '{dta: x}', code=1)
    assert said.startswith('vizzy: topic pub: Failed to populate field: dta: std_msgs/msg/String '
                           'has no such field'), said

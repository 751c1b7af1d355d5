"""The graph across two hosts, on request: two network namespaces joined by a veth pair, the
simulator and the gaze controller on one, foveation on the other, both with the LAN opt-in
(VIZZY_DDS_LAN=1: Cyclone's defaults, i.e. the veth interface and multicast discovery). The second
host sees the simulator's camera and foveation's output computed from it; a process there without
the opt-in (loopback only, the default) sees nothing of the first host. The namespaces have no
other link and no route out (checked before anything runs in them), and their addresses are from
TEST-NET-1 (192.0.2.0/24, RFC 5737: documentation only, never routed), so no packet can leave
them. Skipped, with the reason, without root or iproute2."""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mixed_support import graph_subset  # noqa: E402

from vizzy_runtime.testing import STOP_GRACE_S, scaled  # noqa: E402

pytestmark = pytest.mark.slow  # a whole graph across two network namespaces

PROBE = r'''
import json, sys, time
from vizzy_runtime import dds
topics = {'/vizzy/left/camera_info': 'sensor_msgs/msg/CameraInfo',
          '/foveation/image': 'sensor_msgs/msg/Image'}
readers = {t: dds.RawReader(t, ty, dds.QoS(reliable=False)) for t, ty in topics.items()}
counts = dict.fromkeys(topics, 0)
deadline = time.monotonic() + float(sys.argv[1])
while time.monotonic() < deadline and not all(counts.values()):
    for t, r in readers.items():
        counts[t] += len(r.take(16))
    time.sleep(0.05)
print(json.dumps(counts))
'''


# The two namespaces' veth ends: TEST-NET-1 (RFC 5737), reachable only between the two.
HOST_ADDRESSES = ('192.0.2.1/24', '192.0.2.2/24')


def _ip(*args: str) -> str:
    return subprocess.run(['ip', *args], check=True, capture_output=True, text=True,
                          timeout=scaled(30)).stdout


def _confined(host: str, dev: str) -> bool:
    """Only lo and this veth end in the namespace, and no default route."""
    links = {line.split(':')[1].strip().split('@')[0]
             for line in _ip('-n', host, '-o', 'link').splitlines()}
    return links == {'lo', dev} and 'default' not in _ip('-n', host, 'route')


@pytest.fixture
def two_hosts():
    if os.geteuid() != 0 or shutil.which('ip') is None:
        pytest.skip('needs root and iproute2 to make network namespaces')
    n = random.randint(1000, 9999)
    hosts = (f'vza{n}', f'vzb{n}')
    try:
        for host in hosts:
            _ip('netns', 'add', host)
        _ip('link', 'add', f'va{n}', 'type', 'veth', 'peer', 'name', f'vb{n}')
        for host, dev, addr in ((hosts[0], f'va{n}', HOST_ADDRESSES[0]),
                                (hosts[1], f'vb{n}', HOST_ADDRESSES[1])):
            _ip('link', 'set', dev, 'netns', host)
            _ip('-n', host, 'addr', 'add', addr, 'dev', dev)
            _ip('-n', host, 'link', 'set', dev, 'up')
            _ip('-n', host, 'link', 'set', 'lo', 'up')
    except (subprocess.CalledProcessError, OSError) as exc:
        for host in hosts:
            subprocess.run(['ip', 'netns', 'del', host], capture_output=True)
        pytest.skip(f'cannot make network namespaces here: {getattr(exc, "stderr", "") or exc}')
    try:
        assert _confined(hosts[0], f'va{n}') and _confined(hosts[1], f'vb{n}')
        yield hosts
    finally:
        for host in hosts:
            subprocess.run(['ip', 'netns', 'del', host], capture_output=True)


def _in(host: str, args: list[str], lan: bool, **kw) -> subprocess.Popen:
    env = {**os.environ, 'PYTHONUNBUFFERED': '1'}
    env.pop('VIZZY_DDS_LAN', None)
    if lan:
        env['VIZZY_DDS_LAN'] = '1'
    return subprocess.Popen(['ip', 'netns', 'exec', host, sys.executable, *args], env=env, **kw)


def _stop(proc: subprocess.Popen) -> None:
    """SIGINT, then SIGTERM (the launcher still stops its nodes), then SIGKILL."""
    for sig, wait in ((signal.SIGINT, 60), (signal.SIGTERM, 30), (signal.SIGKILL, 30)):
        if proc.poll() is not None:
            return
        proc.send_signal(sig)
        try:
            proc.wait(wait)
        except subprocess.TimeoutExpired:
            continue


def test_the_graph_spans_two_hosts_with_the_lan_opt_in(two_hosts, tmp_path):
    host_a, host_b = two_hosts
    sim = graph_subset(tmp_path / 'a.yaml', ['sim', 'gaze_controller'])
    perception = graph_subset(tmp_path / 'b.yaml', ['foveation'])
    launch = ['-m', 'vizzy_runtime.cli', 'launch', '--duration', '300',
              '--grace', str(STOP_GRACE_S)]
    # output to files: a pipe nobody reads fills up and blocks the launcher and its nodes
    logs = {name: open(tmp_path / f'{name}.log', 'w+')  # noqa: SIM115 - the launchers' output
            for name in ('a', 'b')}
    a = _in(host_a, [*launch, str(sim)], lan=True, stdout=logs['a'], stderr=subprocess.STDOUT)
    b = _in(host_b, [*launch, str(perception)], lan=True, stdout=logs['b'],
            stderr=subprocess.STDOUT)
    try:
        seen = _in(host_b, ['-c', PROBE, str(scaled(120))], lan=True, stdout=subprocess.PIPE,
                   text=True)
        counts = json.loads(seen.communicate(timeout=scaled(180))[0])
        local = _in(host_b, ['-c', PROBE, '8'], lan=False, stdout=subprocess.PIPE, text=True)
        local_counts = json.loads(local.communicate(timeout=scaled(60))[0])
    finally:
        _stop(a)
        _stop(b)
    log_a, log_b = (logs[n].seek(0) or logs[n].read()[-3000:] for n in ('a', 'b'))
    where = f'host A:\n{log_a}\nhost B:\n{log_b}'
    assert counts['/vizzy/left/camera_info'] > 0, f'no camera from host A: {counts}\n{where}'
    assert counts['/foveation/image'] > 0, f'no foveation output on host B: {counts}\n{where}'
    assert local_counts == {'/vizzy/left/camera_info': 0, '/foveation/image': 0}, local_counts
    assert a.returncode == 0 and b.returncode == 0, where

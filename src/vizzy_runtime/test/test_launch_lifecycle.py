"""`vizzy launch` lifecycle: a killed launcher, signals, the stop's escalation, respawns and
zygotes (split from test_launch.py; the zygote itself: test_zygote.py)."""

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from vizzy_runtime import dds
from vizzy_runtime.launcher import (
    Graph,
    Launcher,
    LaunchError,
    NodeSpec,
    load_graph,
)
from vizzy_runtime.testing import STOP_GRACE_S, scaled, wait_until
from vizzy_runtime.zygote import process_running


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell's background job starts


@pytest.mark.slow
def test_nodes_end_when_their_launcher_is_killed(tmp_path):
    """SIGKILL (or the OOM killer) gives the launcher no chance to stop its nodes: they end on
    their own (PR_SET_PDEATHSIG), zygotes too (the shipped graph's respawn_standby: the node is
    the zygote's child), instead of running on orphaned."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mixed_support import graph_subset
    graph_file = graph_subset(tmp_path / 'graph.yaml', ['gaze_controller'], use_sim_time=False)
    proc = subprocess.Popen([sys.executable, '-m', 'vizzy_runtime.cli', 'launch', str(graph_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    pids: list[int] = []
    zygotes: list[int] = []
    lines: list[str] = []
    watchdog = threading.Timer(180, proc.kill)
    watchdog.start()
    try:
        for line in proc.stdout:
            lines.append(line)
            pids += [int(p) for p in re.findall(r'process started with pid \[(\d+)\]', line)]
            zygotes += [int(p) for p in re.findall(r'forked by its zygote, pid \[(\d+)\]', line)]
            if any('[gaze_controller-' in ln and 'INFO' in ln and 'launch' not in ln
                   for ln in lines):
                break
        assert len(pids) == 1 and process_running(pids[0]), ''.join(lines)
        assert len(zygotes) == 1 and process_running(zygotes[0]), ''.join(lines)
        proc.kill()
        proc.wait(timeout=scaled(30))
        deadline = time.monotonic() + scaled(60)
        while any(map(process_running, pids + zygotes)) and time.monotonic() < deadline:
            time.sleep(0.2)
    finally:
        watchdog.cancel()
        if proc.poll() is None:
            proc.kill()
        for pid in pids + zygotes:
            if process_running(pid):
                os.kill(pid, signal.SIGKILL)
    assert not process_running(pids[0]), f'node {pids[0]} outlived its SIGKILLed launcher'
    assert not process_running(zygotes[0]), f'zygote {zygotes[0]} outlived its SIGKILLed launcher'


def test_parameter_sets_for_benchmarks() -> None:
    from vizzy_runtime.launcher import parse_parameter_sets
    assert parse_parameter_sets(['mot_planner.scale=1.1', 'sim.seed=3', 'sim.scene=tabletop',
                                 'stereo_ses.depth_range_m=[0.3, 5]']) == {
        'mot_planner': {'scale': 1.1}, 'sim': {'seed': 3, 'scene': 'tabletop'},
        'stereo_ses': {'depth_range_m': [0.3, 5]}}
    for bad in ('scale=1.1', 'mot_planner.scale', '.scale=1', 'mot_planner.=1'):
        with pytest.raises(ValueError, match='expected node.parameter=value'):
            parse_parameter_sets([bad])


def test_end_with_launcher_arms_only_under_a_launcher() -> None:
    from vizzy_runtime.process_exit import LAUNCHER_PID_ENV, end_with_launcher
    assert not end_with_launcher({})
    assert not end_with_launcher({LAUNCHER_PID_ENV: 'x'})


@pytest.mark.slow
@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_signal_to_the_launcher_stops_every_node(tmp_path, sig):
    """What timeout, systemd, docker stop, CI cancels and `kill -INT` send: no node may outlive
    the launcher, even one started with SIGINT ignored (a shell's background job)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mixed_support import graph_subset
    graph_file = graph_subset(tmp_path / 'graph.yaml', ['gaze_controller', 'mot_planner'],
                              use_sim_time=False)
    proc = subprocess.Popen([sys.executable, '-m', 'vizzy_runtime.cli', 'launch', str(graph_file),
                             '--grace', str(STOP_GRACE_S)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=_ignore_sigint)
    pids: list[int] = []
    lines: list[str] = []
    watchdog = threading.Timer(180, proc.kill)  # a launcher that never gets there fails, not hangs
    watchdog.start()
    try:
        # up: each node has logged its start-up line (signals before rclpy.init are another matter)
        for line in proc.stdout:
            lines.append(line)
            pids += [int(p) for p in re.findall(r'process started with pid \[(\d+)\]', line)]
            if all(any(f'[{n}-' in ln and 'INFO' in ln and 'launch' not in ln for ln in lines)
                   for n in ('gaze_controller', 'mot_planner')):
                break
        assert len(pids) == 2 and all(process_running(p) for p in pids), ''.join(lines)
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=scaled(120))
    finally:
        watchdog.cancel()
        if proc.poll() is None:
            proc.kill()
    text = ''.join(lines) + out
    assert proc.returncode == 0, text[-3000:]
    said = ('user interrupted with ctrl-c' if sig == signal.SIGINT
            else f'stopping on {signal.Signals(sig).name}')
    assert said in text, text[-3000:]
    assert not [p for p in pids if process_running(p)], f'orphaned nodes {pids}:\n{text[-3000:]}'


@pytest.mark.slow
def test_stop_escalates_and_names_the_node_without_calling_it_a_failure(tmp_path):
    graph = Graph(nodes=[])
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(graph, output=log, grace_s=0.5)
    # like a node (node_tools.run): stacks on SIGUSR1, which the launcher sends before SIGTERM
    stubborn = ('import faulthandler, signal, sys, time; signal.signal(signal.SIGINT, '
                'signal.SIG_IGN); '
                'faulthandler.register(signal.SIGUSR1, all_threads=True, file=sys.stdout); '
                'print("ready", flush=True); time.sleep(120)')
    launcher.procs['stubborn'] = subprocess.Popen([sys.executable, '-c', stubborn],
                                                  stdout=subprocess.PIPE,
                                                  text=True, start_new_session=True)
    launcher.procs['crashed'] = subprocess.Popen([sys.executable, '-c', 'raise SystemExit(3)'],
                                                 start_new_session=True)
    assert launcher.procs['stubborn'].stdout.readline() == 'ready\n'
    launcher.procs['crashed'].wait(scaled(30))
    codes = launcher.stop()
    log.seek(0)
    text = log.read()
    assert codes == {'stubborn': -signal.SIGTERM, 'crashed': 3}
    assert launcher.escalated == {'stubborn': 'SIGTERM after SIGINT'}
    assert re.search(r'process stubborn \(pid \d+\) still running 0.5 s after SIGINT \(its '
                     r'threads\' '
                     r'stacks are above\): sending SIGTERM', text), text
    assert launcher.failed(codes) == {'crashed': 3}
    stacks = launcher.procs['stubborn'].stdout.read()
    assert 'most recent call first' in stacks and 'File "<string>", line 1' in stacks, stacks


@pytest.mark.slow
def test_a_killed_node_respawns_and_its_outputs_flow_again(tmp_path):
    """SIGKILL a node of a respawning graph: the launcher starts it again and /gaze/state flows
    from the new process. Prints the time from the kill to the first new message (the respawn
    time; not asserted: tests must pass on a loaded machine)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mixed_support import graph_subset
    path = graph_subset(tmp_path / 'graph.yaml', ['gaze_controller'], use_sim_time=False)
    data = yaml.safe_load(path.read_text())
    data.update(respawn=True, respawn_delay=0.0)
    path.write_text(yaml.safe_dump(data))
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(load_graph(path), output=log, grace_s=STOP_GRACE_S)
    reader = dds.RawReader('/gaze/state', 'active_vision_msgs/msg/GazeState',
                           dds.QoS(reliable=False))
    try:
        launcher.start()
        assert wait_until(lambda: bool(reader.take(8)), scaled(60)), (
            'gaze_controller never published')
        first = launcher.procs['gaze_controller']
        killed_at = time.monotonic()
        os.killpg(first.pid, signal.SIGKILL)
        assert wait_until(lambda: first.poll() is not None, scaled(30))
        reader.take(64)  # what the first process sent before it died
        assert wait_until(lambda: launcher.procs['gaze_controller'] is not first
                          and bool(reader.take(8)), scaled(60))
        back_s = time.monotonic() - killed_at
        running = launcher.poll()
    finally:
        codes = launcher.stop()
        dds.delete(reader)
    log.seek(0)
    text = log.read()
    print(f'respawn: /gaze/state flowing again {back_s:.2f} s after SIGKILL')
    assert (launcher.respawned == {'gaze_controller': 1}
            and running == {'gaze_controller': None}), text
    assert 'process gaze_controller has finished (exit code -9); respawning in 0 s' in text, text
    assert re.search(r'process started with pid \[\d+\]: gaze_controller \(respawn 1\)', text), text
    assert codes == {'gaze_controller': 0}, text


@pytest.mark.slow
def test_respawn_stops_at_a_start_up_error_and_at_max_retries(tmp_path):
    graph = Graph(nodes=[NodeSpec('vizzy_gaze', 'gaze_controller', 'bad',
                                  respawn_max_retries=1,
                                  arguments=['--ros-args', '-p', 'control_rate_hz:=-5.0']),
                         NodeSpec('vizzy_gaze', 'gaze_controller', 'twice',
                                  respawn_max_retries=1,
                                  arguments=['--ros-args', '-p', 'use_sim_time:=false'])],
                  respawn=True, respawn_delay=0.0)
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(graph, output=log, grace_s=STOP_GRACE_S)
    try:
        launcher.start()
        assert wait_until(lambda: launcher.poll()['bad'] is not None, scaled(60))
        for _ in range(2):  # killed, respawned once, killed again: no more
            assert wait_until(lambda: launcher.poll()['twice'] is None, scaled(60))
            proc = launcher.procs['twice']
            os.killpg(proc.pid, signal.SIGKILL)
            assert wait_until(lambda proc=proc: proc.poll() is not None, scaled(30))
        launcher.wait(scaled(60))  # returns: every node has exited for good
        codes = launcher.poll()
    finally:
        launcher.stop()
    log.seek(0)
    text = log.read()
    assert codes == {'bad': 2, 'twice': -9}, text
    assert launcher.respawned == {'twice': 1}, text
    assert 'process bad has finished (exit code 2) (a start-up error: not respawned)' in text, text


@pytest.mark.slow
def test_a_killed_node_is_forked_again_by_its_zygote(tmp_path):
    """respawn_standby: the node is forked by a zygote that did its imports; after each SIGKILL of
    the node the same zygote forks it again (a new pid, a new handle) and /gaze/state flows from
    it, again and again; stop() ends the node and then its zygote (no process left). Prints the
    time from each kill to the first new message (not asserted: a loaded machine)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mixed_support import graph_subset
    path = graph_subset(tmp_path / 'graph.yaml', ['gaze_controller'], use_sim_time=False)
    data = yaml.safe_load(path.read_text())
    data.update(respawn=True, respawn_delay=0.0, respawn_standby=True)
    path.write_text(yaml.safe_dump(data))
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(load_graph(path), output=log, grace_s=STOP_GRACE_S)
    reader = dds.RawReader('/gaze/state', 'active_vision_msgs/msg/GazeState',
                           dds.QoS(reliable=False))
    nodes, back_s = [], []
    try:
        launcher.start()
        assert wait_until(lambda: bool(reader.take(8)), scaled(60)), (
            'gaze_controller never published')
        zygote = launcher.standbys['gaze_controller']
        assert zygote.pid in launcher.ready_standbys
        for _ in range(3):
            node = launcher.procs['gaze_controller']
            nodes.append(node)
            assert node.pid != zygote.pid and process_running(node.pid)
            killed_at = time.monotonic()
            os.killpg(node.pid, signal.SIGKILL)
            assert wait_until(lambda node=node: node.poll() is not None, scaled(30))
            reader.take(64)
            assert wait_until(lambda node=node: launcher.procs['gaze_controller'] is not node
                              and launcher.procs['gaze_controller'].pid != zygote.pid
                              and bool(reader.take(8)), scaled(60)), 'never forked again'
            back_s.append(time.monotonic() - killed_at)
        nodes.append(launcher.procs['gaze_controller'])
        assert launcher.standbys['gaze_controller'] is zygote and zygote.poll() is None
    finally:
        codes = launcher.stop()
        dds.delete(reader)
    log.seek(0)
    text = log.read()
    print('zygote: /gaze/state flowing again ' + ', '.join(f'{s:.2f}' for s in back_s)
          + ' s after each SIGKILL')
    assert [n.poll() for n in nodes] == [-signal.SIGKILL] * 3 + [0], text
    assert len({n.pid for n in nodes}) == 4, text
    for i, node in enumerate(nodes):
        again = f' (respawn {i})' if i else ''
        assert (f'process started with pid [{node.pid}]: gaze_controller{again} (forked by its '
                f'zygote, pid [{zygote.pid}])') in text, text
    assert codes == {'gaze_controller': 0}, text
    assert launcher.standbys == {} and zygote.poll() == 0, text
    assert not any(process_running(p) for p in [zygote.pid, *(n.pid for n in nodes)])


def test_respawn_standby_must_be_a_boolean(tmp_path):
    path = tmp_path / 'g.yaml'
    path.write_text('respawn_standby: 3\nnodes: [{package: p, executable: e}]\n')
    with pytest.raises(LaunchError, match='graph: respawn_standby must be true or false'):
        load_graph(path)
    path.write_text('respawn: true\nnodes: [{package: p, executable: e, respawn_standby: true}, '
                    '{package: p, executable: f}]\n')
    graph = load_graph(path)
    assert [graph.standby(n) for n in graph.nodes] == [True, False]

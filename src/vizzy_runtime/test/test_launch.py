"""The shared graph description: the ROS-less launcher starts every node and stops them cleanly."""

import ast
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
    GRAPH_REMAPS,
    Graph,
    Launcher,
    LaunchError,
    NodeSpec,
    default_graph_file,
    find_entry_point,
    graph_namespace,
    load_graph,
    names_taken,
    node_command,
    node_namespace,
)
from vizzy_runtime.testing import STOP_GRACE_S, bound_addresses, scaled, wait_until

OUTPUTS = {'/gaze/state', '/foveation/image', '/ses/cells', '/cylinders', '/mot/tracks',
           '/objects', '/vizzy/left/image_raw', '/vizzy/right/image_raw', '/joint_states',
           '/clock'}


# on the real tier every node runs on the real rclpy (VIZZY_RUNTIME=ros is inherited)
@pytest.mark.slow
@pytest.mark.live
def test_graph_starts_and_stops_cleanly(tmp_path):
    graph = load_graph(default_graph_file())
    assert {n.name for n in graph.nodes} == {'sim', 'gaze_controller', 'foveation', 'stereo_ses',
                                             'cylinder_detector', 'mot_planner', 'object_map'}
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(graph, output=log, grace_s=STOP_GRACE_S)
    disc = dds.Discovery()
    readers: dict[str, dds.RawReader] = {}
    heard: set[str] = set()

    def all_outputs_flowing() -> bool:
        # a message from every output means every node is spinning (not still starting up)
        for ep in disc.endpoints():
            if ep.is_writer and ep.topic in OUTPUTS and ep.topic not in readers:
                readers[ep.topic] = dds.RawReader(ep.topic, ep.typename, dds.QoS(reliable=False))
        heard.update(t for t, r in readers.items() if r.take(8))
        return heard == OUTPUTS

    try:
        launcher.start()
        up = wait_until(all_outputs_flowing, scaled(90))
        running = launcher.poll()
        sockets = {name: bound_addresses(proc.pid) for name, proc in launcher.procs.items()}
        cpu = launcher.cpu_seconds()       # what the benchmarks read: every node, CPU so far
    finally:
        codes = launcher.stop()
    log.seek(0)
    text = log.read()
    assert up, f'no messages on {OUTPUTS - heard}; launch log:\n{text[-3000:]}'
    assert set(cpu) == {n.name for n in graph.nodes} and all(v > 0 for v in cpu.values()), cpu
    assert all(code is None for code in running.values()), running
    assert codes == {name: 0 for name in codes}, f'unclean exit {codes}; log:\n{text[-3000:]}'
    # nothing reachable beyond loopback (the bundled runtime through loopback.py's shim, Fast DDS
    # through its profile)
    assert all(sockets.values()), sockets
    beyond = {name: [s for s in socks if s[1] not in ('127.0.0.1', '::1')]
              for name, socks in sockets.items()}
    assert not any(beyond.values()), beyond


def test_real_launch_file_reads_the_same_graph():
    launch_file = Path(default_graph_file()).parent.parent / 'launch' / 'graph.launch.py'
    source = launch_file.read_text()
    ast.parse(source)
    assert 'graph.yaml' in source and 'launch_ros' in source
    # a graph-wide namespace argument, with the same /clock, /tf, /tf_static remaps as vizzy launch
    assert "'namespace'" in source and 'PushROSNamespace(' in source
    for src, dst in GRAPH_REMAPS:
        assert f"SetRemap('{src}', '{dst}')" in source


def test_commands_carry_names_params_and_remaps():
    graph = load_graph(default_graph_file())
    sim = next(n for n in graph.nodes if n.name == 'sim')
    fov = next(n for n in graph.nodes if n.name == 'foveation')
    # the graph wires the node's generic input to the left camera, relatively
    assert 'image_raw:=vizzy/left/image_raw' in node_command(fov, graph.use_sim_time)
    fov.remappings = {'image_raw': 'cam/image'}
    cmd = node_command(fov, graph.use_sim_time)
    assert cmd[cmd.index('run') + 1:cmd.index('run') + 3] == ['foveation_node', 'foveation']
    assert '__node:=foveation' in cmd and 'image_raw:=cam/image' in cmd
    assert not any(a.startswith('__ns:=') for a in cmd)      # the root namespace: no __ns
    assert 'use_sim_time:=true' in cmd
    assert 'use_sim_time:=true' not in node_command(sim, graph.use_sim_time)  # the clock's source
    assert any(a.endswith('config/foveation.yaml') for a in cmd)


def test_a_namespaced_graph_moves_every_node(tmp_path):
    graph = load_graph(default_graph_file())
    for spec in graph.nodes:
        cmd = node_command(spec, graph.use_sim_time, '/head2', tmp_path)
        assert '__ns:=/head2' in cmd
        assert all(f'{src}:={dst}' in cmd for src, dst in GRAPH_REMAPS)
        # rcl applies a file's `sim:` section to /sim only: the node gets a copy keyed /**/sim
        files = [cmd[i + 1] for i, arg in enumerate(cmd) if arg == '--params-file']
        assert files and all(list(yaml.safe_load(Path(f).read_text())) == [f'/**/{spec.name}']
                             for f in files)
    # like launch_ros: a node's relative namespace goes inside the graph's, an absolute one stays
    assert node_namespace('/head2', 'left') == '/head2/left'
    assert node_namespace('/head2', '/other') == '/other' and node_namespace('', 'x') == 'x'
    assert graph_namespace('head2/') == '/head2' and graph_namespace('/') == ''
    with pytest.raises(LaunchError, match="namespace '/2nd'"):
        graph_namespace('/2nd')
    from vizzy_runtime.cli import build_parser
    assert build_parser().parse_args(['launch', '--namespace', '/head2']).namespace == '/head2'


@pytest.mark.slow
def test_graph_env_sets_defaults_the_caller_overrides(tmp_path, monkeypatch):
    graph = load_graph(default_graph_file())
    assert graph.env['OMP_NUM_THREADS'] == '1' and graph.env['OPENBLAS_NUM_THREADS'] == '1'
    monkeypatch.delenv('OMP_NUM_THREADS', raising=False)
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', '4')           # the caller's own value wins
    launcher = Launcher(graph)
    assert launcher.env['OMP_NUM_THREADS'] == '1' and launcher.env['OPENBLAS_NUM_THREADS'] == '4'
    assert "additional_env=env" in (Path(default_graph_file()).parent.parent / 'launch'
                                    / 'graph.launch.py').read_text()
    bad = tmp_path / 'bad.yaml'
    bad.write_text('env: {OMP_NUM_THREADS: [1]}\nnodes: []\n')
    with pytest.raises(LaunchError, match='env must map variable names'):
        load_graph(bad)


def test_bad_graphs_are_clear_errors(tmp_path):
    with pytest.raises(LaunchError, match='no such file'):
        load_graph(tmp_path / 'none.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('nodes:\n  - package: foveation_node\n')
    with pytest.raises(LaunchError, match='lacks executable'):
        load_graph(bad)
    bad.write_text('respawn_delay: -1\nnodes: []\n')
    with pytest.raises(LaunchError, match=r'graph: respawn_delay must be seconds in \[0, 3600\)'):
        load_graph(bad)
    bad.write_text('nodes:\n  - {package: p, executable: e, respawn: "yes"}\n')
    with pytest.raises(LaunchError, match='node e: respawn must be true or false'):
        load_graph(bad)
    graph = load_graph(default_graph_file())
    assert graph.respawns(graph.nodes[0]) == (True, 0.2)
    with pytest.raises(LaunchError, match="no executable 'nope' in package 'foveation_node'"):
        find_entry_point('foveation_node', 'nope')
    with pytest.raises(LaunchError, match="package 'nope_pkg' not found"):
        find_entry_point('nope_pkg', 'x')


@pytest.mark.slow
def test_cli_reports_errors_in_one_line():
    proc = subprocess.run([sys.executable, '-m', 'vizzy_runtime.cli', 'run', 'nope_pkg', 'x'],
                          capture_output=True, text=True, timeout=scaled(60))
    assert proc.returncode == 2
    assert proc.stderr.strip() == ("vizzy: package 'nope_pkg' not found or has no executables "
                                   '(run `make setup`)')
    proc = subprocess.run([sys.executable, '-m', 'vizzy_runtime.cli', 'bag', 'record', '-d', '1'],
                          capture_output=True, text=True, timeout=scaled(60))
    assert (proc.returncode, proc.stderr.strip()) == (
        2, 'vizzy: bag record: give topics to record or -a/--all (as ros2 bag record)')


@pytest.mark.parametrize('argv, said', [
    (['launch', '--duration', '-5'], "vizzy launch: argument --duration: '-5': expected a positive "
                                     'number of seconds'),
    (['launch', '--grace', '-1'], "vizzy launch: argument --grace: '-1': expected a non-negative "
                                  'number of seconds'),
    (['launch', '--duration', 'nan'], "argument --duration: 'nan': expected a positive number"),
    (['bag', 'play', 'x', '-r', '0'], "vizzy bag play: argument -r/--rate: '0': expected a "
                                      'positive number'),
    (['bag', 'record', '-a', '-d', 'inf'], "argument -d/--duration: 'inf': expected a positive"),
])
@pytest.mark.slow
def test_bad_numbers_are_refused_in_one_line_before_anything_starts(argv, said):
    proc = subprocess.run([sys.executable, '-m', 'vizzy_runtime.cli', *argv], capture_output=True,
                          text=True, timeout=scaled(60))
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert said in proc.stderr and not proc.stdout


@pytest.mark.slow
def test_a_parameter_value_no_node_could_take_is_refused_before_asking_one():
    from vizzy_runtime.param_cli import parse_value
    assert parse_value('levels', '5').value == 5
    assert parse_value('levels', str(2 ** 63 - 1)).value == 2 ** 63 - 1
    for bad, why in (('99999999999999999999999', '64-bit'),
                     ('[1, -99999999999999999999]', '64-bit'), ('[1, 2', 'not YAML')):
        with pytest.raises(ValueError, match=why):
            parse_value('levels', bad)
    proc = subprocess.run([sys.executable, '-m', 'vizzy_runtime.cli', 'param', 'set',
                           '/nowhere', 'levels', '99999999999999999999999'],
                          capture_output=True, text=True, timeout=scaled(60))
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert 'cannot read value' in proc.stderr and '64-bit' in proc.stderr


@pytest.mark.slow
def test_node_list_warns_of_nodes_that_share_a_name():
    """Two processes each with a node /twin (a second graph on the domain): `vizzy node list`
    lists the name once and warns on stderr, as ros2 node list does; one alone: no warning."""
    script = ('import time\n'
              'from vizzy_runtime.ros import rclpy\n'
              'rclpy.init()\n'
              'node = rclpy.create_node("twin")\n'
              'time.sleep(60)\n')
    env = {**os.environ, 'VIZZY_RUNTIME': 'bundled'}
    twins = [subprocess.Popen([sys.executable, '-c', script], env=env) for _ in range(2)]
    try:
        def listing() -> subprocess.CompletedProcess[str]:
            return subprocess.run([sys.executable, '-m', 'vizzy_runtime.cli', 'node', 'list',
                                   '--wait', '3'], capture_output=True, text=True,
                                  timeout=scaled(60), env=env)
        proc = listing()
        for _ in range(5):              # discovery of both may take a moment on a loaded machine
            if proc.stdout.split().count('/twin') == 1 and '/twin (2)' in proc.stderr:
                break
            proc = listing()
        assert proc.returncode == 0 and proc.stdout.split().count('/twin') == 1, proc
        assert 'share an exact name' in proc.stderr and '/twin (2)' in proc.stderr, proc.stderr
        twins.pop().kill()
        proc = listing()
        for _ in range(5):              # the killed participant's lease must run out first
            if 'share an exact name' not in proc.stderr:
                break
            time.sleep(2.0)
            proc = listing()
        assert '/twin' in proc.stdout.split() and 'share an exact name' not in proc.stderr, proc
    finally:
        for twin in twins:
            twin.kill()


@pytest.mark.slow
def test_the_launcher_finds_the_graph_s_names_taken_before_it_starts():
    """Issue 28 item 7: a second graph on the domain was silent chaos (two /clock sources, names
    listed once). Before starting, `vizzy launch` names the nodes whose names are taken."""
    script = ('import time\n'
              'from vizzy_runtime.ros import rclpy\n'
              'rclpy.init()\n'
              'nodes = [rclpy.create_node(n) for n in ("sim", "gaze_controller")]\n'
              'time.sleep(60)\n')
    env = {**os.environ, 'VIZZY_RUNTIME': 'bundled'}
    ours = Launcher(load_graph(default_graph_file())).full_names()
    assert names_taken(ours, 0.5) == []            # nobody there: no warning
    other = subprocess.Popen([sys.executable, '-c', script], env=env)
    try:
        taken: list[str] = []
        for _ in range(10):         # the other process's discovery on a loaded machine
            taken = names_taken(ours, 1.0)
            if taken:
                break
        assert taken == ['/gaze_controller', '/sim'], taken
        # in its own namespace the graph's names are free
        assert names_taken(Launcher(load_graph(default_graph_file()),
                                    namespace='robot2').full_names(), 0.5) == []
    finally:
        other.kill()


def test_default_transport_stays_on_loopback():
    xml = dds.loopback_config()
    assert '<NetworkInterface address="127.0.0.1"/>' in xml
    assert '<AllowMulticast>false</AllowMulticast>' in xml
    assert '<Peer address="127.0.0.1"/>' in xml
    assert not dds.lan_mode()


def _pid_running(pid: int) -> bool:
    """True while pid exists and is not a zombie."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell's background job starts


@pytest.mark.slow
def test_nodes_end_when_their_launcher_is_killed(tmp_path):
    """SIGKILL (or the OOM killer) gives the launcher no chance to stop its nodes: they end on
    their own (PR_SET_PDEATHSIG), standbys too, instead of running on orphaned."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mixed_support import graph_subset
    graph_file = graph_subset(tmp_path / 'graph.yaml', ['gaze_controller'], use_sim_time=False)
    proc = subprocess.Popen([sys.executable, '-m', 'vizzy_runtime.cli', 'launch', str(graph_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    pids: list[int] = []
    lines: list[str] = []
    watchdog = threading.Timer(180, proc.kill)
    watchdog.start()
    try:
        for line in proc.stdout:
            lines.append(line)
            pids += [int(p) for p in re.findall(r'process started with pid \[(\d+)\]', line)]
            if any('[gaze_controller-' in ln and 'INFO' in ln and 'launch' not in ln
                   for ln in lines):
                break
        assert len(pids) == 1 and _pid_running(pids[0]), ''.join(lines)
        proc.kill()
        proc.wait(timeout=scaled(30))
        deadline = time.monotonic() + scaled(60)
        while _pid_running(pids[0]) and time.monotonic() < deadline:
            time.sleep(0.2)
    finally:
        watchdog.cancel()
        if proc.poll() is None:
            proc.kill()
        for pid in pids:
            if _pid_running(pid):
                os.kill(pid, signal.SIGKILL)
    assert not _pid_running(pids[0]), f'node {pids[0]} outlived its SIGKILLed launcher'


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
        assert len(pids) == 2 and all(_pid_running(p) for p in pids), ''.join(lines)
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
    assert not [p for p in pids if _pid_running(p)], f'orphaned nodes {pids}:\n{text[-3000:]}'


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
def test_a_standby_takes_over_a_killed_node_and_is_dismissed_at_stop(tmp_path, monkeypatch):
    """respawn_standby: a spare process with the node's modules imported waits beside the node;
    after a SIGKILL it takes over (same pid as the spare) and /gaze/state flows from it; a new spare
    follows; stop() dismisses the spares (no process left). Prints the time from the kill to the
    first new message."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from mixed_support import graph_subset
    path = graph_subset(tmp_path / 'graph.yaml', ['gaze_controller'], use_sim_time=False)
    data = yaml.safe_load(path.read_text())
    data.update(respawn=True, respawn_delay=0.0, respawn_standby=True)
    path.write_text(yaml.safe_dump(data))
    monkeypatch.setattr(Launcher, 'STANDBY_AFTER_S', 0.0)
    log = open(tmp_path / 'launch.log', 'w+')  # noqa: SIM115 - the launcher's log
    launcher = Launcher(load_graph(path), output=log, grace_s=STOP_GRACE_S)
    reader = dds.RawReader('/gaze/state', 'active_vision_msgs/msg/GazeState',
                           dds.QoS(reliable=False))
    spares = []
    try:
        launcher.start()
        assert wait_until(lambda: bool(reader.take(8)), scaled(60)), (
            'gaze_controller never published')
        assert wait_until(lambda: 'gaze_controller' in launcher.standbys, scaled(30))
        spare = launcher.standbys['gaze_controller']
        spares.append(spare)
        assert wait_until(lambda: spare.pid in launcher.ready_standbys,
                          scaled(60)), 'the standby never got ready'
        first = launcher.procs['gaze_controller']
        killed_at = time.monotonic()
        os.killpg(first.pid, signal.SIGKILL)
        assert wait_until(lambda: launcher.procs['gaze_controller'] is spare, scaled(30))
        reader.take(64)
        assert wait_until(lambda: bool(reader.take(8)), scaled(60)), 'the standby never published'
        back_s = time.monotonic() - killed_at
        assert wait_until(lambda: launcher.standbys.get('gaze_controller') not in (None, spare),
                          scaled(30))
        spares.append(launcher.standbys['gaze_controller'])
    finally:
        codes = launcher.stop()
        dds.delete(reader)
    log.seek(0)
    text = log.read()
    print(f'standby: /gaze/state flowing again {back_s:.2f} s after SIGKILL')
    assert f'standby with pid [{spare.pid}] took over: gaze_controller (respawn 1)' in text, text
    assert codes == {'gaze_controller': 0}, text
    assert launcher.standbys == {} and all(p.poll() is not None for p in spares)


def test_respawn_standby_must_be_a_boolean(tmp_path):
    path = tmp_path / 'g.yaml'
    path.write_text('respawn_standby: 3\nnodes: [{package: p, executable: e}]\n')
    with pytest.raises(LaunchError, match='graph: respawn_standby must be true or false'):
        load_graph(path)
    path.write_text('respawn: true\nnodes: [{package: p, executable: e, respawn_standby: true}, '
                    '{package: p, executable: f}]\n')
    graph = load_graph(path)
    assert [graph.standby(n) for n in graph.nodes] == [True, False]

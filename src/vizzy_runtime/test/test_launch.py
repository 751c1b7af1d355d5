"""The shared graph description: the ROS-less launcher starts every node and stops them cleanly."""

import ast
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from vizzy_runtime import dds
from vizzy_runtime.launcher import (
    GRAPH_REMAPS,
    Launcher,
    LaunchError,
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

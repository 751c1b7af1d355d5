"""The ROS-less launcher: starts the graph of config/graph.yaml, one process per node.

The same YAML drives launch/graph.launch.py under `ros2 launch`, so the graph is described once.
Ctrl-C, SIGTERM or SIGHUP to the launcher (what `timeout`, systemd, docker stop and CI cancels
send), or the duration running out, sends SIGINT to every node, like ros2 launch, then SIGTERM and
SIGKILL to whatever is still running after a grace period; further signals during that stop are
ignored, so the launcher never exits with nodes left behind (each node runs in its own session and
sees no terminal signal of its own). The launcher names each node it had to escalate, and why.

A node with respawn_standby (on the bundled runtime) is forked by a zygote, `vizzy run --zygote`,
that did its imports once and stays beside it sharing those pages (zygote.py): a respawn is a
fork of it, not a cold start. procs[name] is then a ForkedNode, the node's Popen-like handle.

A graph-level namespace (`vizzy launch --namespace /head2`; `namespace:=/head2` under ros2 launch)
prefixes every node's namespace as launch_ros's PushROSNamespace does (a node's absolute namespace
stays), and adds GRAPH_REMAPS to every node so that absolute /clock, /tf and /tf_static users
(rclpy's time source, tools) follow the namespace too: two graphs in /head1 and /head2 on one
domain do not see each other. rcl applies a params file's bare `sim:` section to /sim only, so a
namespaced node gets a copy of each file whose bare keys read `/**/sim` (namespace_proof_params).

The launch arguments `scene:=`, `seed:=`, `params_file:=`, `namespace:=`, `use_sim_time:=` (`vizzy
launch [graph.yaml] key:=value ...`, or ros2 launch's) reach each node's command line through
launch_args.node_parameters, the function graph.launch.py uses too.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import yaml

from . import loopback
from .launch_args import LaunchArgs, LaunchError, node_parameters, param_assignment
from .launch_args import namespace_proof_params as namespace_proof_params  # re-exported
from .process_exit import LAUNCHER_PID_ENV
from .zygote import ForkedNode, ZygoteProcess

# Given to every node of a namespaced graph (before the node's own remappings, like SetRemap):
# relative targets resolve inside the namespace. At the root namespace they would change nothing.
GRAPH_REMAPS: tuple[tuple[str, str], ...] = (
    ('/clock', 'clock'), ('/tf', 'tf'), ('/tf_static', 'tf_static'))

_NAMESPACE = re.compile(r'(/[A-Za-z_][A-Za-z0-9_]*)+')


def graph_namespace(namespace: str | None) -> str:
    """'' for the root namespace, else an absolute namespace without a trailing '/'."""
    ns = (namespace or '').strip().rstrip('/')
    if not ns:
        return ''
    if not ns.startswith('/'):
        ns = '/' + ns
    if not _NAMESPACE.fullmatch(ns):
        raise LaunchError(f'namespace {namespace!r}: expected /name[/name...] (letters, digits and '
                          '_, each part not starting with a digit)')
    return ns


def node_namespace(graph_ns: str, node_ns: str) -> str:
    """A node's namespace inside the graph's (launch_ros prefix_namespace: absolute ones stay)."""
    if not graph_ns or node_ns.startswith('/'):
        return node_ns
    return f'{graph_ns}/{node_ns}' if node_ns else graph_ns


@dataclass
class NodeSpec:
    package: str
    executable: str
    name: str
    namespace: str = ''
    parameters: list[str] = field(default_factory=list)
    remappings: dict[str, str] = field(default_factory=dict)
    arguments: list[str] = field(default_factory=list)
    use_sim_time: bool | None = None  # None: the graph's value
    respawn: bool | None = None  # None: the graph's value
    respawn_delay: float | None = None  # [s]; None: the graph's value
    respawn_max_retries: int = -1  # as launch: -1 = no limit
    respawn_standby: bool | None = None  # None: the graph's value


@dataclass
class Graph:
    nodes: list[NodeSpec]
    use_sim_time: bool = False
    respawn: bool = False
    respawn_delay: float = 0.0
    respawn_standby: bool = False
    # environment defaults for every node (the caller's own environment wins)
    env: dict[str, str] = field(default_factory=dict)

    def respawns(self, spec: NodeSpec) -> tuple[bool, float]:
        return (self.respawn if spec.respawn is None else spec.respawn,
                self.respawn_delay if spec.respawn_delay is None else spec.respawn_delay)

    def standby(self, spec: NodeSpec) -> bool:
        """Whether the launcher forks this node from a zygote that keeps its modules imported
        (zygote.py), so that a respawn is a fork, not a cold start."""
        wanted = self.respawn_standby if spec.respawn_standby is None else spec.respawn_standby
        return wanted and self.respawns(spec)[0]


def share_dir(package: str) -> Path:
    """A package's share directory: the installed one under ROS 2, else its source folder
    src/<pkg>."""
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except Exception:  # noqa: BLE001 - no ROS 2, or not installed there: use the source tree
        pass
    try:
        module = importlib.import_module(package)
    except ImportError:
        raise LaunchError(f'package {package!r} is not installed (run `make setup`)') from None
    if module.__file__ is None:  # a namespace package: no source folder to point at
        raise LaunchError(f'package {package!r} has no source folder')
    return Path(module.__file__).resolve().parent.parent


def parse_parameter_sets(items: list[str]) -> dict[str, dict[str, Any]]:
    """['node.param=value', ...] (each value read as YAML) -> {node: {param: value}}: what a
    benchmark's --set gives every run's params file. ValueError names a bad item."""
    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, value = item.partition('=')
        node, dot, param = key.partition('.')
        if not (sep and dot and node and param):
            raise ValueError(f'--set {item!r}: expected node.parameter=value')
        out.setdefault(node, {})[param] = yaml.safe_load(value)
    return out


def default_graph_file() -> Path:
    return share_dir('vizzy_runtime') / 'config' / 'graph.yaml'


def load_graph(path: str | Path) -> Graph:
    p = Path(path)
    if not p.is_file():
        raise LaunchError(f'graph file {p}: no such file')
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise LaunchError(f'graph file {p}: not valid YAML ({exc})') from None
    if not isinstance(data, dict) or not isinstance(data.get('nodes'), list):
        raise LaunchError(f'graph file {p}: expected a mapping with a list under "nodes"')
    def respawn_fields(where: str, entry: dict[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if 'respawn' in entry:
            if not isinstance(entry['respawn'], bool):
                raise LaunchError(f'graph file {p}: {where}: respawn must be true or false')
            out['respawn'] = entry['respawn']
        if 'respawn_delay' in entry:
            delay = entry['respawn_delay']
            if (isinstance(delay, bool) or not isinstance(delay, (int, float))
                    or not 0 <= delay < 3600):
                raise LaunchError(f'graph file {p}: {where}: respawn_delay must be seconds in [0, '
                                  '3600)')
            out['respawn_delay'] = float(delay)
        if 'respawn_max_retries' in entry:
            retries = entry['respawn_max_retries']
            if isinstance(retries, bool) or not isinstance(retries, int) or retries < -1:
                raise LaunchError(f'graph file {p}: {where}: respawn_max_retries must be an '
                                  'integer >= -1')
            out['respawn_max_retries'] = retries
        if 'respawn_standby' in entry:
            if not isinstance(entry['respawn_standby'], bool):
                raise LaunchError(f'graph file {p}: {where}: respawn_standby must be true or false')
            out['respawn_standby'] = entry['respawn_standby']
        return out

    nodes = []
    for i, entry in enumerate(data['nodes']):
        missing = [k for k in ('package', 'executable') if not isinstance(entry, dict)
                   or k not in entry]
        if missing:
            raise LaunchError(f'graph file {p}: node #{i} lacks {", ".join(missing)}')
        name = entry.get('name') or entry['executable']
        nodes.append(NodeSpec(
            package=entry['package'], executable=entry['executable'],
            name=name, namespace=entry.get('namespace') or '',
            parameters=list(entry.get('parameters') or []),
            remappings=dict(entry.get('remappings') or {}),
            arguments=[str(a) for a in entry.get('arguments') or []],
            use_sim_time=entry.get('use_sim_time'), **respawn_fields(f'node {name}', entry)))
    graph_wide = respawn_fields('graph',
                                {k: v for k, v in data.items() if k != 'respawn_max_retries'})
    env = data.get('env') or {}
    if not isinstance(env, dict) or not all(isinstance(k, str) and k and '=' not in k
                                            and isinstance(v, (str, int, float))
                                            and not isinstance(v, bool) for k, v in env.items()):
        raise LaunchError(f'graph file {p}: env must map variable names to strings or numbers')
    return Graph(nodes=nodes, use_sim_time=bool(data.get('use_sim_time', False)),
                 env={k: str(v) for k, v in env.items()}, **graph_wide)


def find_entry_point(package: str, executable: str) -> importlib.metadata.EntryPoint:
    """The console_scripts entry point `ros2 run package executable` would start."""
    norm = package.replace('-', '_').lower()
    found = []
    for ep in importlib.metadata.entry_points(group='console_scripts'):
        dist = getattr(ep, 'dist', None)
        if dist is not None and dist.metadata['Name'].replace('-', '_').lower() == norm:
            found.append(ep)
            if ep.name == executable:
                return ep
    if not found:
        raise LaunchError(f'package {package!r} not found or has no executables (run `make setup`)')
    names = ', '.join(sorted(ep.name for ep in found))
    raise LaunchError(f'no executable {executable!r} in package {package!r} (it has: {names})')


def node_command(spec: NodeSpec, use_sim_time: bool, namespace: str = '',
                 params_dir: Path | None = None, args: LaunchArgs | None = None) -> list[str]:
    """The node's command line; use_sim_time: the graph's (a node's own value wins); namespace:
    the graph's (graph_namespace), '' for the root; params_dir: where a namespaced node's
    rewritten params files go (a new temporary folder if None); args: the launch arguments
    (launch_args.node_parameters: params_file after the node's files, scene and seed to the sim)."""
    find_entry_point(spec.package, spec.executable)  # fail before starting anything
    share = share_dir(spec.package)
    namespace = graph_namespace(namespace)
    ros_args = ['--ros-args', '-r', f'__node:={spec.name}']
    ns = node_namespace(namespace, spec.namespace)
    if ns:
        ros_args += ['-r', f'__ns:={ns}']
    files = []
    for rel in spec.parameters:
        path = (share / rel) if not os.path.isabs(rel) else Path(rel)
        if not path.is_file():
            raise LaunchError(f'node {spec.name}: parameters file {path} not found')
        files.append(path)
    if ns:
        params_dir = params_dir or Path(tempfile.mkdtemp(prefix='vizzy_launch_'))
    for item in node_parameters(spec.package, spec.executable, files,
                                spec.use_sim_time if spec.use_sim_time is not None
                                else use_sim_time, args or LaunchArgs(),
                                params_dir if ns else None):
        if isinstance(item, Path):
            ros_args += ['--params-file', str(item)]
        else:
            for name, value in item.items():
                ros_args += ['-p', param_assignment(name, value)]
    for src, dst in (GRAPH_REMAPS if namespace else ()):
        ros_args += ['-r', f'{src}:={dst}']
    for src, dst in spec.remappings.items():
        ros_args += ['-r', f'{src}:={dst}']
    return [sys.executable, '-m', 'vizzy_runtime.cli', 'run', spec.package, spec.executable,
            *spec.arguments, *ros_args]


def zygote_command(cmd: list[str]) -> list[str]:
    """node_command's command for a respawn_standby node: `vizzy run --zygote ...` imports the
    node once and forks it, again at each `go` on its stdin (zygote.py)."""
    i = cmd.index('run')
    return [*cmd[:i + 1], '--zygote', *cmd[i + 1:]]


def _pump(prefix: str, stream: TextIO, out: TextIO,
          on_line: Callable[[str], None] | None = None,
          on_end: Callable[[], None] | None = None) -> None:
    for line in stream:
        out.write(f'{prefix} {line}')
        out.flush()
        if on_line is not None:
            on_line(line)
    if on_end is not None:
        on_end()


class LaunchStopped(KeyboardInterrupt):
    """SIGTERM or SIGHUP reached the launcher: stop the graph as Ctrl-C does."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise_stop(signum: int, _frame: Any) -> None:
    raise LaunchStopped(signum)


class stop_on_signals:
    """While active (main thread only), SIGTERM and SIGHUP raise LaunchStopped (a KeyboardInterrupt)
    so the launcher's clean-up runs instead of the process ending with its nodes orphaned; SIGINT
    raises KeyboardInterrupt even where the launcher was started with it ignored (a shell's
    background job, a parent that ignores it), or nothing could stop the graph with SIGINT."""

    SIGNALS = (signal.SIGTERM, signal.SIGHUP)

    def __enter__(self) -> stop_on_signals:
        self._previous: dict[int, Any] = {}
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._previous[sig] = signal.signal(sig, _raise_stop)
            self._previous[signal.SIGINT] = signal.signal(signal.SIGINT, signal.default_int_handler)
        return self

    def __exit__(self, *_exc: Any) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


class Launcher:
    """Starts and stops a Graph's processes."""

    def __init__(self, graph: Graph, *, env: dict[str, str] | None = None, grace_s: float = 5.0,
                 output: TextIO | None = None, namespace: str = '',
                 args: LaunchArgs | None = None) -> None:
        self.graph = graph
        # launch arguments (`vizzy launch key:=value`); namespace (--namespace) wins over theirs
        self.args = args or LaunchArgs()
        self.namespace = graph_namespace(namespace or self.args.namespace)
        self.use_sim_time = (graph.use_sim_time if self.args.use_sim_time is None
                             else self.args.use_sim_time)
        self._params_dir = tempfile.TemporaryDirectory(prefix='vizzy_launch_',
                                                       ignore_cleanup_errors=True)
        # nodes of the bundled runtime bind their receive sockets to 127.0.0.1 (loopback.py)
        self.env = dict(loopback.preload_env({**graph.env, **os.environ, **(env or {}),
                                              'PYTHONUNBUFFERED': '1',
                                              LAUNCHER_PID_ENV: str(os.getpid())}))
        self.grace_s = grace_s
        self.output = output or sys.stdout
        # respawn_standby forks from zygotes on the bundled runtime only: importing the real rclpy
        # starts threads, and fork() after threads is unsafe (there a respawn starts cold)
        self.forks = loopback.bundled_runtime(self.env)
        # each node's process: a Popen, or a ForkedNode (the Popen-like handle of a node its
        # zygote forked: respawn_standby)
        self.procs: dict[str, subprocess.Popen[str] | ForkedNode] = {}
        # respawn_standby nodes: the zygote that forks each (zygote.py), and the pids of those
        # done importing (they have forked their node)
        self.zygotes: dict[str, ZygoteProcess] = {}
        self.ready_standbys: set[int] = set()
        self.escalated: dict[str, str] = {}  # node -> the signal it needed beyond SIGINT, and why
        self.respawned: dict[str, int] = {}  # node -> times it was started again
        self.stop_seconds: dict[str, float] = {}  # node -> seconds from stop()'s SIGINT to its exit
        self._commands: dict[str, tuple[NodeSpec, list[str], int]] = {}
        self._threads: list[threading.Thread] = []
        self._stopping = threading.Event()
        self._reported: set[str] = set()
        self._pending_respawns = 0
        self._supervisor: threading.Thread | None = None
        self._started_at: dict[str, float] = {}

    @property
    def standbys(self) -> dict[str, subprocess.Popen[str]]:
        """The zygotes' processes by node (what a node's respawn forks from; benchmarks)."""
        return {name: z.proc for name, z in self.zygotes.items()}

    def full_names(self) -> list[str]:
        """The full name (namespace and name) of each node of the graph, as it will run."""
        out = []
        for spec in self.graph.nodes:
            ns = node_namespace(self.namespace, spec.namespace).rstrip('/')
            if ns and not ns.startswith('/'):
                ns = '/' + ns
            out.append(f'{ns}/{spec.name}')
        return out

    def start(self) -> None:
        """Start every node (and the supervisor that reports exits and respawns)."""
        commands = [(spec, node_command(spec, self.use_sim_time, self.namespace,
                                        Path(self._params_dir.name), self.args))
                    for spec in self.graph.nodes]
        for index, (spec, cmd) in enumerate(commands, 1):
            self._commands[spec.name] = (spec, cmd, index)
            self._spawn(spec.name)
        self._supervisor = threading.Thread(target=self._supervise, name='launch-supervisor',
                                            daemon=True)
        self._supervisor.start()

    def _popen(self, name: str, cmd: list[str],
               zygote: Callable[[subprocess.Popen[str]], ZygoteProcess] | None = None
               ) -> subprocess.Popen[str]:
        index = self._commands[name][2]
        proc = subprocess.Popen(cmd, env=self.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.PIPE if zygote else None, text=True, bufsize=1,
                                start_new_session=True)
        handle = zygote(proc) if zygote else None
        t = threading.Thread(target=_pump, args=(f'[{name}-{index}]', proc.stdout, self.output,
                                                 handle and handle.on_line,
                                                 handle and handle.ended.set), daemon=True)
        t.start()
        self._threads.append(t)
        if handle is not None:
            self.zygotes[name] = handle
        return proc

    def _spawn(self, name: str) -> None:
        self._started_at[name] = time.monotonic()
        if self.forks and self.graph.standby(self._commands[name][0]):
            # a fork of the node's zygote (a fresh zygote at the first start, or if it died);
            # "process started" is written when the zygote reports the fork (_forked)
            zygote = self.zygotes.get(name)
            node = zygote.respawn() if zygote is not None else None
            if node is None:
                self._popen(name, zygote_command(self._commands[name][1]),
                            lambda proc: ZygoteProcess(proc, lambda n: self._forked(name, n)))
                node = self.zygotes[name].node
            self.procs[name] = node
            return
        proc = self._popen(name, self._commands[name][1])
        self.procs[name] = proc
        self._report_started(name, proc.pid)

    def _forked(self, name: str, node: ForkedNode) -> None:
        """A zygote has forked name's node (called from its output pump)."""
        self.ready_standbys.add(node.zygote.proc.pid)
        self._report_started(name, node.pid,
                             f' (forked by its zygote, pid [{node.zygote.proc.pid}])')

    def _report_started(self, name: str, pid: int, how: str = '') -> None:
        """The log's "process started" line (a respawn says which)."""
        again = f' (respawn {self.respawned[name]})' if self.respawned.get(name) else ''
        self.output.write(f'[INFO] [launch]: process started with pid [{pid}]: {name}{again}'
                          f'{how}\n')

    def _supervise(self) -> None:
        """Report each node's exit; respawn the nodes whose graph entry asks for it (after their
        respawn_delay, up to respawn_max_retries) until stop() begins. A node that exits with
        status 2 (a start-up error: bad parameter or argument) is not respawned: it would fail
        the same way again."""
        due: dict[str, float] = {}
        while not self._stopping.is_set():
            for name, proc in list(self.procs.items()):
                code = proc.poll()
                if code is None or name in self._reported:
                    continue
                self._reported.add(name)
                spec = self._commands[name][0]
                respawn, delay = self.graph.respawns(spec)
                retries = self.respawned.get(name, 0)
                level = 'INFO' if code == 0 else 'ERROR'
                if respawn and code != 2 and (spec.respawn_max_retries < 0
                                              or retries < spec.respawn_max_retries):
                    due[name] = time.monotonic() + delay
                    self.output.write(f'[{level}] [launch]: process {name} has finished (exit code '
                                      f'{code}); respawning in {delay:g} s\n')
                else:
                    why = ' (a start-up error: not respawned)' if respawn and code == 2 else ''
                    self.output.write(f'[{level}] [launch]: process {name} has finished '
                                      f'(exit code {code}){why}\n')
                    if name in self.zygotes:   # no fork will follow
                        self.zygotes[name].dismiss()
            for name, when in list(due.items()):
                if time.monotonic() >= when and not self._stopping.is_set():
                    del due[name]
                    self.respawned[name] = self.respawned.get(name, 0) + 1
                    self._reported.discard(name)
                    self._spawn(name)
            self._pending_respawns = len(due)
            self._stopping.wait(0.05)

    def cpu_seconds(self) -> dict[str, float]:
        """Each running node process's user + system CPU time so far [s] (benchmarks)."""
        from .lockstep import process_cpu_seconds
        out = {}
        for name, proc in list(self.procs.items()):
            cpu = process_cpu_seconds(proc.pid)
            if cpu is not None:
                out[name] = cpu
        return out

    def poll(self) -> dict[str, int | None]:
        return {name: proc.poll() for name, proc in list(self.procs.items())}

    def wait(self, duration: float | None = None) -> None:
        """Until duration passes or every node has exited for good (the supervisor reports exits
        and respawns)."""
        deadline = None if duration is None else time.monotonic() + duration
        while deadline is None or time.monotonic() < deadline:
            states = self.poll()
            if (all(code is not None for code in states.values()) and not self._pending_respawns
                    and set(states) <= self._reported):
                return
            time.sleep(0.1)

    def stop(self) -> dict[str, int | None]:
        """SIGINT everyone, then escalate; returns exit codes. Nodes that needed SIGTERM or SIGKILL
        are reported (one line each) and listed in self.escalated. Signals to the launcher are
        ignored meanwhile: an interrupted stop would leave nodes running."""
        ignored = {}
        if threading.current_thread() is threading.main_thread():
            ignored = {sig: signal.signal(sig, signal.SIG_IGN)
                       for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
        self._stopping.set()  # no respawn from here on
        if self._supervisor is not None:
            self._supervisor.join()
        for zygote in self.zygotes.values():
            zygote.dismiss()   # each ends once its node has (below)
        try:
            previous: tuple[str, float] | None = None
            stop_started = time.monotonic()

            def note_exits(procs: dict[str, subprocess.Popen[str] | ForkedNode]) -> None:
                for name, proc in procs.items():
                    if name not in self.stop_seconds and proc.poll() is not None:
                        self.stop_seconds[name] = round(time.monotonic() - stop_started, 2)

            for sig, grace in ((signal.SIGINT, self.grace_s), (signal.SIGTERM, 2.0),
                               (signal.SIGKILL, 1.0)):
                alive = {n: p for n, p in self.procs.items() if p.poll() is None}
                if not alive:
                    break
                if previous is not None and sig == signal.SIGTERM:
                    self._dump_stacks(alive)
                for name, proc in alive.items():
                    if previous is not None:
                        self.escalated[name] = f'{signal.Signals(sig).name} after {previous[0]}'
                        why = ' (its threads\' stacks are above)' if sig == signal.SIGTERM else ''
                        self.output.write(
                            f'[WARNING] [launch]: process {name} (pid {proc.pid}) still running '
                            f'{previous[1]:g} s after {previous[0]}{why}: sending '
                            f'{signal.Signals(sig).name}\n')
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(proc.pid, sig)
                end = time.monotonic() + grace
                while time.monotonic() < end and any(p.poll() is None for p in alive.values()):
                    note_exits(alive)
                    time.sleep(0.02)
                note_exits(alive)
                previous = (signal.Signals(sig).name, grace)
            self._end_zygotes()
            for t in self._threads:
                t.join(timeout=1.0)
            self._params_dir.cleanup()   # the namespaced nodes' params files, read at start-up
            return self.poll()
        finally:
            for sig, handler in ignored.items():
                signal.signal(sig, handler)

    def _dump_stacks(self, alive: dict[str, subprocess.Popen[str] | ForkedNode]) -> None:
        """Ask nodes that ignored SIGINT for their threads' stacks (node_tools.run registers
        faulthandler on SIGUSR1; they go to the node's output, i.e. this log), so the log says
        where each was stuck."""
        for proc in alive.values():
            with contextlib.suppress(ProcessLookupError):
                os.kill(proc.pid, signal.SIGUSR1)
        time.sleep(0.3)

    def _end_zygotes(self) -> None:
        """Their nodes have ended: each zygote ends at the end of its stdin (dismissed in stop());
        SIGKILL for one that does not."""
        zygotes, self.zygotes = self.zygotes, {}
        for proc in (z.proc for z in zygotes.values()):
            try:
                proc.wait(2.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()

    def failed(self, codes: dict[str, int | None] | None = None) -> dict[str, int | None]:
        """Nodes that really failed: a non-zero exit that is neither the SIGINT they were sent nor
        the escalation stop() reported."""
        codes = self.poll() if codes is None else codes
        return {n: c for n, c in codes.items()
                if c not in (0, None, -signal.SIGINT, 128 + signal.SIGINT)
                and n not in self.escalated}


# How long the launcher listens to the domain before starting a graph (more while a peer found
# is still being discovered): a second graph there is found in well under a second on loopback.
NAME_CHECK_WAIT_S = 1.0


def names_taken(names: list[str], wait_s: float = NAME_CHECK_WAIT_S) -> list[str]:
    """Which of these full node names a node on the domain already has (a second graph, a second
    sim: their topics and /clock would mix with ours)."""
    from .peers import discover_nodes, full_name
    found = {full_name(info) for info in discover_nodes(wait_s)}
    return sorted(set(names) & found)


def launch(graph_file: str | Path | None = None, duration: float | None = None,
           env: dict[str, str] | None = None, namespace: str = '',
           grace_s: float = 5.0, view_port: int | None = None,
           check_names: bool = True, args: LaunchArgs | None = None) -> Launcher:
    """Run a graph (in namespace, '' for the root) until duration, Ctrl-C, SIGTERM or SIGHUP and
    stop it cleanly (SIGINT, then SIGTERM to nodes still running grace_s seconds later); returns
    the stopped Launcher (exit codes: poll(); failures: failed(); escalations: escalated).
    view_port: serve the graph to Foxglove on that port meanwhile (live_view.py); None: no view.
    check_names: first warn (one line) if nodes on the domain already have the graph's names.
    args: launch arguments (launch_args.LaunchArgs: scene, seed, params_file, use_sim_time)."""
    graph = load_graph(graph_file or default_graph_file())
    launcher = Launcher(graph, env=env, namespace=namespace, grace_s=grace_s, args=args)
    view = None
    with stop_on_signals():
        try:
            if check_names:
                taken = names_taken(launcher.full_names())
                if taken:
                    launcher.output.write(
                        f'[WARNING] [launch]: node names already taken on ROS_DOMAIN_ID '
                        f'{os.environ.get("ROS_DOMAIN_ID", "0")}: {", ".join(taken)}; another '
                        'graph runs there, and two graphs on one domain mix their topics and '
                        'clocks: stop it, or start this one with another ROS_DOMAIN_ID or '
                        '--namespace\n')
                    launcher.output.flush()
            if view_port is not None:
                from .live_view import start_or_warn
                view = start_or_warn(view_port)
            launcher.start()
            launcher.wait(duration)
        except LaunchStopped as stop:
            launcher.output.write(f'[WARNING] [launch]: stopping on {stop}\n')
        except KeyboardInterrupt:
            launcher.output.write('[WARNING] [launch]: user interrupted with ctrl-c (SIGINT)\n')
        finally:
            launcher.stop()
            if view is not None:
                view.stop()
    return launcher

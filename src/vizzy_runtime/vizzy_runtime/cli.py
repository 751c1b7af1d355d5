"""`vizzy`: the ros2 verbs people know, for machines without ROS 2.

    vizzy run <package> <executable> [args] [--ros-args ...]
    vizzy launch [graph.yaml] [key:=value ...] [--duration S] [--namespace /NS] [--grace S]
                 [--view-port P | --no-view]
                 keys as ros2 launch vizzy_runtime graph.launch.py: scene:= (tabletop |
                 visual_search | pedestrians), seed:=, params_file:=, namespace:=, use_sim_time:=
    vizzy view [--port 8765] [--host ADDR]            (Foxglove live view of the running graph)
    vizzy topic list [-t] | echo <topic> [type] [--once] | hz <topic> [--duration S]
              | info <topic> [-v] | pub <topic> <type> '<yaml>' [-r HZ] [-1 | -t N] [-w N]
    vizzy node list | info <node>
    vizzy service list [-t] | type <service> | call <service> <type> '<yaml>'
    vizzy interface list [-m] [-s] | show <pkg/msg/Type> | packages | package <pkg>
    vizzy param list <node> | get <node> <name> | set <node> <name> <value> | describe <node> <name>
    vizzy bag record [-o DIR] [-a | topics...] [-d S]
              | play <bag> [-r RATE] [--clock [HZ]] [--remap FROM:=TO ...] [--start-offset S]
              | info <bag> [--check] | reindex <bag>

Each verb has ros2's flags and prints what ros2 prints (cli_topic.py, cli_node.py,
cli_service.py, cli_interface.py, param_cli.py).

Everything speaks ROS 2's DDS wire protocol on loopback, so real ROS 2 tools on this host see
the same topics. Errors are one line naming what and where; the exit code is non-zero.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from typing import Any, NoReturn

from .cli_types import (
    die,
    nonnegative_seconds,
    port_number,
    positive_number,
    positive_seconds,
)

DEFAULT_VIEW_PORT = 8765   # Foxglove's default (live_view.DEFAULT_PORT; not imported: it is slow)


# --- run / launch ------------------------------------------------------------------------------

def cmd_run(ns: argparse.Namespace) -> int:
    from .launcher import find_entry_point
    from .process_exit import end_with_launcher
    end_with_launcher()                  # started by `vizzy launch`: end when it does
    ep = find_entry_point(ns.package, ns.executable)
    main = ep.load()
    if ns.zygote:
        from .zygote import serve
        _prepare_zygote(ep.module)
        return serve(main, [ns.executable, *ns.args])
    sys.argv = [ns.executable, *ns.args]
    result = main()
    return int(result or 0)


def _prepare_zygote(module_name: str) -> None:
    """What a zygote does before it forks the node, without joining the network or starting a
    thread: the runtime's warm-up and the node module's own `standby_prepare()` if it has one
    (the sim probes its OpenGL backend in a child process; the answer is cached for the node)."""
    from .ros import warm_up
    warm_up()
    prepare = getattr(sys.modules.get(module_name), 'standby_prepare', None)
    if callable(prepare):
        prepare()


def launch_arguments(items: list[str], namespace: str = '') -> tuple[str | None, Any]:
    """`vizzy launch`'s positionals: [graph.yaml] and ros2-launch-style key:=value arguments
    (launch_args.VIZZY_LAUNCH_KEYS) -> (graph file or None, LaunchArgs); namespace: --namespace.
    ValueError (LaunchError), one line, for an unknown key, a bad value or two graph files."""
    from .launch_args import VIZZY_LAUNCH_KEYS, LaunchError, launch_args, split_key_values
    graphs = [item for item in items if ':=' not in item]
    if len(graphs) > 1:
        raise LaunchError(f'launch: one graph file, got {len(graphs)} ({", ".join(graphs)}); '
                          'launch arguments read key:=value')
    values = split_key_values([item for item in items if ':=' in item], VIZZY_LAUNCH_KEYS)
    if namespace and values.get('namespace', namespace) != namespace:
        raise LaunchError(f'launch: --namespace {namespace} and namespace:={values["namespace"]} '
                          'disagree: give one')
    if namespace:
        values['namespace'] = namespace
    return (graphs[0] if graphs else None), launch_args(values)


def cmd_launch(ns: argparse.Namespace) -> int:
    from .launcher import launch
    graph, args = launch_arguments(ns.args, ns.namespace)
    launcher = launch(graph, ns.duration, grace_s=ns.grace, args=args,
                      view_port=None if ns.no_view else ns.view_port)
    failed = launcher.failed()
    for name, code in failed.items():
        print(f'vizzy: launch: node {name} failed (exit code {code}); see its output above',
              file=sys.stderr)
    return 1 if failed else 0


def loopback_note(host: str | None) -> str | None:
    """One line when --host asks for every interface but this process binds loopback only
    (loopback.py's bind shim turns a wildcard bind into 127.0.0.1), else None."""
    from . import loopback
    if host not in (loopback.WILDCARD_V4, '::', '') or not loopback.wanted():
        return None
    return (f'vizzy: view: --host {host or "(any)"} serves on {loopback.LOOPBACK_V4} only: '
            'vizzy keeps its sockets on loopback; set VIZZY_DDS_LAN=1 to serve every interface')


def cmd_view(ns: argparse.Namespace) -> int:
    from .live_view import LiveView
    note = loopback_note(ns.host)
    if note:
        print(note, file=sys.stderr, flush=True)
    view = LiveView(host=ns.host, port=ns.port)
    try:
        view.start()
    except Exception as exc:  # noqa: BLE001 - e.g. the port is taken
        return die(f'view: cannot serve on {view.host}:{ns.port} ({exc})')
    print(f'serving the graph to Foxglove on {view.url} (Open connection > Foxglove WebSocket; '
          'layout: src/vizzy_runtime/config/foxglove_layout.json); Ctrl-C to stop', flush=True)
    done = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: done.set())
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        done.wait(ns.duration)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        view.stop()
    served = ', '.join(f'{t} {n}'
                       for t, n in sorted(view.sent.items())) or 'nothing (no subscriber)'
    print(f'served: {served}', flush=True)
    return 0


# --- bags --------------------------------------------------------------------------------------

def _print_counts(counts: dict[str, int]) -> None:
    for topic, count in sorted(counts.items()):
        print(f'{topic}: {count}')


def cmd_bag_record(ns: argparse.Namespace) -> int:
    if not ns.all and not ns.topics:
        return die('bag record: give topics to record or -a/--all (as ros2 bag record)')
    # SIGINT/SIGTERM at any moment from here ends the recording with the bag finished. Until the
    # Recorder exists (the bag package's imports take seconds on a loaded machine) a signal is
    # only noted and stops it as soon as it does; Python's own handler would raise
    # KeyboardInterrupt there instead: status 0, no bag, not a word (issue 28 item 8).
    recorder: Any = None
    noted: list[int] = []

    def on_signal(signum: int, frame: Any) -> None:
        noted.append(signum)
        if recorder is not None:
            recorder.handle_signal(signum, frame)

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        from .bag import Recorder, default_bag_name
        recorder = Recorder(ns.output or default_bag_name(), None if ns.all else ns.topics,
                            exclude=ns.exclude_topics or (), include_hidden=ns.include_hidden)
        if noted:
            recorder.stop()
        counts = recorder.run(ns.duration, handle_signals=False)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    _print_counts(counts)
    return 0


def cmd_bag_play(ns: argparse.Namespace) -> int:
    from .bag import Player
    from .bag.play import parse_remaps
    from .bag.reader import lost_messages
    player = Player(ns.bag, rate=ns.rate, topics=ns.topics, loop=ns.loop,
                    wait_for_subscribers=ns.wait_for_subscribers,
                    remap=parse_remaps(ns.remap or ()), start_offset=ns.start_offset,
                    clock_hz=ns.clock, progress_hz=ns.progress_bar_update_rate)
    _print_counts(player.run())
    skipped = player.corrupt_chunks  # each was also named in a warning when it was skipped
    if skipped:
        print(f'skipped corrupt chunks: {len(skipped)} ({lost_messages(skipped)})')
    return 0


def cmd_bag_info(ns: argparse.Namespace) -> int:
    from .bag import bag_check, bag_info
    print(bag_info(ns.bag), end='')
    if not ns.check:
        return 0
    result = bag_check(ns.bag)
    print('\n'.join(result.lines()))
    return 0 if result.ok else 1


def cmd_bag_reindex(ns: argparse.Namespace) -> int:
    from .bag import reindex_bag
    from .bag.reader import lost_messages
    done = reindex_bag(ns.bag)
    meta = done.metadata
    line = (f'{ns.bag}: rebuilt metadata.yaml: {meta.message_count} messages on '
            f'{len(meta.topics)} topics in {len(meta.files)} file(s)')
    if done.recovered:
        line += f'; finished {len(done.recovered)} unfinished file(s)'
    if done.dropped:  # the bag is whole again: exit 0 (the warnings above name each chunk)
        line += (f'; dropped {len(done.dropped)} corrupt chunk(s) with '
                 f'{lost_messages(done.dropped)}')
    print(line)
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse with its errors in one line (`vizzy launch: argument --duration: ...`), exit 2;
    the subcommands' parsers are of this class too."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f'{self.prog}: {message} (see {self.prog} --help)\n')


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog='vizzy', description=__doc__,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest='verb', required=True)

    run = sub.add_parser('run', help='run one node (like ros2 run)')
    run.add_argument('--zygote', action='store_true',
                     help='import the node once, then fork it, and again at each "go" on stdin '
                          "(the launcher's respawn_standby; vizzy_runtime/zygote.py)")
    run.add_argument('package')
    run.add_argument('executable')
    run.add_argument('args', nargs=argparse.REMAINDER, help='node arguments, incl. --ros-args ...')
    run.set_defaults(func=cmd_run)

    la = sub.add_parser('launch', help='start the graph, one process per node (like ros2 launch)')
    la.add_argument('args', nargs='*', metavar='[graph.yaml] [key:=value]',
                    help='graph YAML (default: vizzy_runtime config/graph.yaml), then launch '
                         'arguments as ros2 launch vizzy_runtime graph.launch.py takes them: '
                         'scene:=tabletop|visual_search|pedestrians, seed:=N, params_file:=FILE '
                         '(after every node\'s own files: its /** or <node> sections override '
                         'them), namespace:=/NS, use_sim_time:=true|false')
    la.add_argument('--duration', type=positive_seconds, help='stop after this many seconds')
    la.add_argument('--namespace', default='',
                    help='put the whole graph in this namespace (e.g. /head2), like ros2 launch '
                         'vizzy_runtime graph.launch.py namespace:=/head2')
    la.add_argument('--grace', type=nonnegative_seconds, default=5.0, metavar='S',
                    help='on stop, seconds from SIGINT to SIGTERM for nodes still running '
                         '(default 5; like ros2 launch sigterm_timeout)')
    la.add_argument('--view-port', type=port_number, default=DEFAULT_VIEW_PORT, metavar='PORT',
                    help='serve the graph to Foxglove on ws://127.0.0.1:PORT (default '
                         f'{DEFAULT_VIEW_PORT})')
    la.add_argument('--no-view', action='store_true', help='no Foxglove live view')
    la.set_defaults(func=cmd_launch)

    view = sub.add_parser('view',
                          help='serve the running graph (or a bag being played) to Foxglove')
    view.add_argument('--port', type=port_number, default=DEFAULT_VIEW_PORT,
                      help=f'WebSocket port (default {DEFAULT_VIEW_PORT}; 0: any free one)')
    view.add_argument('--host', default=None,
                      help='address to listen on (default 127.0.0.1; every interface with '
                           'VIZZY_DDS_LAN=1)')
    view.add_argument('--duration', type=positive_seconds, help='stop after this many seconds')
    view.set_defaults(func=cmd_view)

    from . import cli_interface, cli_node, cli_service, cli_topic, param_cli
    cli_topic.add_parser(sub)
    cli_node.add_parser(sub)
    cli_service.add_parser(sub)
    cli_interface.add_parser(sub)
    param_cli.add_parser(sub)

    bag = sub.add_parser('bag', help='rosbag2 (MCAP) bags').add_subparsers(
        dest='bag_verb', required=True)
    rec = bag.add_parser('record')
    rec.add_argument('topics', nargs='*')
    rec.add_argument('-a', '--all', action='store_true')
    rec.add_argument('-o', '--output', help='bag directory to create (default rosbag2_<time>)')
    rec.add_argument('-d', '--duration', type=positive_seconds,
                     help='seconds (default: until Ctrl-C)')
    rec.add_argument('--include-hidden', action='store_true', help='also hidden topics (_name)')
    rec.add_argument('--exclude-topics', nargs='+', metavar='TOPIC', help='topics not to record')
    rec.set_defaults(func=cmd_bag_record)
    play = bag.add_parser('play')
    play.add_argument('bag')
    play.add_argument('-r', '--rate', type=positive_number, default=1.0)
    play.add_argument('--topics', nargs='+')
    play.add_argument('-l', '--loop', action='store_true')
    play.add_argument('--wait-for-subscribers', type=nonnegative_seconds, default=0.0,
                      metavar='SECONDS')
    play.add_argument('--clock', type=positive_number, nargs='?', const=40.0, default=0.0,
                      metavar='HZ',
                      help='publish /clock at this frequency (default 40 Hz when given without '
                           "one) from the bag's time, as a ROS time source for nodes with "
                           "use_sim_time; the bag's own /clock is then not played")
    play.add_argument('--remap', '-m', nargs='+', metavar='FROM:=TO',
                      help='topics to remap, e.g. /vizzy/left/image_raw:=/replay/left')
    play.add_argument('--start-offset', type=nonnegative_seconds, default=0.0, metavar='S',
                      help='start this many seconds into the bag')
    play.add_argument('--progress-bar-update-rate', type=float, default=3.0, metavar='HZ',
                      help='progress line on stderr ([bag time] Duration played/total [R]unning '
                           'or [D]elayed) this many times a second (default 3; 0: off; '
                           'negative: at every message)')
    play.set_defaults(func=cmd_bag_play)
    info = bag.add_parser('info')
    info.add_argument('bag')
    info.add_argument('--check', action='store_true',
                      help='also decompress every chunk and check its CRC (exit 1 if damaged)')
    info.set_defaults(func=cmd_bag_info)
    reindex = bag.add_parser('reindex', help='repair a killed recording, drop corrupt chunks and '
                             'rebuild metadata.yaml')
    reindex.add_argument('bag')
    reindex.set_defaults(func=cmd_bag_reindex)
    return p


def _bag_error() -> type[Exception]:
    # imported on the error path only: before `bag record` has its Ctrl-C handler, a second of
    # importing the bag package is a second in which Ctrl-C ends it with no bag (issue 28 item 8)
    from .bag import BagError
    return BagError


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    ns, extra = parser.parse_known_args(argv)
    if extra and ns.verb == 'launch' and all(':=' in item for item in extra):
        ns.args += extra   # key:=value after an option (`g.yaml --duration 5 scene:=x`)
    elif extra:
        parser.error(f'unrecognized arguments: {" ".join(extra)}')
    logging.basicConfig(level=logging.INFO, format='[%(levelname)s] %(message)s')
    try:
        return ns.func(ns)
    except KeyboardInterrupt:
        return 0
    except (_bag_error(), ValueError, TimeoutError, FileNotFoundError, KeyError) as err:
        # a KeyError's str() is its repr (the name in quotes): print its message instead
        return die(str(err.args[0]) if isinstance(err, KeyError) and err.args else str(err))


def console_main() -> NoReturn:
    """The `vizzy` program: main() in a process whose sockets bind 127.0.0.1 (loopback.py),
    ended without the interpreter's finalization (process_exit.py says why)."""
    from .loopback import exec_loopback_bound
    from .process_exit import run_then_exit
    exec_loopback_bound()
    run_then_exit(main)


if __name__ == '__main__':
    console_main()

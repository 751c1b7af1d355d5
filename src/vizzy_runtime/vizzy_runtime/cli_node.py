"""`vizzy node list|info`: ros2 node's verbs and output layout (Jazzy's ros2node).

    vizzy node list
    vizzy node info /node [--include-hidden]

A node's topics and services come from the GUIDs its process announces on ros_discovery_info
(rclpy_compat.graph) matched against the DDS endpoints discovered, as rmw's graph cache does.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from typing import Any

from .cli_types import die, nonnegative_seconds

# ros2node.api.INFO_NONUNIQUE_WARNING_TEMPLATE
NONUNIQUE_WARNING = ('There are {count} nodes in the graph with the exact name "{name}". '
                     'You are seeing information about only one of them.')


def cmd_node_list(ns: argparse.Namespace) -> int:
    from .peers import discover_nodes, full_name, shared_names
    infos = discover_nodes(ns.wait)
    for name in sorted({full_name(info) for info in infos}):
        print(name)
    shared = shared_names(infos)
    if shared:   # as ros2 node list warns: a second graph (or a second sim) on this domain?
        print('WARNING: Be aware that there are nodes in the graph that share an exact name, '
              'which can have unintended side effects (a second graph on this ROS_DOMAIN_ID?): '
              + ', '.join(f'{name} ({count})' for name, count in shared), file=sys.stderr)
    return 0


def hidden(name: str) -> bool:
    """A hidden name (a part starting with '_'), as ros2node's _is_hidden_name."""
    return any(part.startswith('_') for part in name.split('/'))


def names_and_types(endpoints: Iterable[Any], include_hidden: bool) -> list[tuple[str, list[str]]]:
    """(name, sorted types) per topic or service, by name (rmw's graph cache is a std::map)."""
    out: dict[str, set[str]] = {}
    for ep in endpoints:
        if include_hidden or not hidden(ep.topic):
            out.setdefault(ep.topic, set()).add(ep.typename)
    return sorted((name, sorted(types)) for name, types in out.items())


def node_sections(info: Any, endpoints: list[Any], services: list[Any],
                  include_hidden: bool = False) -> list[tuple[str, list[tuple[str, list[str]]]]]:
    """ros2 node info's sections of one node (NodeInfo with its reader/writer GIDs)."""
    readers, writers = set(info.reader_gids), set(info.writer_gids)
    return [
        ('Subscribers', names_and_types((ep for ep in endpoints
                                         if not ep.is_writer and ep.guid in readers),
                                        include_hidden)),
        ('Publishers', names_and_types((ep for ep in endpoints
                                        if ep.is_writer and ep.guid in writers), include_hidden)),
        # a server reads requests, a client writes them
        ('Service Servers', names_and_types((ep for ep in services if ep.is_request
                                             and not ep.is_writer and ep.guid in readers),
                                            include_hidden)),
        ('Service Clients', names_and_types((ep for ep in services if ep.is_request
                                             and ep.is_writer and ep.guid in writers),
                                            include_hidden)),
        ('Action Servers', []),   # the bundled runtime has no actions
        ('Action Clients', []),
    ]


def format_node_info(name: str, sections: list[tuple[str, list[tuple[str, list[str]]]]]) -> str:
    """ros2 node info's text: a section with nothing in it is an empty line, as print(*[])
    gives in ros2node's print_names_and_types."""
    lines = [name]
    for title, items in sections:
        lines.append(f'  {title}:')
        lines.extend([f'    {n}: {", ".join(types)}' for n, types in items] or [''])
    return '\n'.join(lines) + '\n'


def cmd_node_info(ns: argparse.Namespace) -> int:
    from . import dds
    from .peers import discover_nodes, full_name
    disc = dds.Discovery()
    name = ns.node_name if ns.node_name.startswith('/') else '/' + ns.node_name
    infos = discover_nodes(ns.wait)
    matching = [i for i in infos if full_name(i) == name]
    # one node may be seen twice (its own process's view and the wire): count distinct ones
    distinct = {(i.participant_gid, i.reader_gids, i.writer_gids) for i in matching}
    if not matching:
        return die(f"Unable to find node '{name}'", 1)
    if len(distinct) > 1:
        print(NONUNIQUE_WARNING.format(count=len(distinct), name=name), file=sys.stderr)
    sections = node_sections(matching[0], disc.endpoints(), disc.service_endpoints(),
                             ns.include_hidden)
    print(format_node_info(name, sections), end='')
    return 0


def add_parser(sub: Any) -> None:
    node = sub.add_parser('node', help='inspect nodes (like ros2 node)').add_subparsers(
        dest='node_verb', required=True)
    nl = node.add_parser('list', help='the nodes of the graph')
    nl.add_argument('--wait', type=nonnegative_seconds, default=1.0,
                    help='seconds to listen for discovery at least; then until every ROS 2 process '
                         'seen has announced its nodes (at most 5 s more)')
    nl.set_defaults(func=cmd_node_list)
    ni = node.add_parser('info', help="a node's subscribers, publishers and services")
    ni.add_argument('node_name', help='node name to request information (e.g. /foveation)')
    ni.add_argument('--include-hidden', action='store_true',
                    help='display hidden topics and services as well')
    ni.add_argument('--wait', type=nonnegative_seconds, default=1.0,
                    help='seconds to listen for discovery at least (then up to 5 s more while a '
                         'process is still being discovered)')
    ni.set_defaults(func=cmd_node_info)

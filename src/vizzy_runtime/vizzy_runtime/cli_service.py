"""`vizzy service list|type|call`: ros2 service's verbs and output (Jazzy's ros2service).

    vizzy service list [-t] [-c] [--include-hidden-services]
    vizzy service type <service>
    vizzy service call <service> <type> ['<yaml>' | --stdin] [-r HZ] [--timeout S]

Services are found on DDS as ROS 2's middlewares name them (rq<name>Request / rr<name>Reply),
so those of real ROS 2 nodes are listed too. The bundled runtime calls the services whose types
it has: rcl_interfaces' (every node's parameter services), through the same client as
`vizzy param` (rclpy_compat.parameter_client: rmw_cyclonedds_cpp's and rmw_fastrtps_cpp's
formats).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from .cli_node import names_and_types
from .cli_types import die, nonnegative_seconds, positive_number, positive_seconds


def service_names_and_types(wait: float, include_hidden: bool) -> list[tuple[str, list[str]]]:
    """(service, types) of every server and client seen, by name (ros2's
    get_service_names_and_types: a service with only clients is listed too)."""
    from . import dds
    from .cli_topic import _listen_for_endpoints
    disc = dds.Discovery()
    _listen_for_endpoints(wait)
    return names_and_types(disc.service_endpoints(), include_hidden)


def cmd_service_list(ns: argparse.Namespace) -> int:
    services = service_names_and_types(ns.wait, ns.include_hidden_services)
    if ns.count_services:
        print(len(services))
        return 0
    for name, types in services:
        print(f'{name} [{", ".join(types)}]' if ns.show_types else name)
    return 0


def cmd_service_type(ns: argparse.Namespace) -> int:
    name = ns.service_name if ns.service_name.startswith('/') else '/' + ns.service_name
    for service, types in service_names_and_types(ns.wait, include_hidden=True):
        if service == name:
            print('\n'.join(types))
            return 0
    return die(f"Unknown service '{name}'", 1)


def service_type(text: str) -> tuple[str, str]:
    """(pkg, Srv) of a service type the bundled runtime can call, else ValueError."""
    from .rclpy_compat.param_services import SRV_DEFINITIONS
    parts = text.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'srv', parts[1]]
    if len(parts) != 3 or parts[1] != 'srv' or not all(parts):
        raise ValueError(f"The passed service type '{text}' is invalid (expected pkg/srv/Type)")
    if parts[0] != 'rcl_interfaces' or parts[2] not in SRV_DEFINITIONS:
        raise ValueError(f"The passed service type '{text}' is invalid: the bundled runtime "
                         'calls rcl_interfaces services (`vizzy interface list -s`)')
    return parts[0], parts[2]


def cmd_service_call(ns: argparse.Namespace) -> int:
    from . import msgs
    from .msg_yaml import FieldError, parse_values, set_fields
    from .rclpy_compat.context import Context
    from .rclpy_compat.executors import SingleThreadedExecutor
    from .rclpy_compat.node import Node
    from .rclpy_compat.param_services import register_types
    from .rclpy_compat.parameter_client import ServiceClient

    pkg, srv = service_type(ns.service_type)
    name = ns.service_name if ns.service_name.startswith('/') else '/' + ns.service_name
    register_types()
    request = msgs.get_message(f'{pkg}/srv/{srv}_Request')()
    try:
        set_fields(request, parse_values(sys.stdin.read() if ns.stdin else ns.values))
    except FieldError as err:
        return die(f'service call: Failed to populate field: {err}', 1)
    context = Context()
    context.init([])
    node = Node(f'_vizzy_requester_{pkg}_{srv}', context=context,
                start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    client = ServiceClient(node, name, srv)
    try:
        if not client.service_is_ready():
            print('waiting for service to become available...', flush=True)
            if not client.wait_for_service(ns.timeout):
                return die(f'service call: {name}: no such service within {ns.timeout:g} s '
                           '(`vizzy service list` lists those on this ROS_DOMAIN_ID)', 1)
        period = 1.0 / ns.rate if ns.rate else None
        while True:
            print(f'requester: making request: {request!r}\n', flush=True)
            last_call = time.monotonic()
            future = client.call_async(request)
            executor.spin_until_future_complete(future, ns.timeout)
            if not future.done():
                client.forget(future)
                return die(f'service call: {name}: no reply within {ns.timeout:g} s', 1)
            try:
                response = future.result()
            except Exception as err:  # noqa: BLE001 - e.g. the service went away
                return die(f'service call: {name}: {err}', 1)
            print(f'response:\n{response!r}\n', flush=True)
            if period is None:
                return 0
            time.sleep(max(0.0, last_call + period - time.monotonic()))
    finally:
        client.destroy()
        node.destroy_node()
        context.try_shutdown()


def _add_wait(p: argparse.ArgumentParser) -> None:
    p.add_argument('--wait', type=nonnegative_seconds, default=1.0,
                   help='seconds to listen for discovery at least; then until every ROS 2 process '
                        'seen has shown its readers and writers (at most 5 s more)')


def add_parser(sub: Any) -> None:
    service = sub.add_parser('service', help='list and call services (like ros2 service)'
                             ).add_subparsers(dest='service_verb', required=True)
    ls = service.add_parser('list', help='the services of the graph')
    ls.add_argument('-t', '--show-types', action='store_true',
                    help='additionally show the service type')
    ls.add_argument('-c', '--count-services', action='store_true',
                    help='only display the number of services discovered')
    ls.add_argument('--include-hidden-services', action='store_true',
                    help='consider hidden services as well')
    _add_wait(ls)
    ls.set_defaults(func=cmd_service_list)
    tp = service.add_parser('type', help="a service's type")
    tp.add_argument('service_name')
    _add_wait(tp)
    tp.set_defaults(func=cmd_service_type)
    call = service.add_parser('call', help='call a service')
    call.add_argument('service_name', help="e.g. '/foveation/list_parameters'")
    call.add_argument('service_type', help="e.g. 'rcl_interfaces/srv/ListParameters'")
    values = call.add_mutually_exclusive_group()
    values.add_argument('values', nargs='?', default='{}',
                        help="the request's fields in YAML (e.g. '{names: [levels]}'); default: "
                             'defaults')
    values.add_argument('--stdin', action='store_true', help='read the values from stdin')
    call.add_argument('-r', '--rate', metavar='N', type=positive_number,
                      help='repeat the call at a specific rate in Hz')
    call.add_argument('--timeout', type=positive_seconds, default=None,
                      help='seconds to wait for the service and for each reply (default: no '
                           'limit, as ros2)')
    call.set_defaults(func=cmd_service_call)

"""The API surface of the seam (vizzy_runtime.ros) as JSON: every public function, method and
property of the classes and functions our nodes use, with each parameter's name, kind and default.

Run it under the real rclpy (.venv-ros) to write the snapshot the bundled runtime is held to
(src/vizzy_runtime/test/test_api_parity.py, issue 30):

    VIZZY_RUNTIME=ros .venv-ros/bin/python scripts/rclpy_signatures.py            # write it
    VIZZY_RUNTIME=ros .venv-ros/bin/python scripts/rclpy_signatures.py --check    # is it current?

Under the bundled runtime (.venv) `surface('bundled')` gives the same structure for
vizzy_runtime.rclpy_compat, which the parity test compares with the snapshot.
"""

from __future__ import annotations

import argparse
import enum
import importlib
import inspect
import json
import sys
from pathlib import Path
from typing import Any

SNAPSHOT = (Path(__file__).resolve().parent.parent / 'src' / 'vizzy_runtime' / 'test'
            / 'rclpy_7.1.6_signatures.json')
RCLPY_VERSION = '7.1.6'

# seam name -> (real rclpy's object, the bundled runtime's): 'module:attribute'. The classes
# the seam exports and those its objects return (node.create_publisher() -> Publisher, ...).
TARGETS: dict[str, tuple[str, str]] = {
    'Node': ('rclpy.node:Node', 'vizzy_runtime.rclpy_compat.node:Node'),
    'Publisher': ('rclpy.publisher:Publisher', 'vizzy_runtime.rclpy_compat.node:Publisher'),
    'Subscription': ('rclpy.subscription:Subscription',
                     'vizzy_runtime.rclpy_compat.node:Subscription'),
    'Timer': ('rclpy.timer:Timer', 'vizzy_runtime.rclpy_compat.node:Timer'),
    'Clock': ('rclpy.clock:Clock', 'vizzy_runtime.rclpy_compat.time:Clock'),
    'ROSClock': ('rclpy.clock:ROSClock', 'vizzy_runtime.rclpy_compat.time:ROSClock'),
    'ClockType': ('rclpy.clock_type:ClockType', 'vizzy_runtime.rclpy_compat.time:ClockType'),
    'Time': ('rclpy.time:Time', 'vizzy_runtime.rclpy_compat.time:Time'),
    'Duration': ('rclpy.duration:Duration', 'vizzy_runtime.rclpy_compat.duration:Duration'),
    'Context': ('rclpy.context:Context', 'vizzy_runtime.rclpy_compat.context:Context'),
    'Executor': ('rclpy.executors:Executor', 'vizzy_runtime.rclpy_compat.executors:Executor'),
    'SingleThreadedExecutor': ('rclpy.executors:SingleThreadedExecutor',
                               'vizzy_runtime.rclpy_compat.executors:SingleThreadedExecutor'),
    'MultiThreadedExecutor': ('rclpy.executors:MultiThreadedExecutor',
                              'vizzy_runtime.rclpy_compat.executors:MultiThreadedExecutor'),
    'Future': ('rclpy.task:Future', 'vizzy_runtime.rclpy_compat.executors:Future'),
    'Parameter': ('rclpy.parameter:Parameter', 'vizzy_runtime.rclpy_compat.parameter:Parameter'),
    'Parameter.Type': ('rclpy.parameter:Parameter.Type',
                       'vizzy_runtime.rclpy_compat.parameter:Parameter.Type'),
    'parameter_value_to_python': ('rclpy.parameter:parameter_value_to_python',
                                  'vizzy_runtime.rclpy_compat.parameter:parameter_value_to_python'),
    'AsyncParameterClient': ('rclpy.parameter_client:AsyncParameterClient',
                             'vizzy_runtime.rclpy_compat.parameter_client:AsyncParameterClient'),
    'QoSProfile': ('rclpy.qos:QoSProfile', 'vizzy_runtime.rclpy_compat.qos:QoSProfile'),
    'DurabilityPolicy': ('rclpy.qos:DurabilityPolicy',
                         'vizzy_runtime.rclpy_compat.qos:DurabilityPolicy'),
    'HistoryPolicy': ('rclpy.qos:HistoryPolicy', 'vizzy_runtime.rclpy_compat.qos:HistoryPolicy'),
    'ReliabilityPolicy': ('rclpy.qos:ReliabilityPolicy',
                          'vizzy_runtime.rclpy_compat.qos:ReliabilityPolicy'),
    'RcutilsLogger': ('rclpy.impl.rcutils_logger:RcutilsLogger',
                      'vizzy_runtime.rclpy_compat.logging:RcutilsLogger'),
    'ExternalShutdownException': ('rclpy.executors:ExternalShutdownException',
                                  'vizzy_runtime.rclpy_compat.exceptions:'
                                  'ExternalShutdownException'),
    'ParameterException': ('rclpy.exceptions:ParameterException',
                           'vizzy_runtime.rclpy_compat.exceptions:ParameterException'),
    'InvalidParameterTypeException': ('rclpy.exceptions:InvalidParameterTypeException',
                                      'vizzy_runtime.rclpy_compat.exceptions:'
                                      'InvalidParameterTypeException'),
    'InvalidParameterValueException': ('rclpy.exceptions:InvalidParameterValueException',
                                       'vizzy_runtime.rclpy_compat.exceptions:'
                                       'InvalidParameterValueException'),
}
# rclpy's module-level functions (vizzy_runtime.ros.rclpy.<name>)
RCLPY_FUNCTIONS = ('create_node', 'get_default_context', 'get_global_executor', 'init', 'ok',
                   'shutdown', 'spin', 'spin_once', 'spin_until_future_complete', 'try_shutdown')
for _name in RCLPY_FUNCTIONS:
    TARGETS[f'rclpy.{_name}'] = (f'rclpy:{_name}', f'vizzy_runtime.rclpy_compat:{_name}')


def resolve(spec: str) -> Any:
    module, _, attr = spec.partition(':')
    obj: Any = importlib.import_module(module)
    for part in attr.split('.'):
        obj = getattr(obj, part)
    return obj


def default_text(value: Any) -> str:
    """A default that reads the same on both runtimes: literals as repr, enum members as
    Class.MEMBER, classes as class:Name, any other object as instance:TypeName (no addresses)."""
    if value is None or isinstance(value, (bool, int, float, str, bytes)) and \
            not isinstance(value, enum.Enum):
        return repr(value)
    if isinstance(value, enum.Enum):
        return f'{type(value).__name__}.{value.name}'
    if isinstance(value, type):
        return f'class:{value.__name__}'
    return f'instance:{type(value).__name__}'


def signature_of(func: Any) -> list[list[Any]] | None:
    """[[name, kind, default or None], ...]; a default is a one-item list (None is a default
    too); None where Python can read no signature (some pybind11 builtins)."""
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return None
    out: list[list[Any]] = []
    for p in sig.parameters.values():
        default = None if p.default is inspect.Parameter.empty else [default_text(p.default)]
        out.append([p.name, p.kind.name, default])
    return out


def describe(obj: Any) -> dict[str, Any]:
    if inspect.isclass(obj) and issubclass(obj, enum.Enum):
        return {'kind': 'enum', 'members': {m.name: int(m.value) if isinstance(m.value, int)
                                            else repr(m.value) for m in obj}}
    if not inspect.isclass(obj):
        return {'kind': 'function', 'signature': signature_of(obj)}
    # the constructor as callers see it (__init__ or __new__, without self or cls)
    members: dict[str, Any] = {'(constructor)': {'kind': 'constructor',
                                                 'signature': signature_of(obj)}}
    names = {n for klass in obj.__mro__ if klass.__module__ != 'builtins' for n in vars(klass)}
    for name in sorted(names):
        if name in ('__init__', '__new__'):
            continue
        if name.startswith('_'):
            continue
        static = inspect.getattr_static(obj, name)
        if isinstance(static, property):
            members[name] = {'kind': 'property'}
        elif isinstance(static, classmethod):
            members[name] = {'kind': 'classmethod', 'signature': signature_of(getattr(obj, name))}
        elif isinstance(static, staticmethod):
            members[name] = {'kind': 'staticmethod', 'signature': signature_of(getattr(obj, name))}
        elif inspect.isclass(static):
            continue    # nested classes (Parameter.Type) are targets of their own
        elif callable(static):
            members[name] = {'kind': 'method', 'signature': signature_of(static)}
    out: dict[str, Any] = {'kind': 'class', 'members': members}
    slots = vars(obj).get('__slots__')
    if slots:   # rclpy's QoSProfile(**kwargs) takes exactly these (less the underscore)
        out['slots'] = sorted(str(s).lstrip('_') for s in slots)
    return out


def surface(which: str) -> dict[str, Any]:
    """{seam name: description} for 'real' (rclpy) or 'bundled' (rclpy_compat)."""
    index = 0 if which == 'real' else 1
    return {name: describe(resolve(specs[index])) for name, specs in sorted(TARGETS.items())}


def snapshot() -> dict[str, Any]:
    from importlib.metadata import version
    return {'rclpy_version': version('ros-jazzy-rclpy'), 'surface': surface('real')}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true',
                        help='compare with the committed snapshot instead of writing it')
    parser.add_argument('--out', type=Path, default=SNAPSHOT)
    args = parser.parse_args(argv)
    try:
        import rclpy  # noqa: F401
    except ImportError as err:
        print(f'rclpy_signatures: the real rclpy does not import ({err}); run it with '
              '.venv-ros/bin/python', file=sys.stderr)
        return 2
    text = json.dumps(snapshot(), indent=1, sort_keys=True) + '\n'
    if args.check:
        current = args.out.read_text() if args.out.exists() else ''
        if current != text:
            print(f'rclpy_signatures: {args.out} is not current: rerun this script under '
                  '.venv-ros to rewrite it', file=sys.stderr)
            return 1
        print(f'rclpy_signatures: {args.out} is current')
        return 0
    args.out.write_text(text)
    print(f'rclpy_signatures: wrote {args.out} ({len(TARGETS)} names)')
    return 0


if __name__ == '__main__':
    sys.exit(main())

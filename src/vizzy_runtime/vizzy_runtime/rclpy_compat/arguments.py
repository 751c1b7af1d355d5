"""Parsing of ROS 2 command-line arguments (`--ros-args ... --`): remapping, parameters, params
files.

Mirrors rcl's rules: `-r/--remap [node:]from:=to` (incl. __node and __ns), `-p/--param name:=value`
(value parsed as YAML), `--params-file FILE` (standard `node: ros__parameters:` files, `/**` and
namespaced keys), `--log-level [name:=]LEVEL`. Errors name the argument and what is wrong.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml


class RosArgumentError(ValueError):
    """A --ros-args argument that cannot be used."""


@dataclass
class Remap:
    source: str
    target: str
    node: str | None = None


@dataclass
class RosArguments:
    remaps: list[Remap] = field(default_factory=list)
    # (node pattern, parameter name, value); pattern '/**' or a node name / fully qualified name
    params: list[tuple[str, str, Any]] = field(default_factory=list)
    log_level: str | None = None
    rosout_logs: bool = True   # --disable-rosout-logs: no node of the process publishes /rosout
    unparsed: list[str] = field(default_factory=list)

    def node_name(self, node: str) -> str:
        return self._special('__node', node) or node

    def namespace(self, node: str, namespace: str) -> str:
        return self._special('__ns', node) or namespace

    def _special(self, key: str, node: str) -> str | None:
        found = None
        for r in self.remaps:
            if r.source == key and (r.node is None or r.node == node):
                found = r.target
        return found

    def parameter_overrides(self, node_fqn: str) -> dict[str, Any]:
        """Parameter values for a node, later sources winning (files and -p in command-line
        order)."""
        name = node_fqn.rsplit('/', 1)[-1]
        out: dict[str, Any] = {}
        for pattern, pname, value in self.params:
            if _node_matches(pattern, node_fqn, name):
                out[pname] = value
        return out


def _node_matches(pattern: str, fqn: str, name: str) -> bool:
    """rcl's rule: a node key is a fully qualified name, a relative one (`sim`) is made absolute
    (`/sim`, so it does not reach /head2/sim); `/**` and `*` are wildcards."""
    if pattern in ('/**', '**'):
        return True
    absolute = pattern if pattern.startswith('/') else '/' + pattern
    return fnmatch.fnmatchcase(fqn, absolute.replace('/**', '*'))


def parse_value(text: str) -> Any:
    """A -p value as rcl reads it: YAML scalar or flow sequence."""
    try:
        return yaml.safe_load(text) if text != '' else ''
    except yaml.YAMLError as exc:
        raise RosArgumentError(f'cannot parse parameter value {text!r}: {exc}') from None


def load_params_file(path: str | Path) -> list[tuple[str, str, Any]]:
    """Entries of a ROS 2 parameters YAML file as (node pattern, name, value)."""
    p = Path(path)
    if not p.is_file():
        raise RosArgumentError(f'--params-file {path}: no such file')
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise RosArgumentError(f'--params-file {path}: not valid YAML ({exc})') from None
    if not isinstance(data, dict):
        raise RosArgumentError(f'--params-file {path}: expected a mapping of node names')
    out: list[tuple[str, str, Any]] = []

    def walk(prefix: str, node: dict) -> None:
        for key, value in node.items():
            if key == 'ros__parameters':
                if not isinstance(value, dict):
                    raise RosArgumentError(f'--params-file {path}: ros__parameters of {prefix!r} '
                                           'is not a mapping')
                for pname, pvalue in _flatten(value):
                    out.append((prefix or '/**', pname, pvalue))
            elif isinstance(value, dict):
                joined = (f'{prefix}/{key}' if prefix and not key.startswith('/')
                          else (prefix + key if prefix else key))
                walk(joined, value)
            else:
                raise RosArgumentError(f'--params-file {path}: {key!r} is outside any '
                                       'ros__parameters')

    walk('', data)
    return out


def _flatten(tree: dict, prefix: str = '') -> list[tuple[str, Any]]:
    items: list[tuple[str, Any]] = []
    for key, value in tree.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, dict):
            items.extend(_flatten(value, name))
        else:
            items.append((name, value))
    return items


def _split_assignment(arg: str, flag: str) -> tuple[str | None, str, str]:
    if ':=' not in arg:
        # rcl's forms: -r from:=to, -p name:=value (a parameter needs its value)
        form = 'name:=value' if flag in ('-p', '--param') else 'from:=to'
        raise RosArgumentError(f"{flag} {arg!r}: expected '{form}'"
                               + (f' (e.g. {arg}:=1)' if form == 'name:=value' and arg else ''))
    lhs, rhs = arg.split(':=', 1)
    node = None
    if ':' in lhs:
        node, lhs = lhs.split(':', 1)
    if not lhs:
        raise RosArgumentError(f'{flag} {arg!r}: empty name before :=')
    return node, lhs, rhs


def parse(argv: list[str] | None) -> RosArguments:
    """Parse every --ros-args section of argv; other arguments are kept as unparsed."""
    result = RosArguments()
    args = list(argv or [])
    i = 0
    in_ros = False
    while i < len(args):
        arg = args[i]
        if arg == '--ros-args':
            in_ros = True
        elif in_ros and arg == '--':
            in_ros = False
        elif not in_ros:
            result.unparsed.append(arg)
        elif arg in ('-r', '--remap', '-p', '--param', '--params-file', '--log-level', '-e',
                     '--enclave'):
            if i + 1 >= len(args):
                raise RosArgumentError(f'{arg} needs a value')
            value = args[i + 1]
            i += 1
            if arg in ('-r', '--remap'):
                node, src, dst = _split_assignment(value, arg)
                if not dst:
                    raise RosArgumentError(f'{arg} {value!r}: empty name after :=')
                result.remaps.append(Remap(src, dst, node))
            elif arg in ('-p', '--param'):
                node, name, text = _split_assignment(value, arg)
                result.params.append((node or '/**', name, parse_value(text)))
            elif arg == '--params-file':
                result.params.extend(load_params_file(value))
            elif arg == '--log-level':
                result.log_level = value.split(':=')[-1].lower()
        elif arg in ('--enable-rosout-logs', '--disable-rosout-logs'):
            result.rosout_logs = arg == '--enable-rosout-logs'
        elif arg in ('--enable-stdout-logs', '--disable-stdout-logs', '--enable-external-lib-logs',
                     '--disable-external-lib-logs'):
            pass
        else:
            raise RosArgumentError(f'unknown --ros-args argument {arg!r}')
        i += 1
    return result


def remove_ros_args(argv: list[str]) -> list[str]:
    """rclpy.utilities.remove_ros_args."""
    return parse(argv).unparsed

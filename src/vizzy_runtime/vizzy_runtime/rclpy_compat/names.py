"""ROS 2 name expansion and remapping (rcl's rules for topics)."""

from __future__ import annotations

import re

from .arguments import Remap

_VALID = re.compile(r'^(~/?|/)?[A-Za-z_{][A-Za-z0-9_/{}]*$|^~$')


class InvalidNameError(ValueError):
    """A topic, node or namespace name ROS 2 would reject."""


def normalize_namespace(namespace: str | None) -> str:
    ns = (namespace or '').strip()
    if not ns:
        return '/'
    if not ns.startswith('/'):
        ns = '/' + ns
    return ns.rstrip('/') or '/'


def validate_node_name(name: str) -> None:
    if not re.fullmatch(r'[A-Za-z_][A-Za-z0-9_]*', name or ''):
        raise InvalidNameError(f'invalid node name {name!r}: letters, digits and _ only, not '
                               'starting with a digit')


def expand(name: str, node_name: str, namespace: str) -> str:
    """Fully qualified topic name: 'x' -> '/ns/x', '~/x' -> '/ns/node/x', '/x' stays."""
    if not name or not _VALID.match(name) or '//' in name or name.endswith('/'):
        raise InvalidNameError(f'invalid topic name {name!r}')
    ns = normalize_namespace(namespace)
    base = ns if ns != '/' else ''
    if name.startswith('~'):
        rest = name[1:].lstrip('/')
        full = f'{base}/{node_name}' + (f'/{rest}' if rest else '')
    elif name.startswith('/'):
        full = name
    else:
        full = f'{base}/{name}'
    return full.replace('{node}', node_name).replace('{ns}', base)


def remap(fqn: str, remaps: list[Remap], node_name: str, namespace: str) -> str:
    """Apply the first matching remap rule (rcl: first match wins) to a fully qualified name."""
    for rule in remaps:
        if rule.source.startswith('__') or (rule.node is not None and rule.node != node_name):
            continue
        try:
            if expand(rule.source, node_name, namespace) == fqn:
                return expand(rule.target, node_name, namespace)
        except InvalidNameError:
            continue
    return fqn

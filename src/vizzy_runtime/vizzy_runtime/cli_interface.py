"""`vizzy interface list|show|packages|package`: ros2 interface's verbs and output (Jazzy's
ros2interface), over the message types the bundled runtime knows.

    vizzy interface list [-m] [-s] [-a]
    vizzy interface show <pkg/msg/Type | pkg/srv/Type | -> [--all-comments | --no-comments]
    vizzy interface packages
    vizzy interface package <pkg>

`show` prints the interface's text with every nested type expanded under its field, indented by
one tab per level, as ros2 does: the top level with its comments and blank lines, nested types
without (--all-comments keeps theirs, --no-comments drops them everywhere). The text is the .msg
file's where there is one: the project's own (msgs/msg), the bundled vision_msgs, or a ROS 2
installation's share/<pkg>/msg on AMENT_PREFIX_PATH. The other standard types are written from
the bundled typestore, which keeps their fields and constants but not their comments.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from .cli_types import die

PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
              'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'}
SEPARATOR = '---'   # between a service's request and response


def split_name(name: str) -> tuple[str, str, str]:
    """(package, 'msg' or 'srv', Type) of pkg/msg/Type (pkg/Type: a message)."""
    parts = name.strip().split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts) or parts[1] not in ('msg', 'srv', 'action'):
        raise ValueError(f"Invalid name '{name}'. Expected three parts separated by '/' "
                         '(pkg/msg/Type)')
    return parts[0], parts[1], parts[2]


def _messages() -> list[str]:
    from . import msgs
    return sorted(n for n in msgs.registry().store.fielddefs if n.split('/')[1] == 'msg')


def _services() -> list[str]:
    from .rclpy_compat.param_services import SRV_DEFINITIONS
    return sorted(f'rcl_interfaces/srv/{name}' for name in SRV_DEFINITIONS)


def _installed_file(pkg: str, kind: str, name: str) -> Path | None:
    """share/<pkg>/<kind>/<name>.<kind> of a ROS 2 installation on AMENT_PREFIX_PATH."""
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        path = Path(prefix) / 'share' / pkg / kind / f'{name}.{kind}'
        if path.is_file():
            return path
    return None


def _type_text(desc: Any, pkg: str) -> str:
    """A field's type as a .msg file writes it (same-package types bare)."""
    from rosbags.interfaces import Nodetype
    kind, rest = desc
    if kind == Nodetype.BASE:
        name, bound = rest
        if name == 'bounded_string' or (name == 'string' and bound):
            return f'string<={bound}'
        return str(name)
    if kind == Nodetype.NAME:
        other, _, short = str(rest).split('/')
        return short if other == pkg else f'{other}/{short}'
    sub, length = rest
    inner = _type_text(sub, pkg)
    if kind == Nodetype.ARRAY:
        return f'{inner}[{length}]'
    return f'{inner}[<={length}]' if length else f'{inner}[]'


def _constant_text(value: Any) -> str:
    return ('true' if value else 'false') if isinstance(value, bool) else str(value)


def generated_text(typename: str) -> str:
    """A .msg text of a type from the typestore: constants, then fields (no comments)."""
    from . import msgs
    reg = msgs.registry()
    pkg = typename.split('/')[0]
    lines = [f'{ctype} {cname}={_constant_text(cvalue)}'
             for cname, ctype, cvalue in reg.constants(typename)]
    defaults = msgs._FIELD_DEFAULTS
    for fname, desc in reg.fields(typename):
        if fname == 'structure_needs_at_least_one_member':
            continue
        default = defaults.get((typename, fname))
        lines.append(f'{_type_text(desc, pkg)} {fname}'
                     + ('' if default is None else f' {default:g}'))
    return '\n'.join(lines) + '\n'


def interface_text(name: str) -> str:
    """The text of an interface (message or service) that ros2 interface show would read."""
    from . import msgs
    pkg, kind, short = split_name(name)
    full = f'{pkg}/{kind}/{short}'
    if kind == 'srv':
        from .rclpy_compat.param_services import SRV_DEFINITIONS
        path = _installed_file(pkg, kind, short)
        if path is not None:
            return path.read_text(encoding='utf-8')
        if pkg == 'rcl_interfaces' and short in SRV_DEFINITIONS:
            return SRV_DEFINITIONS[short].replace('---\n', f'{SEPARATOR}\n')
        raise LookupError(f"Could not find the interface '{full}' (`vizzy interface list -s` "
                          'lists the known services)')
    if kind == 'action':
        raise LookupError(f"Could not find the interface '{full}' (the bundled runtime has no "
                          'actions)')
    if pkg == msgs.OUR_PACKAGE:
        try:
            path = msgs.msgs_dir() / f'{short}.msg'
        except FileNotFoundError:
            path = None
        if path is not None and path.is_file():
            return path.read_text(encoding='utf-8')
    if pkg in msgs.BUNDLED_PACKAGES:
        texts = msgs.bundled_msg_texts(pkg)
        if full in texts:
            return texts[full]
    path = _installed_file(pkg, kind, short)
    if path is not None:
        return path.read_text(encoding='utf-8')
    if full in msgs.registry().store.fielddefs:
        return generated_text(full)
    raise LookupError(f"Could not find the interface '{full}' (`vizzy interface list` lists the "
                      'known ones)')


_FIELD = re.compile(r'^\s*([A-Za-z][\w/]*(?:<=\d+)?)(\[[^\]]*\])?\s+([A-Za-z]\w*)(\s|$)')


def _nested_type(line: str, pkg: str) -> str | None:
    """pkg/msg/Type of the message a field line nests (None: a primitive, a constant, a
    comment), as ros2interface's InterfaceTextLine.nested_type."""
    code = line.split('#', 1)[0]
    if not code.strip() or code.strip() == SEPARATOR:
        return None
    match = _FIELD.match(code)
    if match is None or code[match.end(3):].lstrip().startswith('='):
        return None    # a constant (TYPE NAME=value: no match, or TYPE NAME = value)
    base = match.group(1).split('<=')[0]
    if base in PRIMITIVES:
        return None
    if '/' in base:
        other, _, short = base.rpartition('/')
        return f'{other.split("/")[0]}/msg/{short}'
    return 'std_msgs/msg/Header' if base == 'Header' else f'{pkg}/msg/{base}'


def _without_comment(line: str) -> str:
    return line.split('#', 1)[0].strip()


def show_lines(name: str, *, comments: bool = True, nested_comments: bool = False,
               indent: int = 0) -> Iterator[str]:
    """ros2interface show's lines (_show_interface): each line, and under each nested field its
    type's lines, one more tab in."""
    pkg = split_name(name)[0]
    for raw in interface_text(name).splitlines():
        text = raw.rstrip()
        if not comments:
            if not _without_comment(text):
                continue   # blank or comment-only
            text = _without_comment(text)
        yield '\t' * indent + text if text else ''
        nested = _nested_type(text, pkg)
        if nested is not None:
            yield from show_lines(nested, comments=nested_comments,
                                  nested_comments=nested_comments, indent=indent + 1)


def cmd_interface_show(ns: argparse.Namespace) -> int:
    name = ns.type
    if name == '-':     # `vizzy topic info /x | ...`: the type from stdin, as ros2 allows
        name = sys.stdin.readline().strip()
        if not name:
            return die('interface show: the passed value is empty')
    try:
        lines = list(show_lines(name, comments=not ns.no_comments,
                                nested_comments=ns.all_comments))
    except (ValueError, LookupError) as err:
        return die(str(err).strip("'\""), 1)
    print('\n'.join(lines))
    return 0


def cmd_interface_list(ns: argparse.Namespace) -> int:
    sections = [('Messages', _messages(), ns.only_msgs), ('Services', _services(), ns.only_srvs),
                ('Actions', [], ns.only_actions)]
    only = ns.only_msgs or ns.only_srvs or ns.only_actions
    for title, names, chosen in sections:
        if only and not chosen:
            continue
        print(f'{title}:')
        for name in names:
            print(f'    {name}')
    return 0


def cmd_interface_packages(ns: argparse.Namespace) -> int:
    for pkg in sorted({n.split('/')[0] for n in _messages() + _services()}):
        print(pkg)
    return 0


def cmd_interface_package(ns: argparse.Namespace) -> int:
    names = [n for n in _messages() + _services() if n.split('/')[0] == ns.package_name]
    if not names:
        return die(f"Unknown package '{ns.package_name}'", 1)
    for name in sorted(names):
        print(name)
    return 0


def add_parser(sub: Any) -> None:
    interface = sub.add_parser('interface', help='message and service definitions (like ros2 '
                               'interface)').add_subparsers(dest='interface_verb', required=True)
    ls = interface.add_parser('list', help='every interface type known')
    ls.add_argument('-m', '--only-msgs', action='store_true', help='only the message types')
    ls.add_argument('-s', '--only-srvs', action='store_true', help='only the service types')
    ls.add_argument('-a', '--only-actions', action='store_true', help='only the action types')
    ls.set_defaults(func=cmd_interface_list)
    show = interface.add_parser('show', help='an interface definition, nested types expanded')
    comments = show.add_mutually_exclusive_group()
    comments.add_argument('--all-comments', action='store_true',
                          help='show all comments, including those of nested definitions')
    comments.add_argument('--no-comments', action='store_true',
                          help='show no comments or blank lines')
    show.add_argument('type', help="e.g. 'active_vision_msgs/msg/CylinderArray'; '-' reads it "
                                   'from stdin')
    show.set_defaults(func=cmd_interface_show)
    packages = interface.add_parser('packages', help='the packages with interfaces')
    packages.set_defaults(func=cmd_interface_packages)
    package = interface.add_parser('package', help="a package's interfaces")
    package.add_argument('package_name')
    package.set_defaults(func=cmd_interface_package)

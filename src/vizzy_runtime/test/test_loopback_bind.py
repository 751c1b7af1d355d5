"""Receive sockets on 127.0.0.1 by default (loopback.py and its shim): Cyclone alone binds the
wildcard address; with the shim preloaded, or in a library user's process through the patch of
Cyclone's bind slot, every socket of the bundled runtime is on loopback; VIZZY_DDS_LAN=1 turns the
rewrite off. The whole graph's nodes are checked in test_launch.py.

The controls that really bind the wildcard (no shim, the LAN opt-in) run in a private network
namespace holding only lo (`unshare --net`), so no socket of this test is ever reachable from
another host; where namespaces are not allowed they are skipped with the reason."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys

import pytest

from vizzy_runtime import loopback
from vizzy_runtime.testing import scaled

if loopback.shim_path() is None:
    pytest.skip('the loopback-bind shim is not built (reinstall vizzy_runtime)',
                allow_module_level=True)

BIND = '''
import json, socket, sys
family = socket.AF_INET6 if sys.argv[1] == '::' else socket.AF_INET
s = socket.socket(family, socket.SOCK_DGRAM)
s.bind((sys.argv[1], 0))
print(json.dumps(s.getsockname()[0]))
'''

# A bundled-runtime participant, then the addresses its sockets are bound to.
PARTICIPANT = '''
import json, os
from vizzy_runtime import dds
from vizzy_runtime.testing import bound_addresses
dds.participant()
print(json.dumps(sorted({addr for _, addr, _ in bound_addresses(os.getpid())})))
'''


ANY_V4 = loopback.WILDCARD_V4   # bound only inside a private namespace (ISOLATED)
# A private network namespace with only lo, up: what runs there reaches no other host.
ISOLATED = ['unshare', '--net', 'sh', '-c', 'ip link set lo up && exec "$0" "$@"']


def _isolation() -> str | None:
    """Why a private network namespace cannot be made here, or None."""
    if not (shutil.which('unshare') and shutil.which('ip')):
        return 'unshare or ip (util-linux, iproute2) missing'
    proc = subprocess.run([*ISOLATED, 'true'], capture_output=True, text=True, timeout=scaled(30))
    return None if proc.returncode == 0 else f'no network namespace: {proc.stderr.strip()}'


WHY_NOT_ISOLATED = _isolation()
needs_isolation = pytest.mark.skipif(WHY_NOT_ISOLATED is not None, reason=str(WHY_NOT_ISOLATED))


def _run(code: str, *args: str, isolated: bool = False, **env: str) -> str:
    base = {k: v for k, v in os.environ.items() if k not in ('LD_PRELOAD', loopback.EXEC_MARK)}
    prefix = ISOLATED if isolated else []
    proc = subprocess.run([*prefix, sys.executable, '-c', code, *args], env={**base, **env},
                          capture_output=True, text=True, timeout=scaled(120))
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _ipv6() -> bool:
    try:
        with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as s:
            s.bind(('::1', 0))
        return True
    except OSError:
        return False


@pytest.mark.slow
def test_the_shim_binds_loopback_instead_of_the_wildcard() -> None:
    shim = str(loopback.shim_path())
    assert _run(BIND, ANY_V4, LD_PRELOAD=shim) == '127.0.0.1'
    assert _run(BIND, '127.0.0.1', LD_PRELOAD=shim) == '127.0.0.1'  # explicit addresses unchanged
    if _ipv6():
        assert _run(BIND, '::', LD_PRELOAD=shim) == '::1'


@pytest.mark.slow
@needs_isolation
def test_without_the_shim_or_with_the_lan_opt_in_the_wildcard_is_bound() -> None:
    shim = str(loopback.shim_path())
    assert _run(BIND, ANY_V4, isolated=True) == ANY_V4                     # without it
    assert _run(BIND, ANY_V4, isolated=True, LD_PRELOAD=shim, VIZZY_DDS_LAN='1') == ANY_V4


@pytest.mark.slow
@pytest.mark.skipif(not loopback.bundled_runtime(), reason='the shim is for the bundled runtime')
def test_the_shim_keeps_a_cyclone_participant_on_loopback() -> None:
    shim = str(loopback.shim_path())
    assert _run(PARTICIPANT, VIZZY_RUNTIME='bundled', LD_PRELOAD=shim) == ['127.0.0.1']


@pytest.mark.slow
@pytest.mark.skipif(not loopback.bundled_runtime(), reason='the shim is for the bundled runtime')
def test_a_library_user_s_participant_is_on_loopback_without_the_preload() -> None:
    """pytest, a user's script: nothing re-executed them with LD_PRELOAD, so dds.participant()
    points Cyclone's own bind slot at the rewrite (issue 28 item 6: before, the wildcard too)."""
    assert _run(PARTICIPANT, VIZZY_RUNTIME='bundled') == ['127.0.0.1']


@pytest.mark.slow
@needs_isolation
@pytest.mark.skipif(not loopback.bundled_runtime(), reason='the shim is for the bundled runtime')
def test_cyclone_alone_binds_the_wildcard_and_the_patch_touches_only_cyclone() -> None:
    """Why the shim exists (the LAN opt-in leaves Cyclone alone), and the patch's reach: a socket
    the user's own code binds to the wildcard is not rewritten."""
    assert ANY_V4 in _run(PARTICIPANT, isolated=True, VIZZY_RUNTIME='bundled', VIZZY_DDS_LAN='1')
    own = PARTICIPANT.replace(
        'print(', f's = __import__("socket").socket(2, 2); s.bind(({ANY_V4!r}, 0))\nprint(')
    assert _run(own, isolated=True, VIZZY_RUNTIME='bundled') == [ANY_V4, '127.0.0.1']


@pytest.mark.slow
def test_an_entry_point_reexecutes_itself_once_with_the_shim() -> None:
    code = ('import json, os\nfrom vizzy_runtime.loopback import exec_loopback_bound\n'
            'exec_loopback_bound()\nprint(json.dumps(os.environ.get("LD_PRELOAD")))')
    assert _run(code, VIZZY_RUNTIME='bundled') == str(loopback.shim_path())
    assert _run(code, VIZZY_RUNTIME='bundled', VIZZY_DDS_LAN='1') is None
    assert _run(code, VIZZY_RUNTIME='ros') is None   # the real rclpy: its own configuration rules


def test_children_get_the_shim_only_when_wanted() -> None:
    shim = str(loopback.shim_path())
    env = loopback.preload_env({'VIZZY_RUNTIME': 'bundled', 'LD_PRELOAD': '/x/libother.so'})
    assert env['LD_PRELOAD'].split() == [shim, '/x/libother.so']
    assert loopback.preload_env(dict(env))['LD_PRELOAD'] == env['LD_PRELOAD']   # not twice
    assert 'LD_PRELOAD' not in loopback.preload_env({'VIZZY_RUNTIME': 'bundled',
                                                     'VIZZY_DDS_LAN': '1'})
    assert 'LD_PRELOAD' not in loopback.preload_env({'VIZZY_RUNTIME': 'ros'})


def test_servers_listen_on_loopback_unless_the_lan_is_opted_in() -> None:
    assert loopback.default_bind_host({}) == loopback.LOOPBACK_V4 == '127.0.0.1'
    assert loopback.default_bind_host({'VIZZY_DDS_LAN': '1'}) == loopback.WILDCARD_V4

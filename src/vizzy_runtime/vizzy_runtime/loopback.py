"""Keep the bundled runtime's receive sockets on 127.0.0.1 (the networking default).

Cyclone DDS sends only where loopback_config() says (LOOPBACK_V4), but binds its receive sockets
to the wildcard address whatever the configuration, which would leave a node's ports reachable
from the LAN. The cure is a small C library (csrc/loopback_bind.c, built with the package as
`vizzy_runtime/_loopback_bind*.so`) whose bind() turns a bind to the wildcard address into a bind
to loopback. It reaches a process in one of two ways:

- LD_PRELOAD, which acts when a process starts: the launcher starts every node with it
  (preload_env()), and each program's entry point (the `vizzy` command, a node's console script)
  calls exec_loopback_bound() first, which re-executes the same command line once with it;
- any other process that imports the runtime as a library (pytest, a user's script, a notebook):
  before the bundled runtime makes its DDS participant, bind_cyclone_to_loopback() points the
  Cyclone library's own bind slot (its PLT entry) at the same rewrite. Only Cyclone's binds
  change; the process's other sockets are its own business.

Nothing of this applies in LAN mode (VIZZY_DDS_LAN=1; the shim reads it at every bind too) or on the
real rclpy (its Fast DDS profile binds 127.0.0.1 by itself; the user's own ROS configuration rules).
This module imports nothing heavy: entry points call it before anything else.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import sys
import threading
from collections.abc import Mapping, MutableMapping
from pathlib import Path

# The one place the project names these addresses: everything binds and sends on LOOPBACK_V4;
# only the LAN opt-in binds the wildcard (default_bind_host).
LOOPBACK_V4 = '127.0.0.1'
WILDCARD_V4 = '0.0.0.0'

SHIM_MODULE = 'vizzy_runtime._loopback_bind'
# Set in the re-executed process so that a second exec is never attempted (even if the dynamic
# loader refused the preload, which it reports on stderr).
EXEC_MARK = 'VIZZY_LOOPBACK_BIND_EXEC'


def lan_mode(env: Mapping[str, str] = os.environ) -> bool:
    """LAN mode is an explicit opt-in (VIZZY_DDS_LAN=1): then Cyclone's own defaults or the user's
    CYCLONEDDS_URI decide the interfaces, as for any ROS 2 process."""
    return env.get('VIZZY_DDS_LAN', '') in ('1', 'true', 'yes')


def default_bind_host(env: Mapping[str, str] = os.environ) -> str:
    """Where a server of ours (the live view) listens unless told otherwise: loopback, or every
    interface in LAN mode."""
    return WILDCARD_V4 if lan_mode(env) else LOOPBACK_V4


def bundled_runtime(env: Mapping[str, str] = os.environ) -> bool:
    """Whether vizzy_runtime.ros will choose the bundled runtime (the same rule, without importing
    rclpy or Cyclone)."""
    choice = env.get('VIZZY_RUNTIME', '')
    if choice == 'bundled':
        return True
    if choice == 'ros':
        return False
    return importlib.util.find_spec('rclpy') is None


def shim_path() -> Path | None:
    """The built shim, or None (a source checkout that was never built)."""
    spec = importlib.util.find_spec(SHIM_MODULE)
    return Path(spec.origin) if spec is not None and spec.origin else None


def wanted(env: Mapping[str, str] = os.environ) -> bool:
    return bundled_runtime(env) and not lan_mode(env)


def preloaded(env: Mapping[str, str] = os.environ) -> bool:
    shim = shim_path()
    return shim is not None and str(shim) in env.get('LD_PRELOAD', '').replace(':', ' ').split()


def preload_env(env: MutableMapping[str, str]) -> MutableMapping[str, str]:
    """env with the shim added to LD_PRELOAD when this environment wants it (for child
    processes)."""
    shim = shim_path()
    if shim is not None and wanted(env) and not preloaded(env):
        env['LD_PRELOAD'] = ' '.join(p for p in (str(shim), env.get('LD_PRELOAD', '')) if p)
    return env


# The Cyclone library as ctypes loads it (cyclonedds.internal.load_cyclonedds): libddsc*.so.
CYCLONE_LIBRARY = 'libddsc'
_patch_lock = threading.Lock()
_patched = False


def bind_cyclone_to_loopback() -> bool:
    """Make the loaded Cyclone library bind loopback where it asks for the wildcard address, in
    this process, from now on (see the module docstring). Call it after Cyclone is loaded and
    before any participant exists (dds.participant does). True when Cyclone's sockets will be on
    loopback (also: LAN mode or the real rclpy, where nothing is to be done); False, after a
    one-line warning, when the slot could not be rewritten."""
    global _patched
    with _patch_lock:
        if _patched or not wanted() or preloaded():
            return True
        shim = shim_path()
        if shim is None:
            print(f'vizzy: warning: receive sockets bind {WILDCARD_V4} (reachable from the LAN): '
                  'the loopback-bind shim was not built; install a C compiler and reinstall '
                  'vizzy_runtime', file=sys.stderr, flush=True)
            return False
        # RTLD_LOCAL (ctypes' default): its exported bind() stays out of the process's scope.
        patch = ctypes.CDLL(str(shim)).vizzy_loopback_patch
        patch.argtypes = [ctypes.c_char_p]
        patch.restype = ctypes.c_int
        result = patch(CYCLONE_LIBRARY.encode())
        _patched = result > 0
        if not _patched:
            why = {-1: f'{CYCLONE_LIBRARY} is not loaded', -2: 'its bind slot is not writable',
                   -3: 'this architecture is not supported',
                   0: f'{CYCLONE_LIBRARY} has no bind slot'}.get(result, f'error {result}')
            print(f'vizzy: warning: receive sockets bind {WILDCARD_V4} (reachable from the LAN): '
                  f'could not confine Cyclone to loopback ({why}); start the program with '
                  'LD_PRELOAD=$(python -m vizzy_runtime.loopback)', file=sys.stderr, flush=True)
        return _patched


def exec_loopback_bound() -> None:
    """Re-execute this program with the shim preloaded, once, when it is wanted and missing.

    Call only at the very start of a program's entry point (nothing done before it survives)."""
    if os.environ.get(EXEC_MARK) or not wanted() or preloaded():
        return
    if shim_path() is None:
        print(f'vizzy: warning: receive sockets bind {WILDCARD_V4} (reachable from the LAN): the '
              'loopback-bind shim was not built; install a C compiler and reinstall vizzy_runtime',
              file=sys.stderr, flush=True)
        return
    orig = getattr(sys, 'orig_argv', None)
    if not orig or not sys.executable:
        return
    env = dict(os.environ)
    preload_env(env)
    env[EXEC_MARK] = '1'
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, *orig[1:]], env)


if __name__ == '__main__':
    # `LD_PRELOAD=$(python -m vizzy_runtime.loopback) python my_script.py`
    shim = shim_path()
    if shim is None:
        print('vizzy: the loopback-bind shim is not built (reinstall vizzy_runtime)',
              file=sys.stderr)
        sys.exit(2)
    print(shim)

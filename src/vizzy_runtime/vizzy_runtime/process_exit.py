"""Ending a node's process without the interpreter's finalization.

After main() returns, CPython runs the atexit handlers, then tears down modules, whose objects'
__del__ run while threads that are not Python's own (Cyclone DDS's listener threads, torch's
pools) can no longer take the GIL: such a thread inside a call into Python is frozen there for
good. A Cyclone entity deleted in that phase waits for that thread's listener to return, so now
and then a node that had already stopped cleanly hung for ever after SIGINT (in
cyclonedds/core.py's Entity.__del__; the launcher's SIGTERM ended it 30 s later). Everything a node
must do at exit is done by then: destroy_node() closed its files and the runtime's atexit
handlers (run here, while every thread still runs) delete the DDS participant. What is left is
freeing memory the kernel frees anyway, so the process ends with os._exit.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import os
import signal
import sys
import threading
import traceback
from collections.abc import Callable
from typing import NoReturn

#: set by `vizzy launch` in each node's environment: the pid of the launcher
LAUNCHER_PID_ENV = 'VIZZY_LAUNCHER_PID'
_PR_SET_PDEATHSIG = 1


def end_with_launcher(environ: dict[str, str] | None = None, parent: int | None = None) -> bool:
    """A node (or a zygote) started by `vizzy launch` ends when its launcher does, however that
    ends (SIGKILL, the OOM killer, a crash): Linux then sends it SIGTERM (PR_SET_PDEATHSIG), which
    the node takes as it takes a Ctrl-C. If the launcher is already gone, SIGTERM now. Elsewhere
    (no launcher, not Linux) nothing happens. parent: the process to end with instead of the
    launcher (a node forked by its zygote: the zygote, which ends with the launcher; fork() clears
    the setting, so the child arms it again). True if armed."""
    raw = (os.environ if environ is None else environ).get(LAUNCHER_PID_ENV, '')
    if parent is None and raw.isdigit():
        parent = int(raw)
    if parent is None or not sys.platform.startswith('linux'):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent:       # it died before prctl: no signal will come
        os.kill(os.getpid(), signal.SIGTERM)
    return True


def exit_code(exc: SystemExit) -> int:
    """The status Python itself gives a SystemExit: None 0, an int itself, anything else is
    printed to stderr and gives 1."""
    code = exc.code
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


def run_then_exit(main: Callable[[], object]) -> NoReturn:
    """Run main() as a process's whole program, then end the process the way `python` would
    (same status, same traceback for an uncaught exception, non-daemon threads joined, atexit
    handlers run, output flushed) but without module teardown."""
    try:
        result = main()
        code = result if isinstance(result, int) else 0
    except SystemExit as exc:
        code = exit_code(exc)
    except KeyboardInterrupt:
        code = 130
    except BaseException:
        traceback.print_exc()
        code = 1
    try:
        # what Python does first at exit: wait for the threads that are not daemons
        for thread in threading.enumerate():
            if thread is not threading.current_thread() and not thread.daemon:
                thread.join()
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError, AttributeError):  # closed, broken pipe
                stream.flush()
        os._exit(code)


__all__ = ['end_with_launcher', 'exit_code', 'run_then_exit']

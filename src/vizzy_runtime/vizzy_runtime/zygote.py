"""Respawn from a zygote: a respawning node's imports done once, its processes forked from them.

`vizzy launch` starts a node that respawns (graph.yaml respawn_standby) as `vizzy run --zygote
pkg exe args...`: that process, the zygote, imports the node's modules (torch, Open3D, MuJoCo:
seconds of CPU) and does the runtime's warm-up (cli._prepare_zygote; nothing there starts a
thread or joins DDS: fork() copies only the forking thread), then forks the node. The zygote
stays idle, sharing its pages copy-on-write with the node (gc.freeze() keeps the collector from
writing to them). When the node exits the zygote prints its exit status on stdout and waits on
stdin: `go` forks the node again (a respawn is a fork, not a cold start), the end of stdin ends
the zygote.

The forked node is a process of its own for the launcher: its own session (so the launcher's
killpg(node pid) reaches it alone), Python's default signal handlers, stdin on /dev/null, and it
ends when its zygote does (PR_SET_PDEATHSIG; the zygote itself ends with the launcher). On the
launcher's side ZygoteProcess reads the zygote's lines and ForkedNode is the node's Popen-like
handle (pid, poll(), returncode, wait(), send_signal()).
"""

from __future__ import annotations

import contextlib
import gc
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, TextIO

from .process_exit import end_with_launcher, run_then_exit

# The zygote's report lines (stdout, one write each; found anywhere in a line, so that a node's
# unfinished line before one does not hide it).
FORKED = 'vizzy-zygote: node forked, pid'
EXITED = 'vizzy-zygote: node exited, code'
_REPORT = re.compile(r'vizzy-zygote: node (forked|exited), (?:pid|code) (-?\d+)')


def _report(line: str) -> None:
    """One line on stdout in one write (a node writes to the same pipe); a launcher that is gone
    (broken pipe) is no reason to stop."""
    with contextlib.suppress(OSError):
        os.write(sys.stdout.fileno(), f'{line}\n'.encode())


def thread_count() -> int:
    """Threads of this process, native ones included (/proc/self/task); 1 where unknown."""
    try:
        return len(os.listdir('/proc/self/task'))
    except OSError:
        return 1


def serve(main: Callable[[], object], argv: list[str], stdin: TextIO | None = None) -> int:
    """The zygote (`vizzy run --zygote`), its imports done: fork the node (main() with sys.argv =
    argv), report its pid and, once it has exited, its exit status (negative: the signal that
    ended it); then fork again at each `go` line on stdin, until stdin ends (returns 0). SIGINT,
    SIGTERM and SIGHUP (what it gets when its launcher dies) end the zygote (status 128 +
    signal): at once if it is idle, else once its node, to which they are passed on, has ended
    and its end is reported."""
    stdin = sys.stdin if stdin is None else stdin
    zygote = os.getpid()
    child: list[int] = []
    ending: list[int] = []

    def on_signal(signum: int, _frame: Any) -> None:
        ending.append(signum)
        if not child:
            raise SystemExit(128 + signum)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(child[0], signum)

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, on_signal)
    threads = thread_count()
    if threads > 1:   # fork() copies only this thread: a lock another one holds stays held
        # (OpenBLAS's pool, started by NumPy's import unless OPENBLAS_NUM_THREADS or
        # OMP_NUM_THREADS is 1 as graph.yaml's env sets them, is safe: it stops across a fork)
        print(f'vizzy: zygote: {threads} threads before the fork, expected 1 (a library\'s '
              'thread pool?)', file=sys.stderr, flush=True)
    gc.collect()
    gc.freeze()   # the collector no longer writes to the shared objects' headers
    while True:
        for stream in (sys.stdout, sys.stderr):   # nothing buffered is written twice
            with contextlib.suppress(OSError, ValueError):
                stream.flush()
        release_r, release_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(release_w)
            os.read(release_r, 1)   # until the zygote has reported this pid (it comes first)
            os.close(release_r)
            _run_node(main, argv, zygote)
        os.close(release_r)
        child[:] = [pid]
        _report(f'{FORKED} {pid}')
        os.write(release_w, b'g')
        os.close(release_w)
        _, status = os.waitpid(pid, 0)   # retried after a signal handler (PEP 475)
        child.clear()
        _report(f'{EXITED} {os.waitstatus_to_exitcode(status)}')
        if ending:
            return 128 + ending[0]
        if stdin.readline().strip() != 'go':
            return 0


def _run_node(main: Callable[[], object], argv: list[str], zygote: int) -> None:
    """In the forked child: become a process of its own, run main(), exit with its status."""
    try:
        os.setsid()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_DFL)
        devnull = os.open(os.devnull, os.O_RDONLY)
        os.dup2(devnull, 0)
        os.close(devnull)
        end_with_launcher(parent=zygote)   # PR_SET_PDEATHSIG is cleared by fork()
        numpy = sys.modules.get('numpy')
        if numpy is not None:   # each start its own global random state, as a cold start has
            numpy.random.seed()
        sys.argv = list(argv)
    except BaseException:   # noqa: BLE001 - nothing may return into the zygote's code
        import traceback
        traceback.print_exc()
        os._exit(1)
    run_then_exit(main)


# --- the launcher's side ---------------------------------------------------------------------

def process_running(pid: int) -> bool:
    """True while pid exists and is not a zombie (a process that is not our child)."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except (OSError, IndexError):
        return False


class ForkedNode:
    """One node process forked by a zygote, as the launcher sees it (a subprocess.Popen's pid,
    poll(), returncode, wait(), send_signal()). Until the zygote has reported the fork, pid is
    the zygote's (still importing: a signal to it ends it)."""

    def __init__(self, zygote: ZygoteProcess) -> None:
        self.zygote = zygote
        self.args = zygote.proc.args
        self.returncode: int | None = None
        self.forked_pid: int | None = None
        self.reported_code: int | None = None

    @property
    def pid(self) -> int:
        return self.zygote.proc.pid if self.forked_pid is None else self.forked_pid

    def poll(self) -> int | None:
        if self.returncode is None and self.reported_code is not None:
            self.returncode = self.reported_code
        elif self.returncode is None and self.zygote.proc.poll() is not None and (
                self.forked_pid is None or not process_running(self.forked_pid)):
            self.zygote.ended.wait(1.0)   # the pump may not have read the zygote's last lines
            # else the zygote ended without reporting this node's end (killed; the node got
            # SIGTERM from its death and has ended too): the zygote's status stands for it
            self.returncode = (self.reported_code if self.reported_code is not None
                               else self.zygote.proc.returncode)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while (code := self.poll()) is None:
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
            time.sleep(0.02)
        return code

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


class ZygoteProcess:
    """The launcher's handle on one zygote: its Popen (stdin and stdout pipes), the node it forked
    last, and on_forked(node) called (from the output pump) as each fork is reported."""

    def __init__(self, proc: subprocess.Popen[str],
                 on_forked: Callable[[ForkedNode], None]) -> None:
        self.proc = proc
        self.on_forked = on_forked
        self.ended = threading.Event()   # set by the launcher's pump at the end of its output
        self.node = ForkedNode(self)

    def on_line(self, line: str) -> None:
        """The pump's callback for each line of the zygote's (and its nodes') output."""
        found = _REPORT.search(line)
        if found is None:
            return
        node, value = self.node, int(found.group(2))
        if found.group(1) == 'forked':
            node.forked_pid = value
            self.on_forked(node)
        else:
            node.reported_code = value

    def respawn(self) -> ForkedNode | None:
        """`go`: the handle of the node it forks next; None if the zygote is gone."""
        if self.proc.poll() is not None or self.proc.stdin is None:
            return None
        node = ForkedNode(self)
        previous, self.node = self.node, node   # before `go`: its report belongs to the new one
        try:
            self.proc.stdin.write('go\n')
            self.proc.stdin.flush()
        except (OSError, ValueError):
            self.node = previous
            return None
        return node

    def dismiss(self) -> None:
        """End of stdin: the zygote ends once its node has (at once if it is idle)."""
        with contextlib.suppress(OSError, ValueError):
            if self.proc.stdin is not None:
                self.proc.stdin.close()


__all__ = ['EXITED', 'FORKED', 'ForkedNode', 'ZygoteProcess', 'serve', 'thread_count']

"""The zygote (vizzy_runtime/zygote.py): forks the node, reports each exit, forks again at `go`,
ends at the end of stdin; the launcher's handles (ZygoteProcess, ForkedNode) see the forked node
as a process of its own. A stand-in node (a few lines of Python) keeps these tests fast and free
of DDS; test_launch_lifecycle.py runs real nodes through zygotes."""

import os
import signal
import subprocess
import sys
import threading

import pytest

from vizzy_runtime.process_exit import LAUNCHER_PID_ENV
from vizzy_runtime.testing import scaled, wait_until
from vizzy_runtime.zygote import ForkedNode, ZygoteProcess, process_running, thread_count

# The stand-in node: what it does comes from the file named by argv[1] at each start ('0', '1',
# '2': exit with it; 'kill': SIGKILL itself; 'run': print its state, then run until a signal).
NODE = r'''
import os, signal, sys, time
from vizzy_runtime.zygote import serve

def main():
    what = open(sys.argv[1]).read().strip()
    if what == 'kill':
        os.kill(os.getpid(), signal.SIGKILL)
    if what == 'run':
        print(f'node pid={os.getpid()} ppid={os.getppid()} sid={os.getsid(0)} '
              f'sigint={signal.getsignal(signal.SIGINT) is signal.default_int_handler} '
              f'sigterm={signal.getsignal(signal.SIGTERM) is signal.SIG_DFL} '
              f'stdin={os.readlink("/proc/self/fd/0")} argv={sys.argv[2:]}', flush=True)
        try:
            time.sleep(600)
        except KeyboardInterrupt:
            print('node: interrupted', flush=True)
            return 0
    return int(what)

sys.exit(serve(main, ['node', *sys.argv[1:]]))
'''


class Rig:
    """A zygote of the stand-in node under a ZygoteProcess, its output collected as the
    launcher's pump does."""

    def __init__(self, tmp_path, env=None) -> None:
        self.what = tmp_path / 'what'
        self.what.write_text('run')
        self.lines: list[str] = []
        self.forked: list[ForkedNode] = []
        proc = subprocess.Popen([sys.executable, '-c', NODE, str(self.what), 'x'],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, bufsize=1,
                                start_new_session=True, env={**os.environ, **(env or {})})
        self.zygote = ZygoteProcess(proc, self.forked.append)
        self.pump = threading.Thread(target=self._pump, daemon=True)
        self.pump.start()

    def _pump(self) -> None:
        for line in self.zygote.proc.stdout:
            self.lines.append(line)
            self.zygote.on_line(line)
        self.zygote.ended.set()

    def text(self) -> str:
        return ''.join(self.lines)

    def close(self) -> None:
        self.zygote.dismiss()
        for node in self.forked:
            if node.forked_pid and process_running(node.forked_pid):
                os.kill(node.forked_pid, signal.SIGKILL)
        if self.zygote.proc.poll() is None:
            self.zygote.proc.kill()
        self.zygote.proc.wait(scaled(30))


@pytest.fixture
def rig(tmp_path):
    r = Rig(tmp_path)
    yield r
    r.close()


def test_the_zygote_forks_the_node_as_a_process_of_its_own(rig):
    node = rig.zygote.node
    assert wait_until(lambda: 'node pid=' in rig.text(), scaled(30)), rig.text()
    assert rig.forked == [node] and node.poll() is None
    zygote = rig.zygote.proc.pid
    assert node.pid != zygote and node.pid == node.forked_pid
    line = next(ln for ln in rig.lines if ln.startswith('node pid='))
    # its own session (the launcher's killpg reaches it alone), Python's default handlers, no
    # stdin of the zygote's, the node's arguments
    assert line.split() == ['node', f'pid={node.pid}', f'ppid={zygote}', f'sid={node.pid}',
                            'sigint=True', 'sigterm=True', 'stdin=/dev/null', "argv=['x']"], line
    # the report of the fork came before anything the node wrote
    assert rig.lines.index(next(ln for ln in rig.lines if 'node forked' in ln)) < \
        rig.lines.index(line)
    os.killpg(node.pid, signal.SIGINT)   # what the launcher's stop() sends first
    assert node.wait(scaled(30)) == 0
    assert 'node: interrupted' in rig.text() and rig.zygote.proc.poll() is None


@pytest.mark.parametrize('what, code', [('0', 0), ('1', 1), ('2', 2), ('kill', -signal.SIGKILL)])
def test_the_zygote_reports_each_exit_and_forks_again_at_go(rig, what, code):
    first = rig.zygote.node
    assert wait_until(lambda: 'node pid=' in rig.text(), scaled(30)), rig.text()
    rig.what.write_text(what)
    os.kill(first.pid, signal.SIGKILL)
    assert first.wait(scaled(30)) == -signal.SIGKILL
    for _ in range(2):   # a fork at each `go`, the same zygote
        node = rig.zygote.respawn()
        assert node is not None and node is rig.zygote.node
        assert node.wait(scaled(30)) == code, rig.text()
        assert node.pid not in (first.pid, rig.zygote.proc.pid) and not process_running(node.pid)
    assert len(rig.forked) == 3 and rig.zygote.proc.poll() is None
    rig.zygote.dismiss()   # the end of stdin ends an idle zygote
    assert rig.zygote.proc.wait(scaled(30)) == 0


def test_the_end_of_stdin_ends_the_zygote_once_its_node_has_ended(rig):
    node = rig.zygote.node
    assert wait_until(lambda: 'node pid=' in rig.text(), scaled(30)), rig.text()
    rig.zygote.dismiss()
    with pytest.raises(subprocess.TimeoutExpired):
        rig.zygote.proc.wait(0.5)   # its node still runs: so does the zygote
    os.killpg(node.pid, signal.SIGINT)
    assert rig.zygote.proc.wait(scaled(30)) == 0 and node.poll() == 0
    assert rig.zygote.respawn() is None   # gone: the launcher then starts a fresh zygote


@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGTERM])
def test_the_node_ends_with_its_zygote(rig, sig):
    """A zygote killed (SIGKILL: the node's death signal ends it) or told to end (SIGTERM, what
    it gets when its launcher dies: passed on to the node): no node is left, and its handle
    ends with a status."""
    node = rig.zygote.node
    assert wait_until(lambda: 'node pid=' in rig.text(), scaled(30)), rig.text()
    os.kill(rig.zygote.proc.pid, sig)
    assert wait_until(lambda: not process_running(node.pid), scaled(30)), rig.text()
    # the stand-in node takes SIGTERM's default action (a real node stops as on Ctrl-C)
    assert node.wait(scaled(30)) == -sig, rig.text()
    assert rig.zygote.proc.wait(scaled(30)) == (128 + sig if sig == signal.SIGTERM else -sig)


def test_a_node_under_a_launcher_arms_its_death_signal_on_the_zygote(tmp_path):
    """PR_SET_PDEATHSIG is cleared by fork(): the node arms it again, on its zygote (not on the
    launcher, which is not its parent: it would SIGTERM itself at once)."""
    r = Rig(tmp_path, env={LAUNCHER_PID_ENV: str(os.getpid())})
    try:
        node = r.zygote.node
        assert wait_until(lambda: 'node pid=' in r.text(), scaled(30)), r.text()
        with open(f'/proc/{node.pid}/status') as f:
            assert node.poll() is None and 'State:\tS' in f.read()
        r.zygote.proc.kill()
        assert wait_until(lambda: not process_running(node.pid), scaled(30)), r.text()
    finally:
        r.close()


def test_nothing_runs_a_thread_before_the_fork():
    """fork() copies only the forking thread: the runtime's import and warm-up (what every
    zygote does before it forks) start none, with the shipped graph's env (one thread for the
    math libraries: else OpenBLAS starts its pool at NumPy's import; it is fork-safe)."""
    from vizzy_runtime.launcher import default_graph_file, load_graph
    code = ('import vizzy_runtime.ros as r; from vizzy_runtime.zygote import thread_count; '
            'import vizzy_gaze.gaze_controller_node; r.warm_up(); print(thread_count())')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=scaled(120), env={**load_graph(default_graph_file()).env,
                                                   **os.environ, 'VIZZY_RUNTIME': 'bundled'})
    assert out.stdout.strip() == '1', out.stderr[-2000:]
    assert thread_count() >= 1

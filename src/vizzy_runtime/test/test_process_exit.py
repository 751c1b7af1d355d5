"""process_exit.run_then_exit, how every node's process and the `vizzy` program end: what Python's
own exit does (status, traceback, non-daemon threads, atexit, buffered output), minus the
interpreter's finalization, where a DDS entity's __del__ could wait for ever on a listener thread
that can no longer run."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from vizzy_runtime.process_exit import exit_code
from vizzy_runtime.testing import scaled

SRC = str(Path(__file__).resolve().parents[1])


def _run(body: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    script = tmp_path / 'prog.py'
    script.write_text(textwrap.dedent(f'''
        import atexit, sys, threading, time
        sys.path.insert(0, {SRC!r})
        from vizzy_runtime.process_exit import run_then_exit
        OUT = {str(tmp_path)!r}
        atexit.register(lambda: open(OUT + '/atexit', 'w').close())
        def late_file():   # a non-daemon thread still working when main returns
            time.sleep(0.3)
            open(OUT + '/thread', 'w').close()
        threading.Thread(target=late_file).start()
        print('buffered output')   # a pipe: block-buffered, flushed only at exit
    ''') + textwrap.dedent(body))
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=scaled(60))


@pytest.mark.parametrize(('body', 'status'), [
    ('run_then_exit(lambda: None)', 0),
    ('run_then_exit(lambda: 4)', 4),
    ('def main():\n    raise SystemExit(3)\nrun_then_exit(main)', 3),
])
@pytest.mark.slow
def test_the_status_threads_atexit_and_output_are_those_of_a_normal_exit(tmp_path, body, status):
    proc = _run(body, tmp_path)
    assert proc.returncode == status, proc.stderr
    assert proc.stdout == 'buffered output\n'
    assert (tmp_path / 'thread').exists()    # joined, as Python joins non-daemon threads
    assert (tmp_path / 'atexit').exists()


@pytest.mark.slow
def test_an_uncaught_exception_prints_its_traceback_and_exits_1(tmp_path):
    proc = _run('def main():\n    raise ValueError("bad thing")\nrun_then_exit(main)', tmp_path)
    assert proc.returncode == 1
    assert 'Traceback' in proc.stderr and 'ValueError: bad thing' in proc.stderr
    assert (tmp_path / 'atexit').exists()


def test_a_message_as_exit_code_is_printed_and_gives_1(capsys):
    assert exit_code(SystemExit('no renderer')) == 1
    assert capsys.readouterr().err == 'no renderer\n'
    assert exit_code(SystemExit(None)) == 0
    assert exit_code(SystemExit(2)) == 2

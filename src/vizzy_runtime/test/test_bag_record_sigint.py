"""SIGINT at any moment of `vizzy bag record` ends it with the bag finished (issue 28 item 8).

Each case runs `vizzy bag record -a` (cli.main) in a child process that sends itself SIGINT at
one chosen point, so where the signal lands does not depend on timing: during the imports right
after the start, during DDS's import, during discovery, while the main thread holds the lock of
the wait it is in, and (a second signal) while the bag is being finished.
"""

from __future__ import annotations

import os
import random
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

from vizzy_runtime.testing import scaled

pytestmark = pytest.mark.slow  # starts processes or a whole graph, or takes more than ~5 s

SRC = str(Path(__file__).resolve().parents[1])
DOMAIN = os.environ.get('ROS_DOMAIN_ID') or str(random.randint(100, 200))

CHILD = textwrap.dedent('''
    import contextlib, importlib.abc, os, signal, sys
    point, bag = sys.argv[1], sys.argv[2]

    def interrupt():
        os.kill(os.getpid(), signal.SIGINT)  # handled at the next bytecode, right here

    class InterruptOnImport(importlib.abc.MetaPathFinder):
        def __init__(self, name):
            self.name = name

        def find_spec(self, fullname, path, target=None):
            if fullname == self.name:
                sys.meta_path.remove(self)
                interrupt()
            return None

    args = ['bag', 'record', '-a', '-o', bag]
    if point in ('bag_import', 'dds_import'):
        sys.meta_path.insert(0, InterruptOnImport('vizzy_runtime.' + point[:3]))
    else:
        from vizzy_runtime import dds
        from vizzy_runtime.bag import Recorder
        if point == 'discovery':
            discovery_init = dds.Discovery.__init__
            def slow_start(self):
                interrupt()
                discovery_init(self)
            dds.Discovery.__init__ = slow_start
        elif point == 'wait_lock':
            subscribe = Recorder._subscribe_new
            def with_wait_lock_held(self, *a):
                # threading.Event.wait() holds this lock around its bookkeeping
                with getattr(self._stop, '_cond', contextlib.nullcontext()):
                    interrupt()
                return subscribe(self, *a)
            Recorder._subscribe_new = with_wait_lock_held
        elif point == 'finishing':
            finish = Recorder._finish
            def interrupted_finish(self, *a):
                interrupt()
                interrupt()
                return finish(self, *a)
            Recorder._finish = interrupted_finish
            args += ['-d', '0.5']
    from vizzy_runtime import cli
    code = cli.main(args)
    print('main returned', code, flush=True)
    sys.exit(code)
''')


@pytest.mark.parametrize('point', ['bag_import', 'dds_import', 'discovery', 'wait_lock',
                                   'finishing'])
def test_sigint_at_any_point_finishes_the_bag(tmp_path: Path, point: str) -> None:
    bag = tmp_path / 'bag'
    proc = subprocess.run([sys.executable, '-c', CHILD, point, str(bag)], capture_output=True,
                          text=True, timeout=scaled(60),
                          env={**os.environ, 'PYTHONPATH': SRC, 'ROS_DOMAIN_ID': DOMAIN,
                               'PYTHONFAULTHANDLER': '1'})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert 'main returned 0' in proc.stdout and 'Traceback' not in proc.stderr, proc.stderr
    # finished: metadata.yaml written, the MCAP closed (a bag with no message in it)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['bag_0.mcap']
    assert (bag / 'bag_0.mcap').read_bytes().endswith(b'\x89MCAP0\r\n')
    assert f'recorded {info["message_count"]} messages' in proc.stderr

"""Writing from two threads to a topic read in the same process must not deadlock.

Cyclone runs a reader's listener in the thread that delivers the data and makes a second delivery
to that reader wait until the listener returns. A writer that keeps the GIL while it waits
(cyclonedds-python's ddspy_write does) blocks a listener that needs the GIL again: the whole
process stops. The scenario runs in a child process so that a regression fails instead of hanging.
"""

import subprocess
import sys

import pytest

from vizzy_runtime.testing import scaled

pytestmark = pytest.mark.slow  # each test runs its scenario in a child process

SCENARIO = r'''
import threading, time
from vizzy_runtime import dds, msgs

topic = f'/dds_write_deadlock_{time.monotonic_ns()}'
qos = dds.QoS(reliable=True, depth=10)
got = []
in_listener = threading.Event()

def on_data(reader):
    in_listener.set()
    time.sleep(0.3)  # releases the GIL: the other writer takes it and enters dds_write
    got.extend(data for data, _ in reader.take())  # needs the GIL back

reader = dds.RawReader(topic, 'std_msgs/msg/String', qos, on_data=on_data)
writer = dds.RawWriter(topic, 'std_msgs/msg/String', qos)
payload = bytes(msgs.serialize(msgs.get_message('std_msgs/msg/String')(data='x'),
                               'std_msgs/msg/String'))
first = threading.Thread(target=writer.write, args=(payload,))
second = threading.Thread(target=lambda: (in_listener.wait(5), writer.write(payload)))
first.start(); second.start(); first.join(); second.join()
deadline = time.monotonic() + 10
while len(got) < 2 and time.monotonic() < deadline:
    time.sleep(0.05)
print('received', len(got))
'''


def test_write_while_a_local_listener_runs_does_not_deadlock():
    try:
        out = subprocess.run([sys.executable, '-c', SCENARIO], capture_output=True, text=True,
                             timeout=scaled(60))
    except subprocess.TimeoutExpired:
        raise AssertionError('two writers and a same-process listener deadlocked') from None
    assert out.returncode == 0, out.stderr[-2000:]
    assert 'received 2' in out.stdout, out.stdout + out.stderr[-2000:]


EXIT_SCENARIO = r'''
import threading, time
from vizzy_runtime import dds, msgs

topic = f'/dds_exit_{time.monotonic_ns()}'
qos = dds.QoS(reliable=True, depth=10)
reader = dds.RawReader(topic, 'std_msgs/msg/String', qos, on_data=lambda r: r.take())
writer = dds.RawWriter(topic, 'std_msgs/msg/String', qos)
payload = bytes(msgs.serialize(msgs.get_message('std_msgs/msg/String')(data='x'),
                               'std_msgs/msg/String'))

def keep_writing():   # a daemon thread still publishing while the process exits
    while True:
        try:
            writer.write(payload)
        except Exception:
            pass
        time.sleep(0.001)

threading.Thread(target=keep_writing, daemon=True).start()
time.sleep(0.5)
dds._delete_participant_at_exit()   # what the atexit handler does
for make in (dds.participant, lambda: dds.RawWriter(topic + '_late', 'std_msgs/msg/String', qos)):
    try:
        make()
        print('made one after exit')
    except dds.DdsClosedError as exc:
        print('refused:', exc)
'''


def test_after_the_exit_handler_no_participant_is_made_and_the_process_ends():
    try:   # a normal exit, finalization included, with the listener and the writer thread alive
        out = subprocess.run([sys.executable, '-c', EXIT_SCENARIO], capture_output=True,
                             text=True, timeout=scaled(60))
    except subprocess.TimeoutExpired:
        raise AssertionError('the process hung at exit') from None
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.splitlines() == ['refused: DDS is shut down: the process is exiting'] * 2, \
        out.stdout + out.stderr[-2000:]

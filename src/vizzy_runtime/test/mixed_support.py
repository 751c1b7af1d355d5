"""Shared by the mixed-vendor tests (test_mixed_*.py): processes on the real rclpy (.venv-ros,
rmw_fastrtps_cpp = Fast DDS) beside the bundled runtime (Cyclone DDS) in this pytest process.

Imported by path (pytest runs with --import-mode=importlib): `sys.path.insert(0, HERE)`.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import yaml

from vizzy_runtime import dds, msgs
from vizzy_runtime.launcher import default_graph_file
from vizzy_runtime.testing import STOP_GRACE_S, real_rclpy_env, real_rclpy_python

# SIGINT to SIGTERM for nodes still running when a launcher stops them (testing.STOP_GRACE_S: a
# node busy in a long computation on a loaded 2-core machine needs more than the default 5 s)
GRACE_S = STOP_GRACE_S


def graph_subset(path: Path, names: Iterable[str], use_sim_time: bool | None = None) -> Path:
    """A graph file with only the named nodes of the shipped graph.yaml (same parameters,
    remappings and use_sim_time unless given: without the sim, nothing publishes /clock and
    sim-time timers never fire), written to path."""
    names = set(names)
    graph = yaml.safe_load(Path(default_graph_file()).read_text())
    if use_sim_time is not None:
        graph['use_sim_time'] = use_sim_time
    graph['nodes'] = [n for n in graph['nodes'] if n['name'] in names]
    assert {n['name'] for n in graph['nodes']} == names, f'not in graph.yaml: {names}'
    path.write_text(yaml.safe_dump(graph))
    return path


class RealProcess:
    """A process on the real rclpy (.venv-ros's python, real_rclpy_env()), output to a log file.
    stop(): SIGINT to the process alone (a `vizzy launch` then stops its nodes cleanly), then
    SIGTERM and SIGKILL to its process group."""

    def __init__(self, args: Sequence[str], log: Path, env: dict[str, str] | None = None) -> None:
        self.log_path = log
        self._log = open(log, 'w')  # noqa: SIM115 - the process's output, closed in stop()
        self.proc = subprocess.Popen([str(real_rclpy_python()), *args], env=env or real_rclpy_env(),
                                     stdout=self._log, stderr=subprocess.STDOUT,
                                     start_new_session=True)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def log(self, tail: int = 3000) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors='replace')[-tail:]

    def stop(self, grace_s: float = GRACE_S + 10.0) -> int | None:
        for sig, grace in ((signal.SIGINT, grace_s), (signal.SIGTERM, 3.0), (signal.SIGKILL, 2.0)):
            if self.proc.poll() is not None:
                break
            try:
                if sig == signal.SIGINT:
                    os.kill(self.proc.pid, sig)
                else:
                    os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(grace)
        self._log.close()
        return self.proc.poll()


def real_launch(graph_file: Path, log: Path, duration_s: float = 240.0) -> RealProcess:
    """`vizzy launch graph_file` on the real rclpy; --duration is a safety net should the test
    die without stopping it (it is stopped long before)."""
    return RealProcess(['-m', 'vizzy_runtime.cli', 'launch', str(graph_file),
                        '--duration', str(duration_s), '--grace', str(GRACE_S)], log)


class Flow:
    """Which of some topics have carried a message since this started: a best-effort raw reader
    per topic, created once discovery shows a writer of it (any vendor), as test_launch does."""

    def __init__(self, topics: Iterable[str], decode: Iterable[str] = ()) -> None:
        self.topics = set(topics)
        self.decode = set(decode)  # topics whose every sample is decoded into self.messages
        self.messages: dict[str, list[Any]] = {t: [] for t in self.decode}
        self.disc = dds.Discovery()
        self.readers: dict[str, tuple[dds.RawReader, str]] = {}
        self.counts: dict[str, int] = {t: 0 for t in self.topics}

    def poll(self) -> set[str]:
        """Topics heard so far (polls the readers)."""
        for ep in self.disc.endpoints():
            if ep.is_writer and ep.topic in self.topics and ep.topic not in self.readers:
                self.readers[ep.topic] = (dds.RawReader(ep.topic, ep.typename,
                                                        dds.QoS(reliable=False)),
                                          ep.typename)
        for topic, (reader, typename) in self.readers.items():
            batch = reader.take(16)
            self.counts[topic] += len(batch)
            if batch and topic in self.decode:
                self.messages[topic] += [msgs.deserialize(raw, typename) for raw, _ in batch]
        return self.heard()

    def heard(self) -> set[str]:
        return {t for t, n in self.counts.items() if n}

    def all_heard(self) -> bool:
        return self.poll() == self.topics

    def missing(self) -> set[str]:
        return self.topics - self.heard()

    def close(self) -> None:
        """Delete the readers now (not at garbage collection, still taking images meanwhile)."""
        for reader, _ in self.readers.values():
            dds.delete(reader)
        self.readers.clear()


def expect_clean_real_exit(code: int | None, log: str, what: str) -> None:
    """A real-rclpy launcher or node exited 0 (node_tools.run treats rclpy's Ctrl-C race, a
    RuntimeError from a take interrupted by the signal, as the stop it is)."""
    assert code == 0, f'{what} exited {code}\n{log[-3000:]}'


def stop_all(*stoppers: Any) -> None:
    """Call each stop() even if one raises; re-raise the first error."""
    first: BaseException | None = None
    for stop in stoppers:
        try:
            stop()
        except BaseException as err:  # noqa: BLE001
            first = first or err
    if first is not None:
        raise first


def wait_state(predicate: Any, timeout: float, every: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(every)
    return bool(predicate())

"""Helpers for tests of nodes on the bundled runtime: wait on conditions, never sleep-and-hope."""

from __future__ import annotations

import time
from typing import Any, Callable


def wait_until(predicate: Callable[[], bool], timeout: float = 10.0, spin: Any = None) -> bool:
    """Poll predicate (spinning an executor if given) until it holds; False on timeout."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        if spin is not None:
            spin.spin_once(0.01)
        else:
            time.sleep(0.005)
    return predicate()

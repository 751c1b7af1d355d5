"""Fixtures of the sim node's tests: `running`, one sim node and a Listener on the bundled
runtime, shared by the tests of a module (each test module starts its own)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from vizzy_runtime.ros import Context, SingleThreadedExecutor
from vizzy_runtime.testing import no_renderer, wait_until
from vizzy_sim_bridge.core import render as render_mod
from vizzy_sim_bridge.sim_node import SimNode

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_node_support import OVERRIDES, TIMEOUT, Listener  # noqa: E402


@pytest.fixture(scope='module')
def running():
    try:
        render_mod.select_backend()
    except render_mod.RendererUnavailable as exc:
        no_renderer(str(exc))
    ctx = Context()
    ctx.init(['test'])
    sim = SimNode(context=ctx, parameter_overrides=OVERRIDES)
    listener = Listener(ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sim)
    executor.add_node(listener)
    assert wait_until(lambda: set(Listener.TOPICS) <= set(listener.last), TIMEOUT, spin=executor), (
        f'never received {set(Listener.TOPICS) - set(listener.last)}')
    try:
        yield sim, listener, executor
    finally:
        executor.remove_node(listener)
        executor.remove_node(sim)
        listener.destroy_node()
        sim.destroy_node()
        ctx.try_shutdown()

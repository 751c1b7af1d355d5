"""Fixtures shared by the runtime tests: an initialized bundled rclpy context."""

import pytest

from vizzy_runtime.rclpy_compat.context import Context


@pytest.fixture
def context():
    ctx = Context()
    ctx.init(['test'])
    yield ctx
    ctx.try_shutdown()


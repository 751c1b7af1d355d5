"""Test-wide setup: every pytest run gets its own DDS domain so concurrent runs and demos never mix,
and every test can ask for `context`, an initialized bundled-rclpy context of its own."""

import os
import random

import pytest

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ['VIZZY_RUNTIME'] = 'bundled'


@pytest.fixture
def context():
    from vizzy_runtime.rclpy_compat.context import Context
    ctx = Context()
    ctx.init(['test'])
    yield ctx
    ctx.try_shutdown()

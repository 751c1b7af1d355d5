"""Test-wide setup: every pytest run gets its own DDS domain (unless the caller chose one) so
concurrent runs and demos never mix, and every test can ask for `context`, an initialized context
of its own on the runtime under test.

The runtime under test: the bundled one (VIZZY_RUNTIME=bundled, the default here), or the real
rclpy when the caller set VIZZY_RUNTIME=ros (the real-rclpy tier, run by .venv-ros/bin/python:
see scripts/test_ros.sh). Tests marked `live` run on both; the rest need the bundled runtime or
no runtime at all, and the real-rclpy tier deselects them."""

import os
import random

import pytest

if os.environ.get('ROS_DOMAIN_ID') == '':  # empty counts as unset (ROS 2 would read it as 0)
    del os.environ['ROS_DOMAIN_ID']
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ.setdefault('VIZZY_RUNTIME', 'bundled')


@pytest.fixture
def context():
    from vizzy_runtime.ros import Context
    ctx = Context()
    ctx.init(['test'])
    yield ctx
    ctx.try_shutdown()

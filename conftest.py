"""Test-wide setup: every pytest run gets its own DDS domain (unless the caller chose one) so
concurrent runs and demos never mix, and every test can ask for `context`, an initialized context
of its own on the runtime under test.

The runtime under test: the bundled one (VIZZY_RUNTIME=bundled, the default here), or the real
rclpy when the caller set VIZZY_RUNTIME=ros (the real-rclpy tier, run by .venv-ros/bin/python:
see scripts/test_ros.sh). Tests marked `live` run on both; the rest need the bundled runtime or
no runtime at all, and the real-rclpy tier deselects them.

Deadlines: every test deadline is scaled by VIZZY_TEST_TIME_SCALE (vizzy_runtime.testing.scaled);
`slow` marks tests that start processes or whole graphs or take more than a few seconds
(pytest -m "not slow" for a quick loop); VIZZY_REQUIRE_RENDER=1 (CI) fails, rather than skips, a
test that finds no offscreen renderer (vizzy_runtime.testing.no_renderer)."""

import os
import random
import sys

import pytest

# VIZZY_TEST_TIME_SCALE (the factor on every test deadline) is read by module constants at import
# (testing.py's own too): a bad value ends the run here, in one line, before a test module meets it
try:
    from vizzy_runtime.testing import time_scale
    time_scale()
except ValueError as exc:
    print(f'ERROR: {exc}', file=sys.stderr)
    raise SystemExit(4) from None

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

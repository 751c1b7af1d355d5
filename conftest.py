"""Test-wide setup: every pytest run gets its own DDS domain so concurrent runs and demos never mix."""

import os
import random

os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 200)))
os.environ['VIZZY_RUNTIME'] = 'bundled'

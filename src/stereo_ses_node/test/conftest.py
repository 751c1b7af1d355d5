"""Fixtures of the stereo_ses tests: the live rig's `graph` (stereo_live_rig.py)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stereo_live_rig import graph  # noqa: E402, F401 (a fixture: pytest finds it by name)

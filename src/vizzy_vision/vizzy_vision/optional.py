"""Optional dependencies: what a robot that runs only the perception nodes need not install.

Training and data generation render the simulated head; the nodes never import it. A training
program without it ends with one line saying what to install instead of a traceback.
"""

from __future__ import annotations

import sys
from collections.abc import Callable

# Top-level modules that only rendering needs (the simulated head and its physics engine).
SIMULATOR_MODULES = ('vizzy_sim_bridge', 'mujoco')


def simulator_missing(exc: ModuleNotFoundError, program: str) -> str | None:
    """The one-line error for a program that needs the simulator and lacks it, or None when the
    missing module is another one (then the error is not ours to explain)."""
    missing = (exc.name or '').split('.')[0]
    if missing not in SIMULATOR_MODULES:
        return None
    return (f'{program}: needs the simulated head to render its data, and {missing!r} is not '
            'installed: install vizzy_sim_bridge and MuJoCo (`make setup` in the workspace, or '
            '`pip install mujoco` and build vizzy_sim_bridge with colcon)')


def main_needing_simulator(main: Callable[[list[str] | None], int], program: str
                           ) -> Callable[..., int]:
    """main, returning 2 with simulator_missing's line on stderr when the simulator is absent."""
    def wrapped(argv: list[str] | None = None) -> int:
        try:
            return main(argv)
        except ModuleNotFoundError as exc:
            line = simulator_missing(exc, program)
            if line is None:
                raise
            print(line, file=sys.stderr)
            return 2
    return wrapped


__all__ = ['SIMULATOR_MODULES', 'main_needing_simulator', 'simulator_missing']

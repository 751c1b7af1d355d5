"""What the sim node checks of a joint command before using it, and when a periodic output is
due next in lockstep: ROS-free, used by sim_node.py."""

from __future__ import annotations

import math

from vizzy_vision.kinematics import JOINT_LIMITS, JOINT_NAMES


def command_problem(names: list[str], positions: list[float]) -> tuple[str, str] | None:
    """(reason, detail) for a joint command to reject whole, or None if it is usable."""
    if not names:
        return 'no joint names', f'{len(positions)} positions'
    if len(names) != len(positions):
        return 'length mismatch', f'{len(names)} names but {len(positions)} positions'
    unknown = [n for n in names if n not in JOINT_LIMITS]
    if unknown:
        return 'unknown joint', f'{unknown}; known: {", ".join(JOINT_NAMES)}'
    if len(set(names)) != len(names):
        return 'repeated joint', f'in {names}'
    bad = [f'{n}={v}' for n, v in zip(names, positions, strict=True) if not math.isfinite(v)]
    if bad:
        return 'non-finite target', ', '.join(bad)
    return None


def next_due(due: float, t: float, rate_hz: float) -> float:
    """The next sim time a periodic output is due after it went out at t (due was its slot):
    the phase is kept unless it fell a whole period behind."""
    period = 1.0 / rate_hz
    nxt = due + period
    return nxt if nxt > t else t + period

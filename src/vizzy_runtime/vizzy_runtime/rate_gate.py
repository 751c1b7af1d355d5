"""At most so many messages a second, counted in the messages' own time.

A node that processes images at a capped rate counts that rate in the images' stamps (sim time in
the graph, a bag's time when replayed), not in wall time: a loaded machine then processes the
same frames, later, instead of fewer frames per second of video, and a replay gives the same
result at any speed.
"""

from __future__ import annotations

import math

#: a stamp this far [s] before the last one taken means time was reset (a bag restarted)
RESET_S = 1.0


class RateGate:
    """take(stamp, rate_hz): whether the message stamped stamp [s] is due, at most rate_hz a
    second (rate_hz <= 0: every message). slack: the share of the period a stamp may come early
    and still be taken, so that a cap at half the input rate takes every other frame although
    their stamps are rounded (0: strictly a period after the last one taken)."""

    def __init__(self, slack: float = 0.0) -> None:
        if not 0.0 <= slack < 1.0:
            raise ValueError(f'slack must be in [0, 1), got {slack}')
        self.slack = slack
        self.last = -math.inf          # stamp [s] of the last message taken

    def take(self, stamp_s: float, rate_hz: float) -> bool:
        if rate_hz > 0.0:
            period = 1.0 / rate_hz
            if self.last - RESET_S < stamp_s < self.last + period * (1.0 - self.slack):
                return False
        self.last = stamp_s
        return True

    def reset(self) -> None:
        self.last = -math.inf


__all__ = ['RESET_S', 'RateGate']

"""RateGate: at most so many messages a second of their own stamps."""

from __future__ import annotations

import pytest

from vizzy_runtime.rate_gate import RateGate


def taken(gate: RateGate, stamps: list[float], rate_hz: float) -> list[float]:
    return [t for t in stamps if gate.take(t, rate_hz)]


def test_half_the_camera_rate_takes_every_other_frame_with_slack() -> None:
    frames = [i / 15.0 for i in range(30)]                # 2 s of a 15 Hz camera
    assert taken(RateGate(slack=0.1), frames, 7.5) == frames[::2]
    # without slack a rounded stamp a hair early waits for the next frame
    early = [round(t, 3) for t in frames]
    assert len(taken(RateGate(), early, 7.5)) < 15


def test_no_cap_takes_everything_and_a_reset_clock_starts_again() -> None:
    gate = RateGate()
    assert taken(gate, [0.0, 0.01, 0.02], 0.0) == [0.0, 0.01, 0.02]
    assert gate.take(10.0, 1.0) and not gate.take(10.5, 1.0)
    assert gate.take(2.0, 1.0)                          # a stamp > 1 s back: time was reset
    assert not gate.take(2.5, 1.0) and gate.take(3.0, 1.0)


def test_bad_slack_is_refused() -> None:
    with pytest.raises(ValueError, match='slack'):
        RateGate(slack=1.0)

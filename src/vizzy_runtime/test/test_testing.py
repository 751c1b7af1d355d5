"""vizzy_runtime.testing's own rules (issue 30 item 5): VIZZY_TEST_TIME_SCALE scales every test
deadline, a value that is not a number > 0 is refused in one line, and a test that finds no
offscreen renderer is skipped, or failed where VIZZY_REQUIRE_RENDER=1 (CI)."""

from __future__ import annotations

import os
import subprocess
import sys
from types import SimpleNamespace

import pytest

from vizzy_runtime import testing
from vizzy_runtime.testing import (
    REQUIRE_RENDER_ENV,
    TIME_SCALE_ENV,
    no_renderer,
    publish_until,
    repo_root,
    scaled,
    time_scale,
    wait_until,
)


@pytest.fixture
def fake_clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """testing's clock, moved on 1 s by every sleep (a wait's length in polls, not wall time)."""
    now = [0.0]

    def sleep(_seconds: float) -> None:
        now[0] += 1.0

    monkeypatch.setattr(testing, 'time', SimpleNamespace(monotonic=lambda: now[0], sleep=sleep))
    return now


def test_the_time_scale_is_one_unless_set(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(TIME_SCALE_ENV, raising=False)
    assert time_scale() == 1.0 and scaled(7.5) == 7.5
    monkeypatch.setenv(TIME_SCALE_ENV, ' ')
    assert scaled(7.5) == 7.5


@pytest.mark.parametrize(('raw', 'factor'), [('2', 2.0), ('0.5', 0.5), (' 3.25 ', 3.25),
                                             ('1e1', 10.0)])
def test_the_time_scale_multiplies_a_deadline(monkeypatch: pytest.MonkeyPatch, raw: str,
                                              factor: float) -> None:
    monkeypatch.setenv(TIME_SCALE_ENV, raw)
    assert time_scale() == factor
    assert scaled(20.0) == pytest.approx(20.0 * factor)


@pytest.mark.parametrize('raw', ['0', '-1', '0.0', '-0', 'nan', 'inf', 'fast', '2s'])
def test_a_time_scale_that_is_not_a_number_above_zero_is_refused_in_one_line(
        monkeypatch: pytest.MonkeyPatch, raw: str) -> None:
    monkeypatch.setenv(TIME_SCALE_ENV, raw)
    with pytest.raises(ValueError) as err:
        scaled(1.0)
    said = str(err.value)
    assert said.startswith(f'{TIME_SCALE_ENV}={raw!r} ') and '> 0' in said and '\n' not in said


def test_wait_until_waits_the_scaled_default(monkeypatch: pytest.MonkeyPatch,
                                             fake_clock: list[float]) -> None:
    monkeypatch.setenv(TIME_SCALE_ENV, '3')
    assert not wait_until(lambda: False)
    assert fake_clock[0] == 30.0                       # 10 s, scaled: not the 10 s as written
    fake_clock[0] = 0.0
    assert not wait_until(lambda: False, 4.0)          # a timeout given is taken as given
    assert fake_clock[0] == 4.0


def test_publish_until_sends_for_the_scaled_default(monkeypatch: pytest.MonkeyPatch,
                                                   fake_clock: list[float]) -> None:
    monkeypatch.setenv(TIME_SCALE_ENV, '2')
    sent: list[int] = []
    assert not publish_until(lambda: sent.append(1), lambda: False, None, period=1.0)
    assert len(sent) == 20                             # scaled(10) / period


def test_a_missing_renderer_skips_the_test_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    for value in (None, '0'):
        if value is None:
            monkeypatch.delenv(REQUIRE_RENDER_ENV, raising=False)
        else:
            monkeypatch.setenv(REQUIRE_RENDER_ENV, value)
        with pytest.raises(pytest.skip.Exception, match='no offscreen rendering: no EGL here'):
            no_renderer('no EGL here')


def test_a_missing_renderer_fails_the_test_where_rendering_is_required(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(REQUIRE_RENDER_ENV, '1')
    with pytest.raises(pytest.fail.Exception, match=f'{REQUIRE_RENDER_ENV}=1: no EGL here'):
        no_renderer('no EGL here')
    monkeypatch.setenv(REQUIRE_RENDER_ENV, 'yes')     # neither 0 nor 1: said, not guessed
    with pytest.raises(pytest.fail.Exception, match=f"{REQUIRE_RENDER_ENV}='yes': use 1"):
        no_renderer('no EGL here')


@pytest.mark.slow
def test_pytest_refuses_a_bad_time_scale_in_one_line() -> None:
    env = dict(os.environ, **{TIME_SCALE_ENV: '0'})
    proc = subprocess.run([sys.executable, '-m', 'pytest', '--collect-only', '-p',
                           'no:cacheprovider', __file__], cwd=repo_root(), env=env,
                          capture_output=True, text=True, timeout=scaled(120))
    said = [line for line in (proc.stdout + proc.stderr).splitlines() if line.strip()]
    assert proc.returncode == 4, proc.stdout + proc.stderr
    assert said == [f"ERROR: {TIME_SCALE_ENV}='0' must be a finite number > 0 (1: as written)"]

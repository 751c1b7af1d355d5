"""docs/results.md is generated from experiments/results/*.json by scripts/results_table.py: a
changed result (or table rule) without the regenerated page fails here. The verdict rules of
issue 31 are checked on small made-up results files, so they hold whatever the experiments
write next."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from types import ModuleType

import numpy as np
import pytest

from vizzy_runtime.testing import repo_root, scaled


@pytest.mark.slow
def test_results_page_is_generated_from_the_results_json() -> None:
    root = repo_root()
    run = subprocess.run([sys.executable, str(root / 'scripts' / 'results_table.py'), '--check'],
                         capture_output=True, text=True, timeout=scaled(120), cwd=root)
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]


@pytest.fixture(scope='module')
def rt() -> ModuleType:
    """scripts/results_table.py as a module (it is a script, not a package)."""
    path = repo_root() / 'scripts' / 'results_table.py'
    spec = importlib.util.spec_from_file_location('results_table', path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules['results_table'] = mod          # dataclasses resolve the module by name
    spec.loader.exec_module(mod)
    return mod


def fake(files: dict[str, dict]):
    """A stand-in for results_table.Source: the results files by name."""
    return lambda name: files.get(name)


def z_of(a: list[float], b: list[float]) -> float:
    se = math.hypot(np.std(a, ddof=1) / math.sqrt(len(a)), np.std(b, ddof=1) / math.sqrt(len(b)))
    return float((np.mean(a) - np.mean(b)) / se)


def shifted(base: list[float], other: list[float], z: float) -> list[float]:
    """`base` moved so that its difference of means from `other` is z standard errors."""
    se = math.hypot(np.std(base, ddof=1) / math.sqrt(len(base)),
                    np.std(other, ddof=1) / math.sqrt(len(other)))
    d = z * se - (np.mean(base) - np.mean(other))
    return [x + d for x in base]


RNG_VALUES = [float(x) for x in np.random.default_rng(7).normal(0.0, 1.0, 20)]


def test_a_difference_of_1_4_standard_errors_is_not_reproduced(rt: ModuleType) -> None:
    """Issue 31: one s.e. passed Fig. 3.11 (b) at z = 1.40; two s.e. are needed now, and the
    row prints z."""
    b = RNG_VALUES
    a = shifted(list(reversed(b)), b, 1.40)
    verdict, z = rt.compare(a, b, +1)
    assert verdict == rt.NOT and z == pytest.approx(1.40)
    assert rt.compare(shifted(a, b, 2.1), b, +1)[0] == rt.REPRODUCED
    assert rt.compare(shifted(a, b, -2.1), b, +1)[0] == rt.CONTRADICTED

    # the regret row on a made-up file: Cartesian's final regret 1.40 s.e. below log-polar's
    lp = [2.3 + 0.1 * x for x in RNG_VALUES]
    ca = shifted([2.3 + 0.1 * x for x in RNG_VALUES[::-1]], lp, -1.40)
    runs = {k: {'runs': [{'regret': [0.0, v]} for v in vals]}
            for k, vals in (('logpolar UCB a=100 unbiased', lp),
                            ('cartesian UCB a=100 unbiased', ca))}
    text, verdict = rt.fig_3_11_regret(fake({'active_search.json': {'configs': runs}}))
    assert verdict == rt.NOT and 'z = 1.40' in text


def arm(values: list[float], cpu: float) -> dict:
    return {'runs': [{'summary': {'G/S': v}, 'seed': i, 'cpu_s': cpu + i}
                     for i, v in enumerate(values)]}


def test_identical_arms_are_pooled_once_and_named(rt: ModuleType) -> None:
    """Issue 31: UCB a=0 and PI ran bit-identical runs (only CPU time differs); pooled twice they
    made the exploring rules look better beyond two s.e., counted once they do not."""
    greedy = [0.5 + 0.2 * x for x in RNG_VALUES]
    explore_a = [0.5 + 0.2 * x for x in RNG_VALUES[::-1]]
    explore_b = [0.5 + 0.2 * x for x in RNG_VALUES[5:] + RNG_VALUES[:5]]
    shift = 0.0
    # raise both exploring arms until the pooled-twice z crosses 2 while the counted-once z
    # stays below it (both computed here, independently of the script)
    while z_of([x + shift for x in explore_a + explore_b], greedy + greedy) <= 2.05:
        shift += 0.002
    once = z_of([x + shift for x in explore_a + explore_b], greedy)
    assert once < 2.0                       # the made-up data separate the two rules
    configs = {}
    for s in ('logpolar', 'cartesian'):
        configs[f'{s} UCB a=0 unbiased'] = arm(greedy, 1.0)
        configs[f'{s} PI unbiased'] = arm(greedy, 9.0)          # same runs, other CPU times
        configs[f'{s} UCB a=100 unbiased'] = arm([x + shift for x in explore_a], 2.0)
        configs[f'{s} UCB a=inf unbiased'] = arm([x + shift for x in explore_a], 3.0)
        configs[f'{s} EI unbiased'] = arm([x + shift for x in explore_b], 4.0)
    text, verdict = rt.fig_3_11_greedy(fake({'active_search.json': {'configs': configs}}))
    assert verdict == rt.NOT
    assert f'z = {once:.2f}' in text
    assert 'a=0 / PI 0.' in text and '(20 runs)' in text and '(40 runs)' in text
    assert 'a=0 = PI: identical runs, counted once' in text
    assert 'logpolar a=0 = PI, a=100 = a=inf' in text


def bias_runs(gs: float, rs: float, gi: float, li: float) -> dict:
    return {'runs': [{'summary': {'G/S': gs + 0.01 * i, 'R/S': rs, 'GI/S': gi, 'LI/S': li}}
                     for i in range(5)]}


def test_bias_ordering_is_judged_on_every_metric(rt: ModuleType) -> None:
    """'target best, top worst according to all metrics': G/S alone was judged; the regret
    (lower is better) ordered the other way at 135 deg."""
    configs = {f'logpolar UCB a=100 {b} fov135': bias_runs(*m) for b, m in (
        ('unbiased', (0.46, 2.44, 8.9, 28.1)), ('top', (0.28, 2.28, 11.5, 23.1)),
        ('down', (0.70, 2.63, 0.6, 38.9)), ('target', (0.89, 2.89, 24.1, 30.5)))}
    text, verdict = rt.fig_3_12_order(fake({'active_search.json': {'configs': configs}}))
    assert verdict == rt.PARTIAL
    assert 'R/S (lower is better) best top 2.28, worst target 2.89' in text
    assert '4 of 8 orderings hold' in text


def test_cartesian_135_most_successful_contradicts(rt: ModuleType) -> None:
    def found(k: int) -> dict:
        return {'runs': [{'first_on_target': 10 if i < k else None} for i in range(20)]}
    configs = {'logpolar UCB a=100 unbiased': found(8), 'logpolar UCB a=100 unbiased fov135':
               found(4), 'cartesian UCB a=100 unbiased': found(10),
               'cartesian UCB a=100 unbiased fov135': found(18)}
    text, verdict = rt.fig_3_11_cart135(fake({'active_search.json': {'configs': configs}}))
    assert verdict == rt.CONTRADICTED and 'cartesian fov135 90%' in text


def mot_file(mota: float, read: float, periodic: bool) -> dict:
    rows = [{'area': 'centres', 'k_max': k, 's_max': s, 'motp': 74.0, 'mota': mota,
             'speedup': 12.0, 'detector_cpu_ms_after_bootstrap': 17.0,
             'detector_cpu_ms_planned_frames': 11.0, 'read_fraction_planned_frames': read,
             'speedup_on': 'detector_cpu_ms_after_bootstrap'}
            for k in (1, 2, 3, 4) for s in (0.1, 1.0)]
    return {'grid': rows, 'baseline': {'motp': 74.5, 'mota': max(mota, 0.1),
                                       'detector_cpu_ms_after_bootstrap': 204.0},
            'protocol': {'new_tracks': 'periodic' if periodic else 'none'}}


def test_motp_of_a_tracker_that_barely_tracks_is_uninformative(rt: ModuleType) -> None:
    src = fake({'m.json': mot_file(0.05, 0.08, periodic=False)})
    text, verdict = rt.motp('m.json')(src)
    assert verdict == rt.NOT and 'uninformative' in text
    src = fake({'m.json': mot_file(0.4, 0.08, periodic=False)})
    assert rt.motp('m.json')(src)[1] == rt.REPRODUCED


def test_a_speedup_s_max_does_not_buy_is_at_most_partial(rt: ModuleType) -> None:
    """12x within the tolerance, but the planned frames read 0.3 of the frame (S_max 0.1 does
    not bind) and periodic full frames add 6 of the 17 ms: partially, with both reasons."""
    text, verdict = rt.speedup('m.json')(fake({'m.json': mot_file(0.4, 0.3, periodic=True)}))
    assert verdict == rt.PARTIAL
    assert 'does not bind' in text and 'add 6.0-6.0 ms' in text
    text, verdict = rt.speedup('m.json')(fake({'m.json': mot_file(0.4, 0.12, periodic=False)}))
    assert verdict == rt.REPRODUCED

"""Thesis section 4.4.1 / Fig. 4.9: cylinder fitting under planar-cap outliers and Gaussian noise.

200 synthetic scenes per level (--quick: 30), r = 0.3 m, height ~ U[0.05, 2.0] m, 900 side points,
N_d = 450. (a) caps (lids) at 10 densities, cap points / side points = 0.25 .. 2.5 (Eq. 4.5 outlier
fraction 20% .. 71%); (b) Gaussian noise std = 0.01 r .. 0.10 r. Axis along z (as in the thesis),
centre random. Methods: Rabbani (uniform accumulator, normals only), ours unbiased / mildly /
strongly biased (Table 4.1). Errors: orientation (deg), position (distance of the true centre to
the fitted axis, m), radius (m). Writes experiments/results/cylinder_robustness.{png,json}.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from cylinder_detector_node.core.accumulator import TABLE_4_1  # noqa: E402
from cylinder_detector_node.core.fitting import FitParams, fit_cylinder, make_directions  # noqa: E402
from cylinder_detector_node.core.geometry import normals_and_curvature  # noqa: E402
from cylinder_detector_node.core.synthetic import axis_angle_deg, axis_distance, make_cylinder  # noqa: E402

RADIUS = 0.3
CAP_RATIOS = [0.25 * k for k in range(1, 11)]
NOISE_LEVELS = [0.01 * k for k in range(1, 11)]
BASE = dict(n_directions=450, radius_min=0.1, radius_max=0.5, min_confidence=0.0)
METHODS = {
    'rabbani': FitParams(method='rabbani', **BASE),
    'ours_unbiased': FitParams(gmm=TABLE_4_1['unbiased'], **BASE),
    'ours_mild': FitParams(gmm=TABLE_4_1['mild'], **BASE),
    'ours_strong': FitParams(gmm=TABLE_4_1['strong'], **BASE),
}


def run_level(n_scenes: int, cap_ratio: float, noise: float,
              seed: int) -> dict[str, dict[str, float]]:
    dirs = {m: make_directions(p) for m, p in METHODS.items()}
    errs: dict[str, list[tuple[float, float, float]]] = {m: [] for m in METHODS}
    for i in range(n_scenes):
        rng = np.random.default_rng([seed, i])
        scene = make_cylinder(rng, RADIUS, rng.uniform(0.05, 2.0), 900, cap_ratio, noise * RADIUS,
                              centre=rng.uniform(-1.0, 1.0, 3))
        feats = normals_and_curvature(scene.points, METHODS['rabbani'].k_neighbours)
        for m, p in METHODS.items():
            c = fit_cylinder(scene.points, p, dirs[m], feats)
            if c is None:
                errs[m].append((90.0, np.nan, np.nan))
                continue
            errs[m].append((axis_angle_deg(np.array(c.axis), scene.axis),
                            axis_distance(scene.centre, np.array(c.centre), np.array(c.axis)),
                            abs(c.radius - RADIUS)))
    out = {}
    for m, e in errs.items():
        a = np.array(e, dtype=float)
        out[m] = {'orientation_deg_mean': float(np.nanmean(a[:, 0])),
                  'orientation_deg_std': float(np.nanstd(a[:, 0])),
                  'orientation_deg_median': float(np.nanmedian(a[:, 0])),
                  'position_m_mean': float(np.nanmean(a[:, 1])),
                  'position_m_std': float(np.nanstd(a[:, 1])),
                  'radius_m_mean': float(np.nanmean(a[:, 2])),
                  'radius_m_std': float(np.nanstd(a[:, 2]))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true', help='30 scenes per level instead of 200')
    ap.add_argument('--scenes', type=int, default=None)
    ap.add_argument('--out', type=Path, default=Path(__file__).resolve().parent / 'results')
    args = ap.parse_args(argv)
    n = args.scenes or (30 if args.quick else 200)
    results: dict[str, object] = {'n_scenes': n, 'radius_m': RADIUS, 'n_surface': 900,
                                  'n_directions': 450, 'cap_ratios': CAP_RATIOS,
                                  'outlier_fraction_eq_4_5': [r / (1 + r) for r in CAP_RATIOS],
                                  'noise_std_over_radius': NOISE_LEVELS, 'outliers': [],
                                  'noise': []}
    for k, r in enumerate(tqdm(CAP_RATIOS, desc='outliers')):
        results['outliers'].append(run_level(n, r, 0.0, 1000 + k))
    for k, s in enumerate(tqdm(NOISE_LEVELS, desc='noise')):
        results['noise'].append(run_level(n, 0.0, s, 2000 + k))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'cylinder_robustness.json').write_text(json.dumps(results, indent=1))
    fig, axes = plt.subplots(3, 2, figsize=(11, 11))
    for col, (key, xs, xlabel) in enumerate([('noise', [100 * s for s in NOISE_LEVELS],
                                              'noise std (% of radius)'),
                                             ('outliers', [100 * r for r in CAP_RATIOS],
                                              'cap points (% of side points)')]):
        for row, (metric, ylabel) in enumerate([('orientation_deg', 'orientation error (deg)'),
                                                ('position_m', 'position error (m)'),
                                                ('radius_m', 'radius error (m)')]):
            ax = axes[row, col]
            for m in METHODS:
                mu = np.array([lv[m][metric + '_mean'] for lv in results[key]])
                sd = np.array([lv[m][metric + '_std'] for lv in results[key]])
                ax.errorbar(xs, mu, yerr=sd, label=m, capsize=2, marker='o', ms=3)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
    axes[0, 0].legend()
    fig.suptitle(f'Fig. 4.9 reproduction: {n} scenes/level, r = {RADIUS} m, N_d = 450 '
                 '(mean +- std)')
    fig.tight_layout()
    fig.savefig(args.out / 'cylinder_robustness.png', dpi=110)
    print(json.dumps({m: [round(lv[m]['orientation_deg_mean'], 1) for lv in results['outliers']]
                      for m in METHODS}))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

#!/usr/bin/env python3
"""Thesis Fig. 3.8: average information of one stereo snapshot against distance and vergence.

Setting (section 3.4.1): a fronto-parallel plane at distance d in front of the binocular system,
the eyes verged by theta_v (symmetric, version 0, tilt 0); for every left receptive field (RF)
whose ray hits the plane and whose point is also seen by the right camera, the correspondence
(left RF centre, exact projection in the right image) goes through the Unscented Transform
(Eqs. 3.9-3.18, L = 4, alpha 0.25, beta 2, kappa 3) with the spreads of the left RF and of the
right RF containing the match (Eq. 3.7). Information I = -log|Sigma| (Eq. 3.45), averaged over
those RFs: TI (Eq. 3.46). Both sensors have N_rf = 200 x 200 on the Vizzy eye camera (640x480,
85.4 deg horizontal FOV, baseline 0.204 m): the Cartesian grid (sigma 1.6 px) and the log-polar
retina of the foveation package (200 rings x 200 wedges, rho_min 1 px).

This is the geometric characterization (the uncertainty that the RF quantization causes, with
exact correspondences), which is what Fig. 3.8 isolates. A check on synthetic renders runs the
whole pipeline (each sensor's matcher: SGBM on the 200x200 Cartesian grid, or the log-polar
sensor's foveated SGBM; UT) on the textured plane for a few (d, theta_v), searching the
disparities of points 0.2-20 m away (`multires.disparity_window`, as the node does by default),
and reports TI of the matched RFs and the fraction matched.

Writes experiments/results/sensor_characterization.png and .json.

    .venv/bin/python experiments/sensor_characterization.py [--out DIR] [--quick]
"""

from __future__ import annotations

import os

os.environ.setdefault('OMP_NUM_THREADS', '1')

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for _pkg in ('stereo_ses_node', 'foveation_node'):
    sys.path.insert(0, str(ROOT / 'src' / _pkg))

from protocol import cpu_seconds, protocol  # noqa: E402

from stereo_ses_node.core.geometry import pixel_rays, project, vergence_poses  # noqa: E402
from stereo_ses_node.core.information import information  # noqa: E402
from stereo_ses_node.core.multires import disparity_window  # noqa: E402
from stereo_ses_node.core.sensors import RFSensor, cartesian_sensor, logpolar_sensor  # noqa: E402
from stereo_ses_node.core.stereo import StereoPipeline  # noqa: E402
from stereo_ses_node.core.synthetic import plane_texture, render_plane  # noqa: E402
from stereo_ses_node.core.ut import SigmaPointTable, StereoRig, UTParams  # noqa: E402
from vizzy_vision.logpolar import LogPolarRetina  # noqa: E402


def protocol_of(result: dict, cpu_s: float | None = None) -> dict:
    """The protocol object of a result (issue 16), from the result's own fields."""
    return protocol(
        data=f"a fronto-parallel plane at {len(result['depths_m'])} distances x "
             f"{len(result['vergences_deg'])} vergences, Vizzy eye camera "
             f"{result['setting']['image'][0]}x{result['setting']['image'][1]}; plus a rendered "
             'textured-plane check through the whole stereo pipeline',
        repetitions=1, thesis_repetitions=1,
        models='none (geometry: receptive fields + Unscented Transform)',
        differs_from_thesis=['the robot camera (640x480, 85.4 deg, baseline 0.204 m) and '
                             '200x200 receptive fields; the thesis does not give its grid'],
        cpu_s=cpu_s)

W, H = 640, 480
F = 320.0 / np.tan(np.radians(85.4 / 2))
K = np.array([[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1.0]])
BASELINE = 0.204
N_RF = 200
# Vizzy's eyes pan +-38 deg: vergence up to 76 deg (the thesis sweeps [0, pi/2])
ROBOT_MAX_VERGENCE = np.radians(76.0)


def sensors() -> dict[str, tuple[RFSensor, np.ndarray]]:
    """The two sensors and their usable RFs."""
    cart = cartesian_sensor(W, H, N_RF, N_RF)
    retina = LogPolarRetina(W, H, rings=N_RF, wedges=N_RF)
    lp = logpolar_sensor(retina)
    return {'cartesian': (cart, np.ones(cart.n_rf, bool)),
            'logpolar': (lp, retina.rf_valid.reshape(-1).astype(bool))}


def snapshot_information(sensor: RFSensor, ok: np.ndarray, table: SigmaPointTable,
                         depth: float, vergence: float) -> tuple[float, float]:
    """(TI over the RFs that see the plane in both eyes, fraction of the usable RFs that do)."""
    pl, pr = vergence_poses(BASELINE, vergence)
    rig = StereoRig.create(K, K, pl, pr)
    il = np.nonzero(ok)[0]
    uv_l = sensor.centers[il]
    d = pixel_rays(uv_l, K, pl)
    s = (depth - pl[2, 3]) / d[:, 2]
    hit = s > 0
    pts = pl[:3, 3] + s[:, None] * d
    uv_r = project(pts, K, pr)
    # in front of the right camera and inside its image
    in_r = (np.linalg.inv(pr)[2, :3] @ pts.T + np.linalg.inv(pr)[2, 3]) > 0
    inside = (uv_r[:, 0] >= 0) & (uv_r[:, 0] <= W - 1) & (uv_r[:, 1] >= 0) & (uv_r[:, 1] <= H - 1)
    keep = hit & in_r & inside
    if not np.any(keep):
        return float('nan'), 0.0
    il, uv_l, uv_r = il[keep], uv_l[keep], uv_r[keep]
    ir = sensor.rf_index(uv_r[:, 0], uv_r[:, 1])
    _, cov, valid = table.transform(rig, uv_l, uv_r, il, ir)
    info = information(cov[valid])
    info = info[np.isfinite(info)]
    return (float(info.mean()) if info.size else float('nan')), float(info.size / ok.sum())


def rendered_check(depths: list[float], quick: bool) -> list[dict]:
    """SGBM on synthetic renders: TI of the matched RFs and the fraction matched."""
    tex = plane_texture(1024)
    pipes = {'cartesian': StereoPipeline(W, H, 'cartesian', (N_RF, N_RF)),
             'logpolar': StereoPipeline(W, H, 'logpolar', (N_RF, N_RF))}
    out = []
    for depth in depths:
        for ratio in ((1.0,) if quick else (0.67, 1.0, 1.5)):
            fixation = depth * ratio
            vergence = 2 * np.arctan(BASELINE / 2 / fixation)
            pl, pr = vergence_poses(BASELINE, vergence)
            rig = StereoRig.create(K, K, pl, pr)
            left = render_plane(K, pl, W, H, depth, tex)
            right = render_plane(K, pr, W, H, depth, tex)
            window = disparity_window(K, K, pl, pr, W, H, 0.2, 20.0)
            for name, pipe in pipes.items():
                fr = pipe.process(left, right, rig, window)
                info = information(fr.covs)
                info = info[np.isfinite(info)]
                err = np.abs(fr.means[:, 2] - depth)
                out.append({'sensor': name, 'depth_m': depth, 'fixation_m': round(fixation, 3),
                            'vergence_deg': round(float(np.degrees(vergence)), 2),
                            'TI': float(info.mean()) if info.size else None,
                            'matched_fraction': float(fr.means.shape[0] / pipe.rf_ok.sum()),
                            'median_depth_error_m': float(np.median(err)) if err.size else None})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', type=Path, default=ROOT / 'experiments' / 'results')
    ap.add_argument('--quick', action='store_true', help='a coarse grid (a smoke run)')
    args = ap.parse_args()
    cv2.setNumThreads(1)
    t0 = time.time()
    depths = np.round(np.linspace(0.2, 2.0, 10 if args.quick else 19), 3)
    vergences = np.radians(np.arange(0.0, 90.0, 10.0 if args.quick else 4.0))
    result: dict = {'setting': {
        'image': [W, H], 'focal_px': float(F), 'baseline_m': BASELINE, 'n_rf': [N_RF, N_RF],
        'ut': {'alpha': 0.25, 'beta': 2.0, 'kappa': 3.0},
        'information': '-log|Sigma| (Eq. 3.45), Sigma in m^2; TI: mean over RFs (Eq. 3.46)'},
        'depths_m': depths.tolist(), 'vergences_deg': np.degrees(vergences).round(2).tolist()}
    for name, (sensor, ok) in sensors().items():
        table = SigmaPointTable(sensor, sensor, UTParams())
        ti = np.full((depths.size, vergences.size), np.nan)
        frac = np.zeros_like(ti)
        for i, depth in enumerate(depths):
            for j, verg in enumerate(vergences):
                ti[i, j], frac[i, j] = snapshot_information(sensor, ok, table, float(depth),
                                                            float(verg))
        result[name] = {'TI': np.round(ti, 4).tolist(), 'seen_fraction': np.round(frac, 4).tolist()}
        print(f'{name}: TI in [{np.nanmin(ti):.2f}, {np.nanmax(ti):.2f}] '
              f'({time.time() - t0:.0f} s)')

    result['summary'] = summarize(result, depths, vergences)
    result['rendered_check'] = rendered_check([0.5, 1.0, 1.5], args.quick)
    result['seconds'] = round(time.time() - t0, 1)
    args.out.mkdir(parents=True, exist_ok=True)
    result['protocol'] = protocol_of(result, cpu_seconds())
    suffix = '_quick' if args.quick else ''
    (args.out / f'sensor_characterization{suffix}.json').write_text(
        json.dumps(result, indent=1, allow_nan=True) + '\n')
    plot(result, depths, vergences, args.out / f'sensor_characterization{suffix}.png')
    for row in result['rendered_check']:
        print(row)
    print(json.dumps(result['summary']))


def summarize(result: dict, depths: np.ndarray, vergences: np.ndarray) -> dict:
    """The numbers the docs compare with the thesis's Fig. 3.8 statements."""
    lp, ca = np.array(result['logpolar']['TI']), np.array(result['cartesian']['TI'])
    both = np.isfinite(lp) & np.isfinite(ca)
    fixation = BASELINE / 2 / np.tan(np.maximum(vergences, 1e-9) / 2)     # per vergence
    # for each depth, the vergence of the best TI, and the fixation distance it corresponds to
    best = {}
    for name, ti in (('logpolar', lp), ('cartesian', ca)):
        j = np.nanargmax(np.where(np.isfinite(ti), ti, -np.inf), axis=1)
        best[name] = {'best_vergence_deg': np.degrees(vergences[j]).round(1).tolist(),
                      'best_fixation_m': np.round(fixation[j], 3).tolist()}
    # the vergence whose fixation lies on the plane, per depth: TI there vs the range over vergence
    on_plane = [int(np.argmin(np.abs(fixation - d))) for d in depths]
    spread = {name: float(np.nanmean(np.nanmax(ti, axis=1) - np.nanmin(ti, axis=1)))
              for name, ti in (('logpolar', lp), ('cartesian', ca))}
    lp_on = np.array([lp[i, j] for i, j in enumerate(on_plane)])
    ca_on = np.array([ca[i, j] for i, j in enumerate(on_plane)])
    return {
        'logpolar_minus_cartesian_mean': float(np.mean(lp[both] - ca[both])),
        'logpolar_better_fraction': float(np.mean(lp[both] > ca[both])),
        'TI_fixating_the_plane': {'depth_m': depths.tolist(),
                                  'logpolar': np.round(lp_on, 3).tolist(),
                                  'cartesian': np.round(ca_on, 3).tolist()},
        'logpolar_decreases_with_depth_when_fixating': bool(np.all(np.diff(lp_on) < 0)),
        'mean_TI_range_over_vergence': spread,
        'best': best,
    }


def plot(result: dict, depths: np.ndarray, vergences: np.ndarray, path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    lp, ca = np.array(result['logpolar']['TI']), np.array(result['cartesian']['TI'])
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    vsel = [j for j, v in enumerate(np.degrees(vergences)) if round(v) in (0, 12, 24, 40, 60, 80)]
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(len(vsel), 2)))
    for c, j in zip(colors, vsel, strict=False):   # at least 2 colours: may be more
        lab = f'{np.degrees(vergences[j]):.0f} deg'
        axes[0].plot(depths, lp[:, j], '-', color=c, label=f'log-polar {lab}')
        axes[0].plot(depths, ca[:, j], '--', color=c, label=f'Cartesian {lab}')
    axes[0].set_xlabel('plane distance d [m]')
    axes[0].set_ylabel('average information TI (Eq. 3.46)')
    axes[0].set_title('(a) against distance, one curve per vergence')
    axes[0].legend(fontsize=6, ncol=2)
    dsel = [i for i, d in enumerate(depths) if round(d, 2) in (0.2, 0.5, 1.0, 1.5, 2.0)]
    colors = plt.cm.plasma(np.linspace(0, 0.85, max(len(dsel), 2)))
    for c, i in zip(colors, dsel, strict=False):
        axes[1].plot(np.degrees(vergences), lp[i], '-', color=c,
                     label=f'log-polar {depths[i]:.1f} m')
        axes[1].plot(np.degrees(vergences), ca[i], '--', color=c,
                     label=f'Cartesian {depths[i]:.1f} m')
        # the vergence that fixates the plane
        axes[1].axvline(np.degrees(2 * np.arctan(BASELINE / 2 / depths[i])), color=c, lw=0.6,
                        ls=':')
    axes[1].axvline(np.degrees(ROBOT_MAX_VERGENCE), color='k', lw=0.8, ls='-.')
    axes[1].set_xlabel('vergence [deg] (dotted: fixation on the plane; dash-dot: Vizzy limit)')
    axes[1].set_ylabel('TI')
    axes[1].set_title('(b) against vergence, one curve per distance')
    axes[1].legend(fontsize=6, ncol=2)
    fig.suptitle('Fig. 3.8: 200x200 RFs, 640x480, f = 347 px, b = 0.204 m (solid log-polar, '
                 'dashed Cartesian)')
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


if __name__ == '__main__':
    main()

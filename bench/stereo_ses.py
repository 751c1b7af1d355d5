"""stereo_ses benchmark (thesis chapter 3 core, no simulator): one CPU thread.

Inputs are synthetic: a textured fronto-parallel plane 1 m ahead rendered exactly into the two
640x480 Vizzy eye cameras (85.4 deg, baseline 0.204 m, verged on the plane), see
`stereo_ses_node.core.synthetic`; no simulator recording is used.

- ut_points_per_s: UT of 40000 correspondences (Cartesian 200x200 RFs): sigma-point gather from
  the precomputed per-RF table (`SigmaPointTable.transform`) + mid-point triangulation of the 9
  sigma points + Eqs. 3.17-3.18.
- frame_ms_200x200: from the two 640x480 images to fused cells: the Cartesian 200x200 sensor's
  view (area resize), SGBM (80 disparities, window 7), correspondences, UT covariances, and
  fusion into a 20000-cell SES. The log-polar 200x200 frame is printed alongside.
- ses_update_ms: `SensoryEgoSphere.fuse` of 40000 observations into 20000 cells (rigid
  transform, association, information-form fusion).
- association_lookup_ms, association_ckdtree_ms, association_bruteforce_ms: association of 40000
  unit directions into 20000 cells (unbiased), CPU ms: the default exact lookup (`SphereLookup`,
  cube-map candidate lists with a KD-tree fallback), SciPy's cKDTree on the cells' unit vectors
  (the fair baseline: the well-kept library answer to nearest-cell queries) and the chunked
  inner-product argmax of Eq. 3.23 (the thesis's definition, the correctness reference); the
  assignments are checked identical. association_lookup_vs_ckdtree_speedup and
  association_lookup_vs_bruteforce_speedup are the ratios.
- decision_ms: reward statistics (Eqs. 3.38-3.40) + UCB over 20000 cells.

Rectified pairs with ground truth (issue 13, item 3): `--pairs` 640x480 pairs of real
photographs (`--images`, default /work/shared/data/imagenet-samples; a synthetic texture where
that folder is missing) painted on slanted planes (`core.synthetic.random_layers`: a background
at disparity 18-32 px, three shapes at 38-70 px, the first covering the image centre with its
edge near it), the right view rendered with occlusions (z-order), Gaussian noise sd 2 grey
levels on both views and a 0.97 gain on the right one. Per pair and matcher (same SGBM
settings everywhere), the CPU ms of the disparity map (best of --repeats; and, independent of
the machine's load, the SGBM cost-volume cells, pixels x disparities, of the log-polar matcher
against plain SGBM's) and bad-2.0 (the
fraction of non-occluded pixels whose disparity is missing or off by > 2 px) inside the
log-polar fovea (r < 31.8 px of the centre: where the 200 x 200 retina's RFs are at least one
pixel apart, `sensors.fovea_radius`), in the central 200x200, over the whole image, and on
each annulus where the RF law calls for pyramid level l = 1, 2, 3 (r in [31.8, 63.7),
[63.7, 127.3), >= 127.3 px):

- sgbm_full_gt: plain cv2.StereoSGBM on the full-resolution pair with the true range (+-2 px,
  numDisparities rounded up to 16): the fair baseline (it is told the range);
- full: the same at full resolution, with the range searched (`coarse_window`, from [0, 213));
- logpolar: `FoveatedSGBM` (fovea at full resolution, level 1 on its annulus, level 2 for the
  rest; range coarse-to-fine from [0, 213)), what `stereo_file --sensor logpolar` runs;
- logpolar_rf_law: the same with the RF law's levels all the way (max_level 5: level 3,
  1/8 resolution, beyond r = 127 px);
- cartesian: SGBM on the 200x200 Cartesian view, range searched;
- logpolar_rebuilt: what the log-polar pipeline did before issue 13 (to_cortex, to_retina,
  SGBM on the rebuilt 640x480 pair, with the true range).

Times are CPU seconds of this single-threaded process (robust to other load on a shared
machine), best of several repeats; wall times are printed alongside.

    .venv/bin/python bench/stereo_ses.py [--pairs 12] [--only rectified|core] [--figure F.png]
    # last line: one JSON object
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for _pkg in ('stereo_ses_node', 'foveation_node'):
    sys.path.insert(0, str(ROOT / 'src' / _pkg))

from stereo_ses_node.core.decision import choose_fixation  # noqa: E402
from stereo_ses_node.core.geometry import vergence_poses  # noqa: E402
from stereo_ses_node.core.multires import (  # noqa: E402
    DisparityWindow,
    FoveatedSGBM,
    SGBMParams,
    bad_fraction,
    cartesian_disparity,
    coarse_window,
    full_disparity,
    round_up16,
    to_gray,
)
from stereo_ses_node.core.sensors import fovea_radius  # noqa: E402
from stereo_ses_node.core.ses import SensoryEgoSphere, brute_force_associate  # noqa: E402
from stereo_ses_node.core.stereo import StereoPipeline  # noqa: E402
from stereo_ses_node.core.synthetic import layered_pair, plane_texture, random_layers, render_plane  # noqa: E402
from stereo_ses_node.core.ut import StereoRig  # noqa: E402
from vizzy_vision.logpolar import LogPolarRetina  # noqa: E402

W, H = 640, 480
F = 320.0 / np.tan(np.radians(85.4 / 2))
K = np.array([[F, 0, 319.5], [0, F, 239.5], [0, 0, 1.0]])
BASELINE, DEPTH = 0.204, 1.0


def timed(fn: Callable[[], object], repeats: int = 5) -> tuple[float, float, object]:
    """(best CPU s, best wall s, last result) over repeats."""
    cpu, wall, out = [], [], None
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        out = fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return min(cpu), min(wall), out


def core(results: dict) -> None:
    pl, pr = vergence_poses(BASELINE, 2 * np.arctan(BASELINE / 2 / DEPTH))
    rig = StereoRig.create(K, K, pl, pr)
    tex = plane_texture(1024)
    left = render_plane(K, pl, W, H, DEPTH, tex)
    right = render_plane(K, pr, W, H, DEPTH, tex)

    # UT throughput on 40000 correspondences
    cart = StereoPipeline(W, H, 'cartesian', (200, 200))
    s = cart.sensor
    uv_l = s.centers
    uv_r = uv_l - np.array([2.0, 0.0])
    il = np.arange(s.n_rf)
    ir = s.rf_index(uv_r[:, 0], uv_r[:, 1])

    def ut() -> object:
        return cart.table.transform(rig, uv_l, uv_r, il, ir)

    ut_cpu, ut_wall, (_, _, ok) = timed(ut)
    ut_rate = s.n_rf / ut_cpu

    # full frame: images -> fused cells
    ses = SensoryEgoSphere(20000, 'unbiased', seed=0)

    def frame(pipe: StereoPipeline) -> Callable[[], object]:
        def run() -> object:
            fr = pipe.process(left, right, rig)
            ses.fuse(fr.means, fr.covs)
            return fr
        return run

    fr_cpu, fr_wall, fr = timed(frame(cart))
    lp = StereoPipeline(W, H, 'logpolar', (200, 200))
    lp_cpu, lp_wall, lp_fr = timed(frame(lp), 3)

    # SES update: 40000 observations
    rng = np.random.default_rng(0)
    q = rng.standard_normal((40000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    obs = q * rng.uniform(0.5, 4.0, (40000, 1))
    m = rng.standard_normal((40000, 3, 3)) * 0.05
    covs = m @ m.transpose(0, 2, 1) + 1e-4 * np.eye(3)
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, 0.37]
    ses2 = SensoryEgoSphere(20000, 'unbiased', seed=1)
    up_cpu, up_wall, rep = timed(lambda: ses2.fuse(obs, covs, pose))

    # association: fast lookup vs chunked brute force
    bf_cpu, bf_wall, ref = timed(lambda: brute_force_associate(q, ses2.directions), 2)
    gr_cpu, gr_wall, got = timed(lambda: ses2.associate(q, 'grid'), 7)
    kd_cpu, kd_wall, got_kd = timed(lambda: ses2.tree.query(q)[1], 5)
    identical = bool(np.array_equal(ref, got) and np.array_equal(ref, got_kd))
    speedup = bf_cpu / gr_cpu

    # decision over 20000 cells
    dec_cpu, dec_wall, dec = timed(lambda: choose_fixation(ses2.mean, ses2.cov, 'ucb', 1.0), 7)
    pi_cpu, _, _ = timed(lambda: choose_fixation(ses2.mean, ses2.cov, 'pi'), 5)
    ei_cpu, _, _ = timed(lambda: choose_fixation(ses2.mean, ses2.cov, 'ei'), 5)

    print(f'UT: {s.n_rf} correspondences in {1e3 * ut_cpu:.1f} ms CPU ({1e3 * ut_wall:.1f} '
          f'wall): {ut_rate:.0f} points/s ({ok.mean():.0%} valid)')
    print(f'frame, Cartesian 200x200 on 640x480 (resize + SGBM + UT + SES fusion): '
          f'{1e3 * fr_cpu:.1f} ms CPU ({1e3 * fr_wall:.1f} wall), {fr.means.shape[0]} points, '
          f'rejected {fr.rejected}; target <= 50 ms: {"met" if fr_cpu <= 0.05 else "NOT met"}')
    print(f'frame, log-polar 200x200 (foveated SGBM + to_cortex colours + UT + fusion): '
          f'{1e3 * lp_cpu:.1f} ms CPU ({1e3 * lp_wall:.1f} wall), {lp_fr.means.shape[0]} points')
    print(f'SES fuse 40000 obs into 20000 cells: {1e3 * up_cpu:.1f} ms CPU '
          f'({1e3 * up_wall:.1f} wall); {rep.summary()}')
    print(f'association 40000 -> 20000: brute force {1e3 * bf_cpu:.0f} ms, lookup '
          f'{1e3 * gr_cpu:.1f} ms ({speedup:.0f}x), cKDTree {1e3 * kd_cpu:.1f} ms '
          f'({bf_cpu / kd_cpu:.0f}x); lookup vs cKDTree {kd_cpu / gr_cpu:.1f}x; identical '
          f'assignments: {identical}; target >= 100x brute force: '
          f'{"met" if speedup >= 100 and identical else "NOT met"}')
    print(f'decision over 20000 cells: UCB {1e3 * dec_cpu:.2f} ms, PI {1e3 * pi_cpu:.2f} ms, '
          f'EI {1e3 * ei_cpu:.2f} ms (CPU); UCB chose cell {dec.cell}')
    results.update({'ut_points_per_s': round(ut_rate),
                    'frame_ms_200x200': round(1e3 * fr_cpu, 1),
                    'frame_ms_logpolar_200x200': round(1e3 * lp_cpu, 1),
                    'ses_update_ms': round(1e3 * up_cpu, 1),
                    'association_lookup_ms': round(1e3 * gr_cpu, 2),
                    'association_ckdtree_ms': round(1e3 * kd_cpu, 2),
                    'association_bruteforce_ms': round(1e3 * bf_cpu, 1),
                    'association_lookup_vs_ckdtree_speedup': round(kd_cpu / gr_cpu, 2),
                    'association_lookup_vs_bruteforce_speedup': round(speedup, 1),
                    'decision_ms': round(1e3 * dec_cpu, 2)})


IMAGES = Path('/work/shared/data/imagenet-samples')


def textures(folder: Path, n: int) -> tuple[list[np.ndarray], str]:
    """n RGB 640x480 textures: photographs of at least 500x333 from folder (sorted names), or
    synthetic ones (plane_texture) when the folder is missing."""
    out: list[np.ndarray] = []
    if folder.is_dir():
        for f in sorted(folder.iterdir()):
            bgr = cv2.imread(str(f), cv2.IMREAD_COLOR) if f.suffix.lower() in (
                '.jpeg', '.jpg', '.png') else None
            if bgr is None or bgr.shape[1] < 500 or bgr.shape[0] < 333:
                continue
            out.append(cv2.cvtColor(cv2.resize(bgr, (W, H), interpolation=cv2.INTER_CUBIC),
                                    cv2.COLOR_BGR2RGB))
            if len(out) == n:
                return out, str(folder)
    while len(out) < n:
        t = plane_texture(W, seed=len(out))[:H]
        out.append(np.repeat(t[..., None], 3, axis=2))
    return out, 'synthetic (plane_texture)' if not folder.is_dir() else f'{folder} + synthetic'


def plain_sgbm(left: np.ndarray, right: np.ndarray, lo: int, num: int,
               params: SGBMParams) -> np.ndarray:
    """cv2.StereoSGBM as a user runs it: minDisparity lo, numDisparities num; NaN = no match."""
    raw = params.create(lo, num).compute(to_gray(left), to_gray(right))
    d = raw.astype(np.float32) / 16.0
    d[raw < lo * 16] = np.nan
    return d


ECC_BINS = np.arange(0.0, 416.0, 16.0)      # eccentricity bins of the figure [px]


def rectified(results: dict, n_pairs: int, repeats: int, folder: Path,
              figure: Path | None = None) -> None:
    params = SGBMParams()
    tex, source = textures(folder, 4 * n_pairs)
    retina = LogPolarRetina(W, H, 200, 200)
    r_fovea = fovea_radius(retina)
    fov = FoveatedSGBM(W, H, r_fovea, retina.center, params=params)
    law = FoveatedSGBM(W, H, r_fovea, retina.center, max_level=5, params=params)
    window = DisparityWindow(0, W // 3)
    ecc = fov.eccentricity
    regions = {'fovea': ecc < r_fovea, 'centre200': np.zeros((H, W), bool), 'all': None}
    regions['centre200'][H // 2 - 100:H // 2 + 100, W // 2 - 100:W // 2 + 100] = True
    level = law.level_map()          # the annuli of the RF law's levels (0 = the fovea)
    regions.update({f'level{lv}': level == lv for lv in range(1, law.n_levels)})
    methods = ('sgbm_full_gt', 'full', 'logpolar', 'logpolar_rf_law', 'cartesian',
               'logpolar_rebuilt')
    ms: dict[str, list[float]] = {m: [] for m in methods}
    bad: dict[str, dict[str, list[float]]] = {m: {r: [0.0, 0.0, 0.0] for r in regions}
                                              for m in methods}   # bad, missing, pixels
    per_pair = []
    ecc_bin = np.clip(np.digitize(ecc, ECC_BINS) - 1, 0, ECC_BINS.size - 2)
    by_ecc = {m: np.zeros((2, ECC_BINS.size - 1)) for m in methods}    # bad, pixels per bin
    work: list[float] = []

    def pair_runs(left: np.ndarray, right: np.ndarray, lo: int,
                  num: int) -> dict[str, Callable[[], object]]:
        """The methods timed on one pair, each a call returning its disparity."""

        def rebuilt() -> np.ndarray:
            vl = retina.to_retina(retina.to_cortex(to_gray(left)))
            vr = retina.to_retina(retina.to_cortex(to_gray(right)))
            return plain_sgbm(np.clip(np.rint(vl), 0, 255).astype(np.uint8),
                              np.clip(np.rint(vr), 0, 255).astype(np.uint8), lo, num, params)

        return {
            'sgbm_full_gt': lambda: plain_sgbm(left, right, lo, num, params),
            'full': lambda: full_disparity(left, right, coarse_window(left, right, window,
                                                                      params), params).disparity,
            'logpolar': lambda: fov.compute(left, right, window).disparity,
            'logpolar_rf_law': lambda: law.compute(left, right, window).disparity,
            'cartesian': lambda: cartesian_disparity(
                left, right, coarse_window(left, right, window, params), (200, 200),
                params).disparity,
            'logpolar_rebuilt': rebuilt,
        }

    for k in range(n_pairs):
        layers = random_layers(tex[4 * k:4 * k + 4], W, H, seed=k)
        left, right, gt, visible = layered_pair(layers, W, H, noise_sd=2.0, gain=0.97, seed=k)
        truth = np.where(visible, gt, np.nan)
        lo = int(math.floor(gt.min())) - 2
        num = round_up16(math.ceil(gt.max()) + 2 - lo)
        runs = pair_runs(left, right, lo, num)
        row = {'pair': k, 'true_range': [round(float(gt.min()), 1), round(float(gt.max()), 1)]}
        # load-independent cost: SGBM cost-volume cells (pixels x disparities); plain SGBM
        # scores the columns x >= lo + num of every row
        work.append(fov.compute(left, right, window).work / (H * (W - lo - num) * num))
        for m, fn in runs.items():
            cpu, _, disp = timed(fn, repeats)
            ms[m].append(1e3 * cpu)
            row[m] = {'cpu_ms': round(1e3 * cpu, 1)}
            for r, mask in regions.items():
                b, dens = bad_fraction(disp, truth, 2.0, mask)
                n = int(np.count_nonzero(np.isfinite(truth) & (True if mask is None else mask)))
                acc = bad[m][r]
                acc[0] += b * n
                acc[1] += (1 - dens) * n
                acc[2] += n
                row[m][f'bad2_{r}'] = round(100 * b, 2)
            has = np.isfinite(truth)
            wrong = has & ~(np.abs(disp - truth) <= 2.0)
            by_ecc[m][0] += np.bincount(ecc_bin[wrong], minlength=ECC_BINS.size - 1)
            by_ecc[m][1] += np.bincount(ecc_bin[has], minlength=ECC_BINS.size - 1)
        per_pair.append(row)
        print(json.dumps(row))
    print(f'rectified pairs: {n_pairs} x 640x480, textures from {source}; fovea radius '
          f'{r_fovea:.1f} px; CPU ms best of {repeats}')
    print(f'{"matcher":18s} {"CPU ms (median, range)":>26s} {"bad-2.0 % fovea":>16s} '
          f'{"centre200":>10s} {"all":>7s} {"missing % fovea / all":>22s}')
    summary: dict[str, dict] = {}
    for m in methods:
        t = np.array(ms[m])
        pooled = {r: 100 * v[0] / v[2] for r, v in bad[m].items()}
        missing = {r: 100 * v[1] / v[2] for r, v in bad[m].items()}
        summary[m] = {'ms': float(np.median(t)), 'pooled': pooled, 'missing': missing}
        print(f'{m:18s} {np.median(t):10.1f} ({t.min():6.1f}-{t.max():6.1f}) '
              f'{pooled["fovea"]:16.2f} {pooled["centre200"]:10.2f} {pooled["all"]:7.2f} '
              f'{missing["fovea"]:10.2f} / {missing["all"]:.2f}   by level annulus 1..: '
              + ', '.join(f'{pooled[f"level{lv}"]:.1f}' for lv in range(1, law.n_levels)))
    ratio = np.array(ms['logpolar']) / np.array(ms['sgbm_full_gt'])
    ratio_full = np.array(ms['logpolar']) / np.array(ms['full'])
    if figure is not None:
        plot(figure, by_ecc, ms, r_fovea, n_pairs, source)
    gap = summary['logpolar']['pooled']['fovea'] - summary['sgbm_full_gt']['pooled']['fovea']
    print(f'logpolar / plain full-resolution SGBM (true range) CPU: median {np.median(ratio):.3f}'
          f' (max {ratio.max():.3f}); / full with searched range: {np.median(ratio_full):.3f}; '
          f'target <= 1/3: {"met" if ratio.max() <= 1 / 3 else "NOT met"}; fovea bad-2.0 '
          f'logpolar - full SGBM: {gap:+.2f} points (target <= +1: '
          f'{"met" if gap <= 1 else "NOT met"}); SGBM cost-volume cells logpolar / plain full: '
          f'median {np.median(work):.3f} (max {max(work):.3f})')
    results.update({
        'rectified_pairs': n_pairs,
        'sgbm_full_ms': round(summary['sgbm_full_gt']['ms'], 1),
        'full_searched_ms': round(summary['full']['ms'], 1),
        'logpolar_ms': round(summary['logpolar']['ms'], 1),
        'logpolar_rf_law_ms': round(summary['logpolar_rf_law']['ms'], 1),
        'cartesian_ms': round(summary['cartesian']['ms'], 1),
        'logpolar_rebuilt_ms': round(summary['logpolar_rebuilt']['ms'], 1),
        'logpolar_to_full_cost_ratio': round(float(np.median(ratio)), 3),
        'logpolar_to_full_cost_ratio_max': round(float(ratio.max()), 3),
        'fovea_bad2_gap_logpolar_minus_full_points': round(gap, 2),
        'logpolar_to_full_sgbm_cells_ratio': round(float(np.median(work)), 3),
        **{f'bad2_fovea_{m}': round(summary[m]['pooled']['fovea'], 2) for m in methods},
        **{f'bad2_all_{m}': round(summary[m]['pooled']['all'], 2) for m in methods},
        **{f'bad2_centre200_{m}': round(summary[m]['pooled']['centre200'], 2) for m in methods},
    })


def plot(path: Path, by_ecc: dict, ms: dict, r_fovea: float, n_pairs: int, source: str) -> None:
    """bad-2.0 against eccentricity per matcher, and their CPU times."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={'width_ratios': [2, 1]})
    centres = 0.5 * (ECC_BINS[1:] + ECC_BINS[:-1])
    for m, (bad, n) in by_ecc.items():
        ok = n > 0
        ax.plot(centres[ok], 100 * bad[ok] / n[ok], marker='.', label=m)
    for lv in range(3):
        ax.axvline(r_fovea * 2 ** lv, color='grey', ls=':', lw=1,
                   label='log-polar RFs 1, 2, 4 px apart' if lv == 0 else None)
    ax.text(r_fovea / 2, 0.95, 'fovea', ha='center', va='top', color='grey',
            transform=ax.get_xaxis_transform())
    ax.set_xlabel('eccentricity from the fixation (image centre) [px]')
    ax.set_ylabel('bad-2.0 [% of non-occluded pixels]')
    ax.set_title(f'{n_pairs} rectified 640x480 pairs (real photographs on slanted planes)')
    ax.set_ylim(0, None)
    ax.legend(fontsize=8)
    names = list(ms)
    med = [float(np.median(ms[m])) for m in names]
    lo = [med[i] - min(ms[m]) for i, m in enumerate(names)]
    hi = [max(ms[m]) - med[i] for i, m in enumerate(names)]
    bx.barh(names, med, xerr=[lo, hi], color='tab:blue', alpha=0.7, label='median, min-max')
    bx.set_xlabel('CPU time per pair [ms] (one thread)')
    bx.invert_yaxis()
    bx.legend(fontsize=8)
    fig.suptitle(f'stereo_ses: SGBM on what each sensor needs; textures: {source}', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f'figure: {path}')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--only', choices=('core', 'rectified'), help='run one part')
    ap.add_argument('--pairs', type=int, default=12, help='rectified pairs (default 12)')
    ap.add_argument('--repeats', type=int, default=5, help='timing repeats per matcher')
    ap.add_argument('--images', type=Path, default=IMAGES, help='photographs for the textures')
    ap.add_argument('--figure', type=Path, help='write bad-2.0 vs eccentricity and the CPU '
                    'times of the rectified part to this .png')
    args = ap.parse_args()
    cv2.setNumThreads(1)
    results: dict = {}
    if args.only != 'rectified':
        core(results)
    if args.only != 'core':
        rectified(results, args.pairs, args.repeats, args.images, args.figure)
    print(json.dumps(results))


if __name__ == '__main__':
    main()

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
- kdtree_vs_bruteforce_speedup: association of 40000 unit directions into 20000 cells
  (unbiased): the default exact lookup (`SphereLookup`, cube-map candidate lists with KD-tree
  fallback) against the chunked inner-product argmax (Eq. 3.23), assignments checked identical;
  the plain cKDTree's speed-up is printed too.
- decision_ms: reward statistics (Eqs. 3.38-3.40) + UCB over 20000 cells.

Times are CPU seconds of this single-threaded process (robust to other load on a shared
machine), best of several repeats; wall times are printed alongside.

    .venv/bin/python bench/stereo_ses.py           # last line: one JSON object
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Callable  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for _pkg in ('stereo_ses_node', 'foveation_node'):
    sys.path.insert(0, str(ROOT / 'src' / _pkg))

from stereo_ses_node.core.decision import choose_fixation  # noqa: E402
from stereo_ses_node.core.geometry import vergence_poses  # noqa: E402
from stereo_ses_node.core.ses import SensoryEgoSphere, brute_force_associate  # noqa: E402
from stereo_ses_node.core.stereo import StereoPipeline  # noqa: E402
from stereo_ses_node.core.synthetic import plane_texture, render_plane  # noqa: E402
from stereo_ses_node.core.ut import StereoRig  # noqa: E402

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


def main() -> None:
    cv2.setNumThreads(1)
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
    print(f'frame, log-polar 200x200 (to_cortex + to_retina at 640x480 + SGBM + UT + fusion): '
          f'{1e3 * lp_cpu:.1f} ms CPU ({1e3 * lp_wall:.1f} wall), {lp_fr.means.shape[0]} points')
    print(f'SES fuse 40000 obs into 20000 cells: {1e3 * up_cpu:.1f} ms CPU '
          f'({1e3 * up_wall:.1f} wall); {rep.summary()}')
    print(f'association 40000 -> 20000: brute force {1e3 * bf_cpu:.0f} ms, lookup '
          f'{1e3 * gr_cpu:.1f} ms ({speedup:.0f}x), cKDTree {1e3 * kd_cpu:.1f} ms '
          f'({bf_cpu / kd_cpu:.0f}x); identical assignments: {identical}; target >= 100x: '
          f'{"met" if speedup >= 100 and identical else "NOT met"}')
    print(f'decision over 20000 cells: UCB {1e3 * dec_cpu:.2f} ms, PI {1e3 * pi_cpu:.2f} ms, '
          f'EI {1e3 * ei_cpu:.2f} ms (CPU); UCB chose cell {dec.cell}')
    print(json.dumps({'ut_points_per_s': round(ut_rate),
                      'frame_ms_200x200': round(1e3 * fr_cpu, 1),
                      'ses_update_ms': round(1e3 * up_cpu, 1),
                      'kdtree_vs_bruteforce_speedup': round(speedup, 1),
                      'decision_ms': round(1e3 * dec_cpu, 2)}))


if __name__ == '__main__':
    main()

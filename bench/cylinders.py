"""Cylinder detector benchmark (thesis Table 4.2 timings and section 4.4.1 accuracy).

A synthetic 640x480 organized tabletop frame (3 cylinders, 8 distractors, ray cast with Open3D):
segmentation + fitting per frame (no classifier yet: frame_ms is null), fitting time of Rabbani's
baseline and ours on the same clusters, and our orientation error at 150% cap outliers (cap points
= 1.5 x side points, r = 0.3 m, N_d = 450, mild Table 4.1 bias; the other biases alongside).
Last line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import time

# one BLAS thread: the per-cluster matrices are small, and threads only contend on a shared machine
for _v in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_v, '1')

import numpy as np  # noqa: E402

from cylinder_detector_node.core.accumulator import TABLE_4_1  # noqa: E402
from cylinder_detector_node.core.fitting import FitParams, fit_cylinder, make_directions, rotation_to_z  # noqa: E402
from cylinder_detector_node.core.pipeline import detect_cylinders  # noqa: E402
from cylinder_detector_node.core.scene import make_tabletop  # noqa: E402
from cylinder_detector_node.core.segmentation import segment_tabletop  # noqa: E402
from cylinder_detector_node.core.synthetic import axis_angle_deg, make_cylinder  # noqa: E402


def timed(fn, repeats: int) -> float:
    fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=10)
    ap.add_argument('--scenes', type=int, default=50, help='synthetic scenes for the outlier accuracy')
    args = ap.parse_args()
    scene = make_tabletop(np.random.default_rng(0))
    fit = FitParams(gmm=TABLE_4_1['mild'])
    det = detect_cylinders(scene.cloud, fit=fit, intrinsics=scene.intrinsics)
    frame_ms = timed(lambda: detect_cylinders(scene.cloud, fit=fit, intrinsics=scene.intrinsics), args.repeats)
    seg = segment_tabletop(scene.cloud, intrinsics=scene.intrinsics)
    seg_ms = timed(lambda: segment_tabletop(scene.cloud, intrinsics=scene.intrinsics), args.repeats)
    rot = rotation_to_z(seg.plane[:3])
    clusters = [c.points @ rot.T for c in seg.clusters]
    per_method = {}
    for name, p in (('rabbani', FitParams(method='rabbani')), ('ours', fit)):
        d = make_directions(p)
        per_method[name] = timed(lambda: [fit_cylinder(c, p, d) for c in clusters], args.repeats)
    errs: dict[str, float] = {}
    medians: dict[str, float] = {}
    for bias in ('unbiased', 'mild', 'strong'):
        p = FitParams(gmm=TABLE_4_1[bias], radius_min=0.1, radius_max=0.5, min_confidence=0.0)
        d = make_directions(p)
        e = []
        for i in range(args.scenes):
            rng = np.random.default_rng([7, i])
            s = make_cylinder(rng, 0.3, rng.uniform(0.05, 2.0), 900, 1.5, centre=rng.uniform(-1, 1, 3))
            c = fit_cylinder(s.points, p, d)
            e.append(90.0 if c is None else axis_angle_deg(np.array(c.axis), s.axis))
        errs[bias] = float(np.mean(e))
        medians[bias] = float(np.median(e))
    pr = FitParams(method='rabbani', radius_min=0.1, radius_max=0.5, min_confidence=0.0)
    dr = make_directions(pr)
    er = []
    for i in range(args.scenes):
        rng = np.random.default_rng([7, i])
        s = make_cylinder(rng, 0.3, rng.uniform(0.05, 2.0), 900, 1.5, centre=rng.uniform(-1, 1, 3))
        c = fit_cylinder(s.points, pr, dr)
        er.append(90.0 if c is None else axis_angle_deg(np.array(c.axis), s.axis))
    print(f'frame: {len(seg.clusters)} clusters, {len(det.cylinders)} cylinders above confidence '
          f'{fit.min_confidence}; segmentation {seg_ms:.1f} ms')
    print(json.dumps({
        'frame_ms': None,
        'frame_ms_no_classifier': round(frame_ms, 1),
        'segmentation_ms': round(seg_ms, 1),
        'rabbani_ms': round(per_method['rabbani'], 1),
        'ours_ms': round(per_method['ours'], 1),
        'n_clusters': len(seg.clusters),
        'orientation_err_deg_at_150pct_outliers': round(errs['mild'], 2),
        'orientation_err_deg_at_150pct_outliers_median': round(medians['mild'], 2),
        'orientation_err_deg_at_150pct_outliers_unbiased': round(errs['unbiased'], 2),
        'orientation_err_deg_at_150pct_outliers_strong': round(errs['strong'], 2),
        'rabbani_orientation_err_deg_at_150pct_outliers': round(float(np.mean(er)), 2),
        'load_average_1min': round(os.getloadavg()[0], 2), 'cpu_count': os.cpu_count(),
    }))


if __name__ == '__main__':
    main()

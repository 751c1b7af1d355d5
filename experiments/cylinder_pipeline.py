"""Thesis Table 4.2 and Fig. 4.8 on simulated tabletop frames: the pipeline with and without the
pre-attention classifier, and the classifier's precision-recall against the fit-quality baseline.

Frames: vizzy_sim_bridge tabletop(seed) scenes never used for training (seeds from
train_classifier.HELD_OUT_SEED), one random head pose each
(cylinder_detector_node.training.sim_frames:
640x480 RGB + organized cloud, Xtion-like depth noise). Per frame, detect_cylinders runs with the
packaged classifier and without it (mild Table 4.1 prior, Eq. 4.4 threshold 0.5, one BLAS/torch
thread); the stage times (segmentation, classification, identification = fitting) are medians
over --repeats runs of the frame, then averaged over frames as in Table 4.2, both in wall-clock
and in process CPU time (on a shared, loaded machine the wall clock includes waiting for a core).

Detection quality against the ground truth: each segmented cluster is labelled by the object
owning most of its points (patch_data.label_cluster); a reported cylinder is a true positive if its
cluster belongs to a ground-truth cylinder (each counted once), else a false positive; recall is
over the ground-truth cylinders that own a segmented cluster (what segmentation lets through).
Fig. 4.8: every held-out cluster (purity >= 0.7) with its classifier P(cylinder) and its Eq. 4.4
fit quality as two scores; precision-recall curves and average precision.

Writes experiments/results/cylinder_pipeline.{json,png}.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

for _v in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_v, '1')

import matplotlib  # noqa: E402

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from protocol import cpu_seconds, protocol  # noqa: E402
from tqdm import tqdm  # noqa: E402

from cylinder_detector_node.core.accumulator import TABLE_4_1  # noqa: E402
from cylinder_detector_node.core.classifier import PatchClassifier  # noqa: E402
from cylinder_detector_node.core.fitting import FitParams  # noqa: E402
from cylinder_detector_node.core.pipeline import detect_cylinders  # noqa: E402
from cylinder_detector_node.core.synthetic import axis_angle_deg  # noqa: E402
from cylinder_detector_node.training.patch_data import (  # noqa: E402
    MIN_PURITY,
    SEGMENT,
    frame_patches,
    label_cluster,
)
from cylinder_detector_node.training.sim_frames import SimRenderer, random_joints  # noqa: E402
from cylinder_detector_node.training.train_classifier import HELD_OUT_SEED, average_precision  # noqa: E402

THESIS_FRAMES = 200


def protocol_of(result: dict, cpu_s: float | None = None) -> dict:
    """The protocol object of a result (issue 16), from the result's own fields."""
    n = result['frames']
    return protocol(
        data=f'{n} held-out simulated tabletop frames (vizzy_sim_bridge tabletop seeds '
             f'{result["first_seed"]}..{result["first_seed"] + n - 1}, one random head pose each, '
             '640x480 RGB + organized cloud with Xtion-like depth noise)',
        repetitions=n, thesis_repetitions=THESIS_FRAMES,
        models='packaged pre-attention patch CNN (cylinder_detector_node, trained on simulated '
               'tabletop patches); Hough fitting with the mild Table 4.1 prior',
        differs_from_thesis=[
            f'{n} simulated frames instead of 200 real Asus Xtion frames',
            'the classifier is trained on simulated patches (thesis: SqueezeNet on real ones)',
            f'stage times are medians of {result["repeats"]} runs per frame on a shared 2-core '
            f'machine (load average {result.get("load_average_1min")}), wall and CPU time',
        ], cpu_s=cpu_s)

STAGES = ('segmentation', 'classification', 'identification')


def pr_curve(scores: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(-scores, kind='stable')
    y = labels[order].astype(float)
    tp = np.cumsum(y)
    return tp / max(y.sum(), 1.0), tp / np.arange(1, len(y) + 1)     # recall, precision


def evaluate(frame, det, rng) -> dict[str, object]:
    """TP / FP / visible cylinders of one detection, and pose errors of the true positives."""
    owners = [label_cluster(frame, cl.points, rng) for cl in det.all_clusters]
    visible = {name for lab, pur, name in owners if lab == 1 and pur >= MIN_PURITY}
    by_id = {id(cl): o for cl, o in zip(det.all_clusters, owners, strict=True)}
    found, fp, errs = set(), 0, []
    objects = {o.name: o for o in frame.objects}
    for cl, c in zip(det.clusters, det.cylinders, strict=True):
        lab, pur, name = by_id[id(cl)]
        if lab == 1 and name not in found:
            found.add(name)
            o = objects[name]
            errs.append((axis_angle_deg(np.array(c.axis), o.axis), abs(c.radius - o.radius)))
        elif lab != 1:
            fp += 1
    return {'tp': len(found & visible), 'fp': fp, 'dup': len(det.cylinders) - len(found) - fp,
            'visible': len(visible), 'errors': errs,
            'n_cyl_clusters': sum(1 for lab, pur, _ in owners if lab == 1),
            'n_other_clusters': sum(1 for lab, pur, _ in owners if lab != 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--frames', type=int, default=30,
                    help='held-out frames (thesis: 200 real frames)')
    ap.add_argument('--repeats', type=int, default=3,
                    help='timed runs per frame and setting (median)')
    ap.add_argument('--out', type=Path, default=Path(__file__).resolve().parent / 'results')
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    clf = PatchClassifier.load()
    fit = FitParams(gmm=TABLE_4_1['mild'])
    renderer = SimRenderer()
    times: dict[str, dict[str, list[float]]] = {s: {k: [] for k in STAGES + ('total',)}
                                                for s in ('with', 'without')}
    cpu: dict[str, dict[str, list[float]]] = {s: {k: [] for k in STAGES + ('total',)}
                                              for s in ('with', 'without')}
    quality = {s: {'tp': 0, 'fp': 0, 'visible': 0, 'dup': 0, 'errors': []}
               for s in ('with', 'without')}
    scores, fitq, labels = [], [], []
    counts = []
    seed = HELD_OUT_SEED
    n = 0
    with tqdm(total=args.frames, desc='held-out frames', unit='frame') as bar:
        while n < args.frames:
            s, seed = seed, seed + 1
            try:
                frame = renderer.frame(s, random_joints(np.random.default_rng([2, s])))
            except RuntimeError:        # a seed whose objects do not fit on the table
                continue
            for setting, c in (('with', clf), ('without', None)):
                runs = []
                for _ in range(args.repeats):
                    t, tc = time.perf_counter(), time.process_time()
                    det = detect_cylinders(frame.cloud, SEGMENT, fit, image=frame.image,
                                           classifier=c)
                    runs.append((dict(det.timings_ms), 1e3 * (time.perf_counter() - t),
                                 dict(det.cpu_ms), 1e3 * (time.process_time() - tc)))
                for k in STAGES:
                    times[setting][k].append(float(np.median([r[0][k] for r in runs])))
                    cpu[setting][k].append(float(np.median([r[2][k] for r in runs])))
                times[setting]['total'].append(float(np.median([r[1] for r in runs])))
                cpu[setting]['total'].append(float(np.median([r[3] for r in runs])))
                ev = evaluate(frame, det, np.random.default_rng(s))
                for k in ('tp', 'fp', 'visible', 'dup'):
                    quality[setting][k] += ev[k]
                quality[setting]['errors'] += ev['errors']
            counts.append((ev['n_cyl_clusters'], ev['n_other_clusters']))
            fp_ = frame_patches(frame, seed=s)
            ok = fp_.purity >= MIN_PURITY
            scores.append(clf.probabilities(fp_.patches[ok]))
            fitq.append(fp_.fit_quality[ok])
            labels.append(fp_.labels[ok])
            n += 1
            bar.update()
    renderer.close()
    scores_a, fitq_a, labels_a = (np.concatenate(scores), np.concatenate(fitq),
                                  np.concatenate(labels))
    table = {s: {k: round(float(np.mean(v)), 1) for k, v in times[s].items()} for s in times}
    table_cpu = {s: {k: round(float(np.mean(v)), 1) for k, v in cpu[s].items()} for s in cpu}
    det_quality = {}
    for s, q in quality.items():
        e = np.array(q['errors']).reshape(-1, 2)
        det_quality[s] = {
            'true_positives': q['tp'], 'false_positives': q['fp'], 'duplicates': q['dup'],
            'visible_cylinders': q['visible'],
            'precision': round(q['tp'] / max(q['tp'] + q['fp'] + q['dup'], 1), 3),
            'recall': round(q['tp'] / max(q['visible'], 1), 3),
            'axis_error_deg_median': round(float(np.median(e[:, 0])), 2) if len(e) else None,
            'radius_error_mm_median': round(1e3 * float(np.median(e[:, 1])), 1) if len(e) else None}
    acc = float(((scores_a >= 0.5) == labels_a).mean())
    best_fit_acc = max(float(((fitq_a >= t) == labels_a).mean()) for t in np.linspace(0, 1, 101))
    fit_acc = float(((fitq_a >= fit.min_confidence) == labels_a).mean())
    cnt = np.array(counts, float)
    result = {
        'frames': n, 'first_seed': HELD_OUT_SEED, 'repeats': args.repeats,
        'avg_cylinder_clusters': round(float(cnt[:, 0].mean()), 2),
        'avg_other_clusters': round(float(cnt[:, 1].mean()), 2),
        'table_4_2_ms': table,
        'table_4_2_cpu_ms': table_cpu,
        'thesis_table_4_2_ms': {'without': {'segmentation': 15, 'identification': 213,
                                            'total': 228},
                                'with': {'segmentation': 15, 'classification': 64,
                                         'identification': 70, 'total': 149}},
        'detection': det_quality,
        'fig_4_8': {'patches': int(len(labels_a)), 'cylinders': int(labels_a.sum()),
                    'cnn_average_precision': round(average_precision(scores_a, labels_a), 4),
                    'fit_quality_average_precision': round(average_precision(fitq_a, labels_a), 4),
                    'cnn_accuracy_at_0.5': round(acc, 4),
                    'fit_quality_accuracy_at_0.5': round(fit_acc, 4),
                    'fit_quality_best_accuracy': round(best_fit_acc, 4)},
        'model': clf.meta,
        'load_average_1min': round(os.getloadavg()[0], 2), 'cpu_count': os.cpu_count(),
    }
    result['protocol'] = protocol_of(result, cpu_seconds())
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'cylinder_pipeline.json').write_text(json.dumps(result, indent=1))

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.3))
    for sc, name in ((scores_a, 'CNN (pre-attention)'), (fitq_a, 'fit quality, Eq. 4.4')):
        r, p = pr_curve(sc, labels_a)
        a1.plot(r, p, label=f'{name}: AP {average_precision(sc, labels_a):.3f}')
    a1.set_xlabel('recall')
    a1.set_ylabel('precision')
    a1.set_ylim(0.4, 1.02)
    a1.set_title(f'Fig. 4.8b: cylinder class, {len(labels_a)} held-out patches')
    a1.legend(loc='lower left')
    x = np.arange(2)
    bottom = np.zeros(2)
    for k in STAGES:
        v = np.array([table_cpu['without'][k], table_cpu['with'][k]])
        a2.bar(x, v, bottom=bottom, label=k)
        bottom += v
    a2.set_xticks(x, ['no classifier', 'with classifier'])
    a2.set_ylabel('CPU ms per frame (mean of medians)')
    a2.set_title(f'Table 4.2: {n} simulated frames, {cnt[:, 0].mean():.1f} cylinders + '
                 f'{cnt[:, 1].mean():.1f} others')
    a2.legend()
    fig.tight_layout()
    fig.savefig(args.out / 'cylinder_pipeline.png', dpi=110)
    print(json.dumps({'table_4_2_ms': table, 'table_4_2_cpu_ms': table_cpu,
                      'detection': det_quality, 'fig_4_8': result['fig_4_8'],
                      'load_average_1min': result['load_average_1min']}))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

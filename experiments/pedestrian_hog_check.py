#!/usr/bin/env python3
"""Does OpenCV's pretrained HOG people detector fire on the simulator's walking people?

Renders the procedural crowd (vizzy_sim_bridge.core.pedestrians) with MuJoCo offscreen from a
camera near Vizzy's eye height looking forward (horizontal FOV 85.4 deg, 640x480 like the robot's
cameras; --scene preview: a grey floor and a plain wall, camera --camera-height up; --scene sim:
the simulator's pedestrians scene and head, its left camera at rest), runs cv2.HOGDescriptor with
the default people detector (detectMultiScale, winStride (8, 8), scale 1.05, hitThreshold 0) on
every frame, and matches detections to the ground truth from a segmentation render.

Ground truth per person and frame: the amodal image box (segmentation of the person rendered
alone) and the visible fraction (its pixels in the full render / alone). A person counts for
recall when the amodal box is inside the image, at least --min-height px tall, and at least
75 % visible. A detection matches a person when its IoU with the person's box in HOG's
canonical shape (the INRIA window: person height = 0.75 window height, width = height / 2,
same centre) is >= 0.5 (also reported at 0.3). Detections that match no person (IoU >= 0.3,
any visibility) are false positives.

Writes a PNG montage (green: counted people, yellow: other people, red: HOG detections with
their SVM score) and a JSON of the detection rates.

    .venv/bin/python experiments/pedestrian_hog_check.py [--seeds 0 1 2 3 4] [--misses]
    .venv/bin/python experiments/pedestrian_hog_check.py --scene sim --name pedestrian_hog_check_sim

Rendering uses MUJOCO_GL if set, else EGL, else OSMesa.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

KEY = [((0, 200, 0), 'person counted for recall (HOG-shaped box)'),
       ((0, 220, 220), 'other person (small, occluded or cut off)'),
       ((0, 0, 255), 'HOG detection (number: SVM score)')]


def colour_key(width: int) -> np.ndarray:
    """A band under the montage naming each box colour (BGR), readable at the montage's size."""
    band = np.full((44, width, 3), 255, np.uint8)
    x = 12
    for colour, text in KEY:
        cv2.rectangle(band, (x, 12), (x + 28, 32), colour, 3)
        cv2.putText(band, text, (x + 38, 29), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1,
                    cv2.LINE_AA)
        x += 38 + cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 1)[0][0] + 30
    return band


def choose_gl() -> None:
    """MUJOCO_GL as given, else EGL if an EGL context can be made, else OSMesa."""
    if os.environ.get('MUJOCO_GL'):
        return
    probe = 'import mujoco; mujoco.GLContext(8, 8).make_current()'
    for backend in ('egl', 'osmesa'):
        env = {**os.environ, 'MUJOCO_GL': backend}
        if subprocess.run([sys.executable, '-c', probe], env=env,
                          capture_output=True).returncode == 0:
            os.environ['MUJOCO_GL'] = backend
            return
    sys.exit('no offscreen OpenGL for MuJoCo: install libegl1 (EGL) or libosmesa6 (OSMesa)')


choose_gl()

import cv2  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'src' / 'vizzy_sim_bridge'))
from protocol import cpu_seconds, protocol  # noqa: E402

from vizzy_sim_bridge.core.pedestrians import PedestrianCrowd, preview_scene_xml  # noqa: E402


def protocol_of(result: dict, cpu_s: float | None = None) -> dict:
    """The protocol object of a result (issue 16), from the result's own fields."""
    seeds, frames = result['seeds'], result['frames']
    return protocol(
        data=f"the simulator's walking people ({result['scene']} scene, "
             f"{result['people_per_scene']} per scene, seeds {seeds[0]}..{seeds[-1]}), "
             f'{frames} frames in all, MuJoCo renders 640x480',
        repetitions=len(seeds), thesis_repetitions=None,
        models=result['detector'],
        differs_from_thesis=["no thesis counterpart: checks that the thesis's detector "
                             "(OpenCV HOG) fires on the simulator's people before Fig. 5.3 "
                             'is run on them'],
        cpu_s=cpu_s)

HIDDEN_GROUP = 5


def boxes_from_segmentation(seg: np.ndarray, owner: np.ndarray, count: int
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Per person: pixel count and box (x0, y0, x1, y1), from a segmentation render."""
    ids, types = seg[..., 0], seg[..., 1]
    geom = np.where(types == int(mujoco.mjtObj.mjOBJ_GEOM), ids, -1)
    person = np.where(geom >= 0, owner[np.clip(geom, 0, None)], -1)
    px = np.zeros(count, dtype=int)
    boxes = np.zeros((count, 4))
    for k in range(count):
        vv, uu = np.nonzero(person == k)
        px[k] = len(uu)
        if len(uu):
            boxes[k] = (uu.min(), vv.min(), uu.max() + 1, vv.max() + 1)
    return px, boxes


def canonical(box: np.ndarray) -> np.ndarray:
    """The HOG/INRIA window around a person's box: 4/3 its height, half as wide as tall."""
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    h = (box[3] - box[1]) / 0.75
    return np.array([cx - h / 4, cy - h / 2, cx + h / 4, cy + h / 2])


def iou(a: np.ndarray, b: np.ndarray) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def greedy_match(dets: np.ndarray, scores: np.ndarray, gts: list[np.ndarray], thr: float
                 ) -> dict[int, int]:
    """person index -> detection index, highest-scoring detections first."""
    taken: dict[int, int] = {}
    for d in np.argsort(-scores):
        best, best_iou = -1, thr
        for k, g in enumerate(gts):
            if k in taken:
                continue
            v = iou(dets[d], g)
            if v >= best_iou:
                best, best_iou = k, v
        if best >= 0:
            taken[best] = int(d)
    return taken


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2, 3, 4])
    ap.add_argument('--frames', type=int, default=10, help='frames per seed')
    ap.add_argument('--count', type=int, default=6, help='people per scene')
    ap.add_argument('--width', type=int, default=640)
    ap.add_argument('--height', type=int, default=480)
    ap.add_argument('--hfov', type=float, default=85.4, help='horizontal field of view [deg]')
    ap.add_argument('--camera-height', type=float, default=1.1,
                    help='[m] above the ground (preview scene)')
    ap.add_argument('--scene', choices=('preview', 'sim'), default='preview',
                    help='preview: the crowd on a grey floor before a wall, camera looking ahead '
                         'at --camera-height; sim: core.scenes pedestrians with the Vizzy head, '
                         'its left camera (0.95 m up) at rest')
    ap.add_argument('--min-height', type=float, default=128.0, help='[px] people counted')
    ap.add_argument('--out', type=Path, default=ROOT / 'experiments' / 'results')
    ap.add_argument('--name', default='pedestrian_hog_check')
    ap.add_argument('--misses', action='store_true',
                    help='also write NAME_misses.png: crops of the counted people HOG missed')
    args = ap.parse_args()

    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    args.out.mkdir(parents=True, exist_ok=True)
    totals = {'counted': 0, 'hit50': 0, 'hit30': 0, 'all_in_view': 0, 'all_hit50': 0, 'fp': 0,
              'frames': 0, 'dets': 0}
    by_height: dict[str, list[int]] = {'128-192': [0, 0], '192-256': [0, 0], '256+': [0, 0]}
    per_seed = {}
    det_ms: list[float] = []
    montage: list[np.ndarray] = []
    misses: list[np.ndarray] = []
    for seed in args.seeds:
        if args.scene == 'sim':  # the simulator's own scene and head, seen by the left eye
            from vizzy_sim_bridge.core.model import CameraSpec, compile_model
            from vizzy_sim_bridge.core.scenes import build_scene
            scene = build_scene('pedestrians', seed, count=args.count)
            crowd, camera = scene.crowd, 'left_camera'
            model, _ = compile_model(scene, eye=CameraSpec(args.width, args.height, args.hfov))
        else:
            crowd, camera = PedestrianCrowd(np.random.default_rng(seed), args.count), 'eye'
            model = mujoco.MjModel.from_xml_string(preview_scene_xml(
                crowd, width=args.width, height=args.height, hfov_deg=args.hfov,
                camera_height=args.camera_height))
        data = mujoco.MjData(model)
        rgb_r = mujoco.Renderer(model, args.height, args.width)
        seg_r = mujoco.Renderer(model, args.height, args.width)
        seg_r.enable_segmentation_rendering()
        owner = crowd.geom_owner(model)
        group0 = model.geom_group.copy()
        opt = mujoco.MjvOption()
        opt.geomgroup[HIDDEN_GROUP] = 0
        seed_stats = {'counted': 0, 'hit50': 0, 'fp': 0}
        for f in range(args.frames):
            t = 0.37 + f * crowd.period / args.frames
            crowd.update(model, data, t)
            rgb_r.update_scene(data, camera)
            img = rgb_r.render()
            seg_r.update_scene(data, camera, opt)
            vis_px, _ = boxes_from_segmentation(seg_r.render(), owner, args.count)
            alone_px, boxes = np.zeros(args.count, dtype=int), np.zeros((args.count, 4))
            for k in range(args.count):
                model.geom_group[:] = np.where((owner >= 0) & (owner != k), HIDDEN_GROUP, group0)
                seg_r.update_scene(data, camera, opt)
                px, bx = boxes_from_segmentation(seg_r.render(), owner, args.count)
                alone_px[k], boxes[k] = px[k], bx[k]
            model.geom_group[:] = group0

            bgr = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
            t0 = time.perf_counter()
            rects, weights = hog.detectMultiScale(bgr, winStride=(8, 8), scale=1.05,
                                                  hitThreshold=0)
            det_ms.append(1e3 * (time.perf_counter() - t0))
            dets = np.array([[x, y, x + w, y + h] for x, y, w, h in rects],
                            dtype=float).reshape(-1, 4)
            scores = np.asarray(weights, dtype=float).ravel()
            gts = [canonical(b) for b in boxes]
            m50 = greedy_match(dets, scores, gts, 0.5)
            m30 = greedy_match(dets, scores, gts, 0.3)
            heights = boxes[:, 3] - boxes[:, 1]
            inside = ((boxes[:, 0] > 1) & (boxes[:, 1] > 1) & (boxes[:, 2] < args.width - 1)
                      & (boxes[:, 3] < args.height - 1) & (alone_px > 0))
            big = inside & (heights >= args.min_height)
            visible = vis_px / np.maximum(alone_px, 1)
            counted = big & (visible >= 0.75)
            totals['frames'] += 1
            totals['dets'] += len(dets)
            totals['counted'] += int(counted.sum())
            totals['all_in_view'] += int(big.sum())
            totals['hit50'] += sum(1 for k in np.flatnonzero(counted) if k in m50)
            totals['hit30'] += sum(1 for k in np.flatnonzero(counted) if k in m30)
            totals['all_hit50'] += sum(1 for k in np.flatnonzero(big) if k in m50)
            fp = len(dets) - len(m30)
            totals['fp'] += fp
            seed_stats['counted'] += int(counted.sum())
            seed_stats['hit50'] += sum(1 for k in np.flatnonzero(counted) if k in m50)
            seed_stats['fp'] += fp
            for k in np.flatnonzero(counted):
                if args.misses and k not in m50 and len(misses) < 48:
                    x0, y0, x1, y1 = canonical(boxes[k]).astype(int)
                    pad = cv2.copyMakeBorder(img, 200, 200, 200, 200, cv2.BORDER_CONSTANT)
                    crop = pad[y0 + 200:y1 + 200, x0 + 200:x1 + 200]
                    misses.append(cv2.resize(cv2.cvtColor(crop, cv2.COLOR_RGB2BGR), (96, 192)))
                key = '128-192' if heights[k] < 192 else '192-256' if heights[k] < 256 else '256+'
                by_height[key][0] += 1
                by_height[key][1] += int(k in m50)

            if len(montage) < 6 and f % max(1, args.frames // 3) == 0:
                for k in range(args.count):
                    if alone_px[k] == 0:
                        continue
                    colour = (0, 200, 0) if counted[k] else (0, 220, 220)
                    x0, y0, x1, y1 = boxes[k].astype(int)
                    cv2.rectangle(bgr, (x0, y0), (x1, y1), colour, 1)
                for d, sc in zip(dets.astype(int), scores, strict=True):
                    cv2.rectangle(bgr, (d[0], d[1]), (d[2], d[3]), (0, 0, 255), 2)
                    cv2.putText(bgr, f'{sc:.1f}', (d[0] + 2, d[1] + 14), cv2.FONT_HERSHEY_SIMPLEX,
                                0.45, (0, 0, 255), 1, cv2.LINE_AA)
                cv2.putText(bgr, f'seed {seed} t={t:.2f}s', (6, args.height - 8),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
                montage.append(bgr)
        per_seed[str(seed)] = {**seed_stats,
                               'recall': seed_stats['hit50'] / max(1, seed_stats['counted']),
                               'min_distance_m': crowd.min_distance}
        rgb_r.close()
        seg_r.close()
        print(f'seed {seed}: {seed_stats["hit50"]}/{seed_stats["counted"]} people found, '
              f'{seed_stats["fp"]} false positives', flush=True)

    n = totals['counted']
    result = {
        'detector': 'cv2.HOGDescriptor_getDefaultPeopleDetector, detectMultiScale(winStride=(8,8), '
                    'scale=1.05, hitThreshold=0)',
        'scene': args.scene,
        'camera': {'width': args.width, 'height': args.height, 'hfov_deg': args.hfov,
                   'height_m': args.camera_height if args.scene == 'preview' else 'left_camera'},
        'seeds': args.seeds, 'frames': totals['frames'], 'people_per_scene': args.count,
        'min_height_px': args.min_height,
        'people_counted': n,
        'recall_iou50': totals['hit50'] / max(1, n),
        'recall_iou30': totals['hit30'] / max(1, n),
        'recall_iou50_including_occluded': totals['all_hit50'] / max(1, totals['all_in_view']),
        'people_in_view_including_occluded': totals['all_in_view'],
        'false_positives_per_frame': totals['fp'] / max(1, totals['frames']),
        'detections_per_frame': totals['dets'] / max(1, totals['frames']),
        'recall_by_height_px': {k: {'people': v[0], 'recall': v[1] / max(1, v[0])}
                                for k, v in by_height.items()},
        'per_seed': per_seed,
        'hog_ms_mean': float(np.mean(det_ms)) if det_ms else None,
        'mujoco_gl': os.environ.get('MUJOCO_GL'),
    }
    png = args.out / f'{args.name}.png'
    js = args.out / f'{args.name}.json'
    if montage:
        while len(montage) % 3:
            montage.append(np.zeros_like(montage[0]))
        rows = [np.hstack(montage[i:i + 3]) for i in range(0, len(montage), 3)]
        sheet = np.vstack(rows)
        if args.width > 480:  # keep the picture small enough for the repository
            sheet = cv2.resize(sheet, None, fx=0.75, fy=0.75, interpolation=cv2.INTER_AREA)
        sheet = np.vstack([sheet, colour_key(sheet.shape[1])])
        cv2.imwrite(str(png), sheet, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    result['protocol'] = protocol_of(result, cpu_seconds())
    js.write_text(json.dumps(result, indent=2) + '\n')
    if misses:
        while len(misses) % 12:
            misses.append(np.zeros_like(misses[0]))
        cv2.imwrite(str(args.out / f'{args.name}_misses.png'),
                    np.vstack([np.hstack(misses[i:i + 12]) for i in range(0, len(misses), 12)]))
    print(json.dumps({k: result[k] for k in ('people_counted', 'recall_iou50', 'recall_iou30',
                                             'false_positives_per_frame')}))
    print(f'wrote {png} and {js}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

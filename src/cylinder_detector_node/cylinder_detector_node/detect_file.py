"""detect_file: find cylinders in a .pcd or .ply point cloud and print them as JSON.

    ros2 run cylinder_detector_node detect_file scan.pcd [--method ours|rabbani] [--bias strong]
    python -m cylinder_detector_node.detect_file scan.ply --plot out.png [--image rgb.png]

Tabletop segmentation (thesis section 4.3.1) then the two-stage Hough fit of each cluster
(section 4.3.3). The cloud is taken in a camera optical frame (x right, y down, z forward; REP 103),
so "up" is -y unless --up says otherwise (e.g. --up 0,0,1 for a cloud in a z-up robot frame); the
table is the highest plane below the sensor, within --up-tolerance degrees of level, with objects
on it: not the back wall, the ceiling or the floor under the table (core.segmentation). An
organized .pcd (WIDTH x HEIGHT = POINTS) with colour gives the image for the pre-attention
classifier (section 4.3.2); --image gives one for any organized cloud; --no-classifier turns it
off. Output (stdout, strict JSON): {"cylinders": [{centre, axis, radius, height, confidence,
probability, axis_to_table_normal_deg, ...}], "table": {...}, "planes": [...], "cpu_ms": {load,
downsample, plane, clusters, classification, fitting, total}, "wall_ms": {the same}, "messages":
[...]};
stderr: the messages and one line of CPU time per stage.
Exit status 0 (with an empty list when nothing is found); 2 with one line on stderr when a file
cannot be read (missing, a directory, not .pcd/.ply, truncated, not what its header says, no
points) or an option is bad.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, NoReturn

# One OpenMP thread for Open3D (and torch) unless the user says otherwise: on one frame the extra
# threads mostly spin (the classifier took 370 ms CPU for 10 ms of work with 2 threads on 2 cores).
os.environ.setdefault('OMP_NUM_THREADS', '1')

import numpy as np  # noqa: E402

from .core.accumulator import TABLE_4_1  # noqa: E402
from .core.cloudfile import read_cloud  # noqa: E402
from .core.fitting import FitParams  # noqa: E402
from .core.pipeline import Detection, detect_cylinders  # noqa: E402
from .core.segmentation import CAMERA_UP, SegmentParams  # noqa: E402

PROG = 'detect_file'
STAGES = ('load', 'downsample', 'plane', 'clusters', 'classification', 'fitting', 'total')


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line `detect_file: <message>` on stderr, exit status 2."""

    def error(self, message: str) -> NoReturn:
        print(f'{self.prog}: {message} (see --help)', file=sys.stderr)
        raise SystemExit(2)


def vector3(text: str) -> tuple[float, float, float]:
    """'x,y,z' -> a finite non-zero 3-vector (argparse type)."""
    try:
        v = tuple(float(w) for w in text.split(','))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(np.isfinite(v)) or not any(v):
        raise argparse.ArgumentTypeError(f'{text!r} is not a non-zero vector x,y,z')
    return v


def positive(kind: type) -> Any:
    def parse(text: str) -> Any:
        try:
            v = kind(text)
        except ValueError:
            v = None
        if v is None or not np.isfinite(v) or v <= 0:
            raise argparse.ArgumentTypeError(f'{text!r} is not a positive number')
        return v
    return parse


def strict(value: Any) -> Any:
    """value with every non-finite float as None (strict JSON)."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict(v) for v in value]
    return value


def load_points(path: Path) -> np.ndarray:
    """The xyz points (N, 3) of a .pcd/.ply file (Open3D). Raises ValueError with a clear
    message."""
    return load_cloud(path)[0].reshape(-1, 3)


def load_cloud(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(points, image): points (H, W, 3) for an organized .pcd (WIDTH x HEIGHT = POINTS,
    HEIGHT > 1), else (N, 3); image (H, W, 3) uint8 RGB from an organized cloud's colours, else
    None. Raises ValueError (core.cloudfile.CloudFileError) with a one-line message naming the
    file."""
    return read_cloud(path)


def plot_patches(image: np.ndarray, det: Detection, out: Path) -> None:
    """The image with every cluster's patch: green when fitted as a cylinder, red when the
    classifier rejected it, orange when Eq. 4.4 did; P(cylinder) written above."""
    import cv2
    img = np.ascontiguousarray(image[..., ::-1])
    fitted = {id(c) for c in det.clusters}
    for cl, p in zip(det.all_clusters, det.cluster_probabilities, strict=True):
        if cl.patch is None:
            continue
        u0, v0, u1, v1 = cl.patch
        rejected = p is not None and id(cl) not in fitted and p < 0.5
        colour = (0, 200, 0) if id(cl) in fitted else ((0, 0, 230) if rejected else (0, 140, 255))
        cv2.rectangle(img, (u0, v0), (u1 - 1, v1 - 1), colour, 2)
        if p is not None:
            cv2.putText(img, f'{p:.2f}', (u0, max(v0 - 4, 12)), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                        colour, 1, cv2.LINE_AA)
    try:
        ok = cv2.imwrite(str(out), img)
    except cv2.error:                      # no writer for the suffix
        ok = False
    if not ok:
        raise OSError(f'{out}: OpenCV could not write it (a folder, no permission, or an '
                      f'unknown suffix)')


def plot_detection(points: np.ndarray, det: Detection, out: Path, max_points: int = 40000) -> None:
    """Matplotlib 3D render of the cloud (subsampled) with the fitted cylinders as wireframes, in
    the table frame (table normal up) when a table was found."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from .core.fitting import rotation_to_z
    rot = rotation_to_z(det.plane[:3]) if det.plane is not None else np.eye(3)

    def tf(p: np.ndarray) -> np.ndarray:   # to (x, y, z) plot axes, z up
        q = np.asarray(p) @ rot.T
        return q if det.plane is not None else q[..., [0, 2, 1]] * np.array([1, 1, -1])
    pts = tf(points[np.all(np.isfinite(points), axis=1)])
    if det.clusters:  # zoom on the table region around the objects
        allc = tf(np.vstack([c.points for c in det.clusters]))
        lo, hi = allc.min(axis=0) - 0.15, allc.max(axis=0) + 0.15
        pts = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
    if len(pts) > max_points:
        pts = pts[np.random.default_rng(0).choice(len(pts), max_points, replace=False)]
    fig = plt.figure(figsize=(9, 7))
    ax = fig.add_subplot(projection='3d')
    # camera optical frame (x right, y down, z forward) shown as x, z, -y so up is up
    ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.3, c='0.6', alpha=0.4)
    for cl in det.clusters:
        cp = tf(cl.points)
        ax.scatter(cp[:, 0], cp[:, 1], cp[:, 2], s=0.5, alpha=0.5)
    for c in det.cylinders:
        a = np.array(c.axis)
        u = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(a, u)
        th = np.linspace(0, 2 * np.pi, 40)
        for s in np.linspace(-0.5, 0.5, 5):
            ring = tf(np.array(c.centre) + s * c.height * a
                      + c.radius * (np.outer(np.cos(th), u) + np.outer(np.sin(th), v)))
            ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color=plt.cm.RdYlGn(c.confidence), lw=1.5)
        top = tf(np.array(c.centre))
        ax.text(top[0], top[1], top[2] + c.height / 2 + 0.03,
                f'r={c.radius * 100:.1f}cm p={c.confidence:.2f}')
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_zlabel('up (m)' if det.plane is not None else '-y (m)')
    ax.view_init(elev=20, azim=-75)
    ax.set_box_aspect((1, 1, 1))
    if det.clusters:
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
    ax.set_title(f'{len(det.cylinders)} cylinder(s)')
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def build_parser() -> argparse.ArgumentParser:
    ap = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    ap.add_argument('cloud', type=Path, help='.pcd or .ply file')
    ap.add_argument('--method', choices=('ours', 'rabbani'), default='ours')
    ap.add_argument('--bias', choices=sorted(TABLE_4_1), default='mild',
                    help='Table 4.1 orientation prior; vertical = normal of the table plane')
    ap.add_argument('--n-directions', type=positive(int), default=450)
    ap.add_argument('--radius-min', type=positive(float), default=0.01)
    ap.add_argument('--radius-max', type=positive(float), default=0.1)
    ap.add_argument('--min-confidence', type=float, default=0.5, help='Eq. 4.4 threshold')
    ap.add_argument('--min-normal-agreement', type=float, default=0.7,
                    help='least fraction of a fit\'s side points whose normal is within 20 deg of '
                         'radial (0 = off): flat faces (a box) fail it')
    ap.add_argument('--voxel', type=positive(float), default=0.01,
                    help='downsampling (m) for plane and clusters')
    ap.add_argument('--min-cluster-points', type=positive(int), default=30)
    ap.add_argument('--max-range', type=positive(float), default=None,
                    help='ignore points farther than this (m)')
    ap.add_argument('--up', type=vector3, default=CAMERA_UP, metavar='X,Y,Z',
                    help='"up" (against gravity) in the cloud\'s frame; default 0,-1,0: a camera '
                         'optical frame (y down)')
    ap.add_argument('--up-tolerance', type=positive(float), default=60.0, metavar='DEG',
                    help='largest angle between the table\'s normal and --up, below 90 '
                         '(default 60: a camera looking down up to 60 degrees)')
    ap.add_argument('--any-plane', action='store_true',
                    help='ignore --up: the largest plane of any orientation with objects on it')
    ap.add_argument('--plot', type=Path, default=None,
                    help='save a PNG render of the cloud and cylinders')
    ap.add_argument('--image', type=Path, default=None,
                    help='colour image of an organized cloud (same size) for the classifier')
    ap.add_argument('--no-classifier', action='store_true',
                    help='fit every cluster (no pre-attention CNN)')
    ap.add_argument('--classifier-model', type=Path, default=None,
                    help='classifier weights (default: packaged)')
    ap.add_argument('--classifier-threshold', type=float, default=0.5)
    ap.add_argument('--plot-patches', type=Path, default=None,
                    help='save the image with each cluster\'s patch and classifier probability')
    return ap


def angle_deg(a: Any, b: Any) -> float:
    """Angle between two directions (sign ignored), degrees."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    c = float(abs(float(a @ b)) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, c)))


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if args.radius_min >= args.radius_max:
            raise ValueError(f'--radius-min {args.radius_min} must be below '
                             f'--radius-max {args.radius_max}')
        if not args.up_tolerance < 90.0:
            raise ValueError(f'--up-tolerance {args.up_tolerance:g} must be below 90 degrees')
        for out in (args.plot, args.plot_patches):
            if out is not None and not out.parent.is_dir():
                raise ValueError(f'{out}: cannot write the plot there (no folder {out.parent})')
        seg = SegmentParams(voxel_size=args.voxel, min_cluster_points=args.min_cluster_points,
                            max_range=args.max_range, up=None if args.any_plane else args.up,
                            up_tolerance_deg=args.up_tolerance)
        fit = FitParams(method=args.method, gmm=TABLE_4_1[args.bias],
                        n_directions=args.n_directions, radius_min=args.radius_min,
                        radius_max=args.radius_max, min_confidence=args.min_confidence,
                        min_normal_agreement=args.min_normal_agreement)
        pts, image = load_cloud(args.cloud)
        if args.image is not None:
            import cv2
            bgr = cv2.imread(str(args.image), cv2.IMREAD_COLOR) if args.image.is_file() else None
            if bgr is None:
                raise ValueError(f'{args.image}: not a readable image')
            image = bgr[..., ::-1].copy()
    except ValueError as e:
        print(f'{PROG}: {" ".join(str(e).split())}', file=sys.stderr)
        return 2
    load_wall, load_cpu = 1e3 * (time.perf_counter() - t0), 1e3 * (time.process_time() - c0)
    classifier = None
    if not args.no_classifier and image is not None:
        from .core.classifier import PatchClassifier
        try:
            classifier = PatchClassifier.load(args.classifier_model)
        except (OSError, ValueError) as exc:
            print(f'{PROG}: classifier unavailable, fitting every cluster: {exc}', file=sys.stderr)
    det = detect_cylinders(pts, seg, fit, image=image, classifier=classifier,
                           classifier_threshold=args.classifier_threshold)
    cpu = {'load': load_cpu, **det.stage_cpu_ms}
    wall = {'load': load_wall, **det.stage_wall_ms}
    cpu['total'] += load_cpu
    wall['total'] += load_wall
    for m in det.messages:
        print(f'{PROG}: {args.cloud}: {m}', file=sys.stderr)
    flat = pts.reshape(-1, 3)
    table = None
    if det.plane is not None:
        table = {'normal': [round(float(v), 5) for v in det.plane[:3]],
                 'height_m': round(float(det.plane[3]), 4),
                 'angle_to_up_deg': (None if seg.up is None
                                     else round(angle_deg(det.plane[:3], seg.up), 2))}
    cylinders = []
    for c, p in zip(det.cylinders, det.probabilities, strict=True):
        assert det.plane is not None   # cylinders are fitted only on a table plane
        d = dict(c.to_dict(), probability=p)
        d['axis_to_table_normal_deg'] = round(angle_deg(c.axis, det.plane[:3]), 2)
        d['range_m'] = round(float(np.linalg.norm(c.centre)), 3)
        cylinders.append(d)
    result = {'file': str(args.cloud), 'method': args.method, 'bias': args.bias,
              'n_points': int(np.all(np.isfinite(flat), axis=1).sum()) if len(flat) else 0,
              'organized': pts.ndim == 3, 'classifier': classifier is not None,
              'up': None if seg.up is None else list(seg.up),
              'up_tolerance_deg': seg.up_tolerance_deg,
              'table': table, 'planes': det.planes,
              'n_clusters': det.n_clusters, 'rejected_by_classifier': det.rejected_by_classifier,
              'cluster_probabilities': [None if p is None else round(p, 4)
                                        for p in det.cluster_probabilities],
              'cylinders': cylinders,
              'cpu_ms': {k: round(cpu.get(k, 0.0), 1) for k in STAGES},
              'wall_ms': {k: round(wall.get(k, 0.0), 1) for k in STAGES}, 'messages': det.messages}
    try:
        if args.plot is not None:
            plot_detection(flat, det, args.plot)
        if args.plot_patches is not None and image is not None:
            plot_patches(image, det, args.plot_patches)
    except (OSError, ValueError) as e:     # e.g. an unwritable file, an unknown image suffix
        print(f'{PROG}: cannot save the plot: {" ".join(str(e).split())}', file=sys.stderr)
        return 2
    stages = ', '.join(f'{k} skipped' if k == 'classification' and classifier is None
                       else f'{k} {cpu.get(k, 0.0):.1f}'
                       for k in STAGES)
    print(f'{PROG}: {args.cloud}: {len(det.cylinders)} cylinder(s); CPU ms: {stages} '
          f'(wall total {wall["total"]:.1f} ms)', file=sys.stderr)
    print(json.dumps(strict(result), indent=1, allow_nan=False))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

"""detect_file: find cylinders in a .pcd or .ply point cloud and print them as JSON.

    ros2 run cylinder_detector_node detect_file scan.pcd [--method ours|rabbani] [--bias strong]
    python -m cylinder_detector_node.detect_file scan.ply --plot out.png [--image rgb.png]

Tabletop segmentation (thesis section 4.3.1) then the two-stage Hough fit of each cluster
(section 4.3.3); the cloud is taken in a camera optical frame (z forward) so the table is the plane
below the camera. An organized .pcd (WIDTH x HEIGHT = POINTS) with colour gives the image for the
pre-attention classifier (section 4.3.2); --image gives one for any organized cloud; --no-classifier
turns it off. Output: {"cylinders": [{centre, axis, radius, height, confidence, probability, ...}],
"messages": [...]}.
Exit status 0 with an empty list when nothing is found; 2 when the file cannot be read.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .core.accumulator import TABLE_4_1
from .core.fitting import FitParams
from .core.pipeline import Detection, detect_cylinders
from .core.segmentation import SegmentParams


def load_points(path: Path) -> np.ndarray:
    """The xyz points (N, 3) of a .pcd/.ply file (Open3D). Raises ValueError with a clear message."""
    return load_cloud(path)[0].reshape(-1, 3)


def pcd_size(path: Path) -> tuple[int, int] | None:
    """(WIDTH, HEIGHT) from a .pcd header, or None."""
    if path.suffix.lower() != '.pcd':
        return None
    fields: dict[str, str] = {}
    with open(path, 'rb') as f:
        for _ in range(20):
            line = f.readline().decode('ascii', 'replace').strip()
            if not line or line.startswith('DATA'):
                break
            key, _, value = line.partition(' ')
            fields[key] = value
    try:
        return int(fields['WIDTH']), int(fields['HEIGHT'])
    except (KeyError, ValueError):
        return None


def _declares_no_points(path: Path) -> bool:
    """True for a .pcd whose header says POINTS 0 or a .ply whose says element vertex 0."""
    with open(path, 'rb') as f:
        head = f.read(4096).decode('ascii', 'replace').splitlines()
    if path.suffix.lower() == '.pcd':
        return any(line.split()[:2] == ['POINTS', '0'] for line in head if line.strip())
    return bool(head) and head[0].strip() == 'ply' and any(
        line.split()[:3] == ['element', 'vertex', '0'] for line in head)


def load_cloud(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """(points, image): points (H, W, 3) for an organized .pcd (WIDTH x HEIGHT = POINTS, HEIGHT > 1),
    else (N, 3); image (H, W, 3) uint8 RGB from an organized cloud's colours, else None.
    Raises ValueError with a clear message."""
    import open3d as o3d
    if not path.is_file():
        raise ValueError(f'{path}: no such file')
    if path.suffix.lower() not in ('.pcd', '.ply'):
        raise ValueError(f'{path}: expected a .pcd or .ply file')
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)   # keep stdout pure JSON
    pcd = o3d.io.read_point_cloud(str(path), remove_nan_points=False, remove_infinite_points=False)
    pts = np.asarray(pcd.points, dtype=np.float64)
    if len(pts) == 0 and not _declares_no_points(path):
        raise ValueError(f'{path}: not a readable {path.suffix.lower()[1:].upper()} point cloud '
                         '(Open3D read no points from it)')
    size = pcd_size(path)
    if size is None or size[1] <= 1 or size[0] * size[1] != len(pts):
        return pts, None
    w, h = size
    image = None
    if pcd.has_colors():
        image = np.clip(np.asarray(pcd.colors) * 255.0 + 0.5, 0, 255).astype(np.uint8).reshape(h, w, 3)
    return pts.reshape(h, w, 3), image


def plot_patches(image: np.ndarray, det: Detection, out: Path) -> None:
    """The image with every cluster's patch: green when fitted as a cylinder, red when the
    classifier rejected it, orange when Eq. 4.4 did; P(cylinder) written above."""
    import cv2
    img = np.ascontiguousarray(image[..., ::-1])
    fitted = {id(c) for c in det.clusters}
    for cl, p in zip(det.all_clusters, det.cluster_probabilities):
        if cl.patch is None:
            continue
        u0, v0, u1, v1 = cl.patch
        rejected = p is not None and id(cl) not in fitted and p < 0.5
        colour = (0, 200, 0) if id(cl) in fitted else ((0, 0, 230) if rejected else (0, 140, 255))
        cv2.rectangle(img, (u0, v0), (u1 - 1, v1 - 1), colour, 2)
        if p is not None:
            cv2.putText(img, f'{p:.2f}', (u0, max(v0 - 4, 12)), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1, cv2.LINE_AA)
    cv2.imwrite(str(out), img)


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
            ring = tf(np.array(c.centre) + s * c.height * a + c.radius * (np.outer(np.cos(th), u) + np.outer(np.sin(th), v)))
            ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color=plt.cm.RdYlGn(c.confidence), lw=1.5)
        top = tf(np.array(c.centre))
        ax.text(top[0], top[1], top[2] + c.height / 2 + 0.03, f'r={c.radius * 100:.1f}cm p={c.confidence:.2f}')
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
    ap = argparse.ArgumentParser(prog='detect_file', description=__doc__.splitlines()[0])
    ap.add_argument('cloud', type=Path, help='.pcd or .ply file')
    ap.add_argument('--method', choices=('ours', 'rabbani'), default='ours')
    ap.add_argument('--bias', choices=sorted(TABLE_4_1), default='mild',
                    help='Table 4.1 orientation prior; vertical = normal of the table plane')
    ap.add_argument('--n-directions', type=int, default=450)
    ap.add_argument('--radius-min', type=float, default=0.01)
    ap.add_argument('--radius-max', type=float, default=0.1)
    ap.add_argument('--min-confidence', type=float, default=0.5, help='Eq. 4.4 threshold')
    ap.add_argument('--voxel', type=float, default=0.01, help='downsampling (m) for plane and clusters')
    ap.add_argument('--min-cluster-points', type=int, default=30)
    ap.add_argument('--max-range', type=float, default=None, help='ignore points farther than this (m)')
    ap.add_argument('--plot', type=Path, default=None, help='save a PNG render of the cloud and cylinders')
    ap.add_argument('--image', type=Path, default=None,
                    help='colour image of an organized cloud (same size) for the classifier')
    ap.add_argument('--no-classifier', action='store_true', help='fit every cluster (no pre-attention CNN)')
    ap.add_argument('--classifier-model', type=Path, default=None, help='classifier weights (default: packaged)')
    ap.add_argument('--classifier-threshold', type=float, default=0.5)
    ap.add_argument('--plot-patches', type=Path, default=None,
                    help='save the image with each cluster\'s patch and classifier probability')
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        pts, image = load_cloud(args.cloud)
        if args.image is not None:
            import cv2
            bgr = cv2.imread(str(args.image), cv2.IMREAD_COLOR)
            if bgr is None:
                raise ValueError(f'{args.image}: not a readable image')
            image = bgr[..., ::-1].copy()
        classifier = None
        if not args.no_classifier and image is not None:
            from .core.classifier import PatchClassifier
            try:
                classifier = PatchClassifier.load(args.classifier_model)
            except (OSError, ValueError) as exc:
                print(f'detect_file: classifier unavailable, fitting every cluster: {exc}', file=sys.stderr)
        fit = FitParams(method=args.method, gmm=TABLE_4_1[args.bias], n_directions=args.n_directions,
                        radius_min=args.radius_min, radius_max=args.radius_max, min_confidence=args.min_confidence)
        seg = SegmentParams(voxel_size=args.voxel, min_cluster_points=args.min_cluster_points,
                            max_range=args.max_range)
    except ValueError as e:
        print(f'detect_file: {e}', file=sys.stderr)
        return 2
    det = detect_cylinders(pts, seg, fit, image=image, classifier=classifier,
                           classifier_threshold=args.classifier_threshold)
    for m in det.messages:
        print(f'detect_file: {args.cloud}: {m}', file=sys.stderr)
    flat = pts.reshape(-1, 3)
    result = {'file': str(args.cloud), 'method': args.method, 'bias': args.bias,
              'n_points': int(np.all(np.isfinite(flat), axis=1).sum()) if len(flat) else 0,
              'organized': pts.ndim == 3, 'classifier': classifier is not None,
              'n_clusters': det.n_clusters, 'rejected_by_classifier': det.rejected_by_classifier,
              'cluster_probabilities': [None if p is None else round(p, 4) for p in det.cluster_probabilities],
              'cylinders': [dict(c.to_dict(), probability=p) for c, p in zip(det.cylinders, det.probabilities)],
              'timings_ms': {k: round(v, 1) for k, v in det.timings_ms.items()}, 'messages': det.messages}
    if args.plot is not None:
        plot_detection(flat, det, args.plot)
    if args.plot_patches is not None and image is not None:
        plot_patches(image, det, args.plot_patches)
    print(json.dumps(result, indent=1))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())

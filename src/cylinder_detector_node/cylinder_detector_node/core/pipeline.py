"""Segmentation, pre-attention classification, then fitting (thesis Fig. 4.1, Table 4.2).

Each cluster's image patch goes through the pre-attention CNN (section 4.3.2) when an image and
a classifier are given; clusters it rejects are not fitted (the thesis's speed and precision
argument). The others are fitted in the table frame (table normal = +z), so the vertical biases
of Table 4.1 mean "upright on the table"; results are returned in the cloud's frame. The time of
each stage is kept (segmentation, classification, identification: the rows of Table 4.2), wall and
process CPU time, and the CPU and wall time of each step (downsample, plane, clusters,
classification, fitting, total) in stage_cpu_ms and stage_wall_ms.

Two checks beyond Eq. 4.4 (issue 31: a real milk carton scored 0.52 and a bottle's handle 0.87):
a cluster that is part of a larger object (off the table, beside another cluster: a handle) is not
fitted (parts_of_objects), and a fit whose side points' normals are not radial (a box's faces) is
rejected (FitParams.min_normal_agreement, core.fitting.normal_agreement).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from . import open3d_lib
from .accumulator import TABLE_4_1
from .fitting import Cylinder, FitParams, fit_cylinder, make_directions, rotation_to_z, vec3
from .segmentation import Cluster, SegmentParams, segment_tabletop

if TYPE_CHECKING:
    import open3d as o3d
else:     # the compiled module alone: not the package's visualization start-up (open3d_lib)
    o3d = open3d_lib.load()

Array = NDArray[np.float64]


@dataclass
class Detection:
    cylinders: list[Cylinder] = field(default_factory=list)
    clusters: list[Cluster] = field(default_factory=list)       #: the cluster of each cylinder
    #: classifier P(cylinder) of each (None: not classified)
    probabilities: list[float | None] = field(default_factory=list)
    #: clusters below the Eq. 4.4 threshold
    rejected: int = 0
    #: clusters the classifier rejected (not fitted)
    rejected_by_classifier: int = 0
    #: clusters that are parts of a larger object (parts_of_objects; not fitted)
    rejected_parts: int = 0
    #: fits whose normals are not radial (below FitParams.min_normal_agreement)
    rejected_surface: int = 0
    n_clusters: int = 0                                          #: clusters out of the segmentation
    plane: Array | None = None
    messages: list[str] = field(default_factory=list)
    #: segmentation, classification, identification (wall)
    timings_ms: dict[str, float] = field(default_factory=dict)
    #: the same stages in process CPU time
    cpu_ms: dict[str, float] = field(default_factory=dict)
    #: process CPU time of each step: downsample, plane, clusters (the segmentation), classification
    #: (0 when no classifier ran), fitting, total
    stage_cpu_ms: dict[str, float] = field(default_factory=dict)
    stage_wall_ms: dict[str, float] = field(default_factory=dict)   #: the same steps, wall clock
    #: the segmentation's candidate planes
    planes: list[dict[str, Any]] = field(default_factory=list)
    all_clusters: list[Cluster] = field(default_factory=list)    #: every segmented cluster
    #: P(cylinder) of each of all_clusters
    cluster_probabilities: list[float | None] = field(default_factory=list)


def image_problem(image: Any, cloud_shape: tuple[int, ...]) -> str | None:
    """Why image cannot give patches for an organized cloud of cloud_shape (H, W, 3), or None."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] < 3 or img.dtype != np.uint8:
        return f'image of shape {img.shape} and type {img.dtype} is not an 8-bit colour image'
    if len(cloud_shape) != 3:
        return 'the cloud is not organized (H x W): its clusters have no image patches'
    if img.shape[:2] != tuple(cloud_shape[:2]):
        return (f'image {img.shape[1]}x{img.shape[0]} does not match the '
                f'{cloud_shape[1]}x{cloud_shape[0]} '
                f'cloud (width x height)')
    return None


#: m: a cluster whose lowest point is this far above the table does not stand on it (objects on the
#: table start at SegmentParams.min_height, 1 cm)
PART_LIFT = 0.03
#: m: a neighbour rising this far above such a cluster's lowest point is beside it, not under it
PART_OVERHANG = 0.02


def parts_of_objects(clusters: list[Cluster], plane: Array, gap: float) -> list[int | None]:
    """For each cluster, the index of the larger object it is a part of, or None.

    A part does not reach the table (its lowest point more than PART_LIFT above the plane) and has
    another cluster within `gap` of its points that stands on the table, has more points and rises
    more than PART_OVERHANG above the part's lowest point: the object it hangs from, beside it (a
    bottle's body beside its handle, which the clustering split off across a gap of a little more
    than its eps). Something standing on another object (a cup on books) has that object's top
    under it, not beside it, and stays an object; so does a cluster with nothing near it, and one
    whose bottom is hidden behind an object that does not stand on the table either or is smaller.
    """
    n = np.asarray(plane[:3], dtype=np.float64)
    heights = [cl.points @ n + float(plane[3]) for cl in clusters]
    low = [float(h.min()) if len(h) else 0.0 for h in heights]
    high = [float(h.max()) if len(h) else 0.0 for h in heights]
    clouds: dict[int, o3d.geometry.PointCloud] = {}

    def cloud(i: int) -> o3d.geometry.PointCloud:
        if i not in clouds:
            clouds[i] = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(clusters[i].points))
        return clouds[i]

    out: list[int | None] = [None] * len(clusters)
    for a, ca in enumerate(clusters):
        if low[a] <= PART_LIFT or not len(ca.points):
            continue
        for b, cb in enumerate(clusters):
            if (b == a or low[b] > PART_LIFT or high[b] <= low[a] + PART_OVERHANG
                    or len(cb.points) <= len(ca.points)
                    or np.any(cb.box_min - ca.box_max > gap)
                    or np.any(ca.box_min - cb.box_max > gap)):
                continue
            dist = np.asarray(cloud(a).compute_point_cloud_distance(cloud(b)), dtype=np.float64)
            if len(dist) and float(dist.min()) <= gap:
                out[a] = b
                break
    return out


def _totals(out: Detection, t0: float, c0: float) -> None:
    """Fill in fitting (= identification) and total of the per-step times."""
    out.stage_wall_ms['fitting'] = out.timings_ms['identification']
    out.stage_cpu_ms['fitting'] = out.cpu_ms['identification']
    out.stage_wall_ms['total'] = 1e3 * (time.perf_counter() - t0)
    out.stage_cpu_ms['total'] = 1e3 * (time.process_time() - c0)


def detect_cylinders(points: Array, seg: SegmentParams | None = None, fit: FitParams | None = None,
                     intrinsics: tuple[float, float, float, float] | None = None,
                     image_size: tuple[int, int] = (640, 480),
                     image: NDArray[np.uint8] | None = None,
                     classifier: Any = None, classifier_threshold: float = 0.5) -> Detection:
    """Tabletop segmentation (4.3.1), pre-attention on each cluster's patch of image (RGB, same
    size as the organized cloud) when a classifier (core.classifier.PatchClassifier) is given
    (4.3.2), then a fit per remaining cluster (4.3.3, Eq. 4.4). A bad image (size mismatch, not
    RGB, unorganized cloud) skips the classifier with a message."""
    fit = fit or FitParams()
    t0, c0 = time.perf_counter(), time.process_time()
    s = segment_tabletop(points, seg, intrinsics, image_size)
    t1, c1 = time.perf_counter(), time.process_time()
    out = Detection(plane=s.plane, messages=list(s.messages), n_clusters=len(s.clusters),
                    all_clusters=list(s.clusters), planes=s.planes)
    out.timings_ms['segmentation'], out.cpu_ms['segmentation'] = 1e3 * (t1 - t0), 1e3 * (c1 - c0)
    out.stage_cpu_ms.update(s.cpu_ms)
    out.stage_wall_ms.update(s.wall_ms)
    probs: list[float | None] = [None] * len(s.clusters)
    if classifier is not None and image is not None and s.clusters:
        problem = image_problem(image, np.shape(points))
        if problem is not None:
            out.messages.append(f'classifier skipped: {problem}')
        else:
            idx = [i for i, cl in enumerate(s.clusters) if cl.patch is not None]
            p = classifier.classify(np.asarray(image), [s.clusters[i].patch for i in idx])
            for i, v in zip(idx, p, strict=True):
                probs[i] = float(v)
    out.cluster_probabilities = probs
    t2, c2 = time.perf_counter(), time.process_time()
    out.timings_ms['classification'], out.cpu_ms['classification'] = (
        1e3 * (t2 - t1), 1e3 * (c2 - c1))
    out.stage_wall_ms['classification'], out.stage_cpu_ms['classification'] = (
        1e3 * (t2 - t1), 1e3 * (c2 - c1))
    if s.plane is None or not s.clusters:
        out.timings_ms['identification'] = out.cpu_ms['identification'] = 0.0
        _totals(out, t0, c0)
        return out
    rot = rotation_to_z(s.plane[:3])          # cloud frame -> table frame (normal to +z)
    directions = make_directions(fit)
    # twice the clustering's reach: the gap it split a handle from its body across
    parts = parts_of_objects(s.clusters, s.plane, 2.0 * (seg or SegmentParams()).cluster_eps)
    for cl, prob, part in zip(s.clusters, probs, parts, strict=True):
        if prob is not None and prob < classifier_threshold:
            out.rejected_by_classifier += 1
            continue
        if part is not None:
            out.rejected_parts += 1
            continue
        if len(cl.points) < fit.min_points:
            out.messages.append(f'cluster of {len(cl.points)} points is too small to fit '
                                f'(min_points={fit.min_points})')
            continue
        c = fit_cylinder(cl.points @ rot.T, fit, directions)
        if c is None:
            out.rejected += 1
            continue
        if c.normal_agreement < fit.min_normal_agreement:
            out.rejected_surface += 1
            continue
        centre = rot.T @ np.array(c.centre)
        axis = rot.T @ np.array(c.axis)
        if axis @ s.plane[:3] < 0:
            axis = -axis
        out.cylinders.append(replace(c, centre=vec3(centre), axis=vec3(axis)))
        out.clusters.append(cl)
        out.probabilities.append(prob)
    out.timings_ms['identification'] = 1e3 * (time.perf_counter() - t2)
    out.cpu_ms['identification'] = 1e3 * (time.process_time() - c2)
    _totals(out, t0, c0)
    if out.rejected_by_classifier:
        out.messages.append(f'{out.rejected_by_classifier} cluster(s) below classifier probability '
                            f'{classifier_threshold}: not cylinders (not fitted)')
    if out.rejected_parts:
        out.messages.append(f'{out.rejected_parts} cluster(s) off the table beside a larger one '
                            f'(a handle, a part of an object): not fitted')
    if out.rejected:
        out.messages.append(f'{out.rejected} cluster(s) below confidence {fit.min_confidence} '
                            f'(Eq. 4.4): not cylinders')
    if out.rejected_surface:
        out.messages.append(f'{out.rejected_surface} fit(s) with under '
                            f'{fit.min_normal_agreement:g} of their side normals within '
                            f'{fit.normal_agreement_deg:g} deg of radial (flat faces, e.g. a box): '
                            f'not cylinders')
    return out


def pipeline_params(p: dict[str, Any]) -> tuple[SegmentParams, FitParams]:
    """The core's parameters from the node's."""
    seg = SegmentParams(voxel_size=p['voxel_size_m'], plane_distance=p['plane_distance_m'],
                        cluster_eps=p['cluster_eps_m'], min_cluster_points=p['min_cluster_points'],
                        max_range=p['max_range_m'] or None, up_tolerance_deg=p['up_tolerance_deg'])
    fit = FitParams(method=p['method'], gmm=TABLE_4_1[p['bias']], n_directions=p['n_directions'],
                    radius_min=p['radius_min_m'], radius_max=p['radius_max_m'],
                    min_confidence=p['min_confidence'],
                    min_normal_agreement=p['min_normal_agreement'])
    return seg, fit

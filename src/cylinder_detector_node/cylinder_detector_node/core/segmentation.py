"""Bottom-up tabletop segmentation (thesis section 4.3.1).

Plane RANSAC on a voxel-downsampled cloud (Open3D segment_plane), the points above the plane (the
camera's side), Euclidean clustering (Open3D cluster_dbscan), and each cluster's 2D image patch:
for an organized (H, W, 3) cloud the bounding box of the cluster's own pixels (exact, no camera
model needed); for an unorganized cloud with pinhole intrinsics, the cluster's 3D box projected
(as the thesis does). Problems are reported in `Segmentation.messages`, never raised: bad input
gives empty results.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
from numpy.typing import NDArray
from scipy.spatial import cKDTree

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SegmentParams:
    voxel_size: float = 0.01             #: m, downsampling for RANSAC and clustering
    plane_distance: float = 0.01         #: m, RANSAC inlier distance
    ransac_iterations: int = 500
    ransac_probability: float = 0.999    #: RANSAC stops early once this sure of its plane (Open3D)
    grid_stride: int = 2                 #: organized clouds: pixel stride of the cloud that is downsampled
    min_plane_points: int = 200          #: a plane with fewer (downsampled) inliers is "no table"
    min_height: float = 0.01             #: m above the plane for an object point
    max_height: float = 0.5              #: m above the plane
    cluster_eps: float = 0.02            #: m, DBSCAN neighbourhood (Euclidean clustering tolerance)
    min_cluster_points: int = 30         #: downsampled points; smaller clusters are dropped
    max_table_gap: float = 0.05          #: m, a cluster's centre projected on the plane must be this close to a table point
    max_range: float | None = None       #: m from the sensor; farther points are ignored (None: all)
    max_planes: int = 3                  #: planes tried (largest first) until one has objects on it
    seed: int = 0


@dataclass(frozen=True)
class Cluster:
    points: Array                                   #: (N, 3) full-resolution points of the object
    box_min: Array
    box_max: Array
    patch: tuple[int, int, int, int] | None = None  #: (u0, v0, u1, v1) image box, or None without intrinsics
    pixels: NDArray[np.int64] | None = None          #: flat pixel index of each point (organized clouds)


@dataclass
class Segmentation:
    plane: Array | None = None                      #: (a, b, c, d), normal towards the camera
    clusters: list[Cluster] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)


def finite_points(points: Array) -> Array:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return pts[np.all(np.isfinite(pts), axis=1)]


def project_box(box_min: Array, box_max: Array, intrinsics: tuple[float, float, float, float],
                size: tuple[int, int]) -> tuple[int, int, int, int] | None:
    """The image rectangle (u0, v0, u1, v1) covering a 3D box's 8 corners (camera optical frame,
    z forward), clipped to size = (width, height); None if it lies behind the camera or off-image."""
    fx, fy, cx, cy = intrinsics
    corners = np.array(np.meshgrid(*zip(box_min, box_max), indexing='ij')).reshape(3, -1).T
    corners = corners[corners[:, 2] > 1e-6]
    if len(corners) == 0:
        return None
    u = fx * corners[:, 0] / corners[:, 2] + cx
    v = fy * corners[:, 1] / corners[:, 2] + cy
    w, h = size
    u0, u1 = int(np.clip(np.floor(u.min()), 0, w)), int(np.clip(np.ceil(u.max()), 0, w))
    v0, v1 = int(np.clip(np.floor(v.min()), 0, h)), int(np.clip(np.ceil(v.max()), 0, h))
    if u1 <= u0 or v1 <= v0:
        return None
    return u0, v0, u1, v1


def refine_plane(points: Array, plane: Array, distance: float) -> Array:
    """Least-squares plane (centroid, smallest principal axis) of the points within distance of
    plane; unit normal with the camera (origin) on its positive side."""
    plane = plane / np.linalg.norm(plane[:3])
    on = points[np.abs(points @ plane[:3] + plane[3]) <= distance]
    if len(on) >= 3:
        c = on.mean(axis=0)
        normal = np.linalg.svd(on - c, full_matrices=False)[2][2]
        plane = np.append(normal, -normal @ c)
    return -plane if plane[3] < 0 else plane


def segment_tabletop(points: Array, params: SegmentParams | None = None,
                     intrinsics: tuple[float, float, float, float] | None = None,
                     image_size: tuple[int, int] = (640, 480)) -> Segmentation:
    """Table plane, then object clusters above it. `points` is (N, 3) or an organized (H, W, 3)
    cloud in the camera frame (NaNs allowed). Organized clouds give each cluster's pixels and image
    box; unorganized ones give image boxes when intrinsics = (fx, fy, cx, cy) are given."""
    params = params or SegmentParams()
    out = Segmentation()
    arr = np.asarray(points)
    if arr.dtype not in (np.float32, np.float64):
        arr = arr.astype(np.float64)
    organized = arr.ndim == 3 and arr.shape[-1] == 3
    if organized:
        image_size = (arr.shape[1], arr.shape[0])
    flat = arr.reshape(-1, 3)
    # The plane and the clusters come from a voxel-downsampled cloud: for an organized cloud every
    # `grid_stride`-th pixel is plenty (1.7 mm pixel footprint at 1 m against 1 cm voxels) and
    # makes the copies, range test and voxel grid that much cheaper.
    coarse = arr[::params.grid_stride, ::params.grid_stride].reshape(-1, 3) if organized else flat
    pts = coarse[np.isfinite(coarse.sum(axis=1))].astype(np.float64)   # any NaN/inf makes the sum non-finite
    if len(pts) == 0:
        out.messages.append('cloud has 0 finite points')
        return out
    if params.max_range is not None:
        pts = pts[np.einsum('ij,ij->i', pts, pts) <= params.max_range ** 2]
        if len(pts) == 0:
            out.messages.append(f'no points within max_range {params.max_range} m')
            return out
    down = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)).voxel_down_sample(params.voxel_size)
    if len(down.points) < max(params.min_plane_points, 3):
        out.messages.append(f'no table plane: {len(down.points)} points after downsampling, '
                            f'need at least {params.min_plane_points}')
        return out
    o3d.utility.random.seed(params.seed)
    dpts = np.asarray(down.points)
    # The largest plane is the table unless the floor (or a wall) outnumbers it: then nothing stands
    # on it, and the next plane, from the points off it, is tried (up to max_planes). RANSAC runs
    # on a 2x coarser voxel grid (a tenth of the time), then the plane is refitted by least
    # squares to its inliers on the voxel_size grid.
    rest = down.voxel_down_sample(2.0 * params.voxel_size)
    for attempt in range(params.max_planes):
        if len(rest.points) < 3:
            break
        plane, inliers = rest.segment_plane(params.plane_distance, 3, params.ransac_iterations,
                                            params.ransac_probability)
        plane = refine_plane(dpts, np.asarray(plane, dtype=np.float64), params.plane_distance)
        on = np.abs(dpts @ plane[:3] + plane[3]) <= params.plane_distance
        if on.sum() < params.min_plane_points:
            if attempt == 0:
                out.messages.append(f'no table plane: best plane has {int(on.sum())} inliers, '
                                    f'need {params.min_plane_points}')
                return out
            break
        hd = dpts @ plane[:3] + plane[3]
        above = (hd > params.min_height) & (hd < params.max_height)
        if out.plane is None or above.sum() >= params.min_cluster_points:
            out.plane, table_mask = plane, on
        if above.sum() >= params.min_cluster_points:
            break
        rest = rest.select_by_index(inliers, invert=True)
    if out.plane is None:
        out.messages.append('no table plane: too few points for RANSAC')
        return out
    plane = out.plane
    hd = dpts @ plane[:3] + plane[3]
    above = (hd > params.min_height) & (hd < params.max_height)
    if above.sum() < params.min_cluster_points:
        out.messages.append(f'no objects above the table plane ({int(above.sum())} points)')
        return out
    obj = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(dpts[above]))
    labels = np.asarray(obj.cluster_dbscan(params.cluster_eps, params.min_cluster_points // 3 or 1))
    if labels.size == 0 or labels.max() < 0:
        out.messages.append('no clusters above the table plane')
        return out
    counts = np.bincount(labels[labels >= 0])
    small = int((counts < params.min_cluster_points).sum())
    if small:
        out.messages.append(f'{small} cluster(s) below {params.min_cluster_points} points dropped')
    # Full-resolution points: assign each object point to the nearest downsampled clustered point.
    # NaN rows compare False, so no finiteness pass over the full cloud is needed
    hf = flat @ plane[:3].astype(flat.dtype) + plane[3]
    obj_mask = (hf > params.min_height) & (hf < params.max_height)
    if params.max_range is not None:
        obj_mask &= np.einsum('ij,ij->i', flat, flat) <= params.max_range ** 2
    full_pix = np.flatnonzero(obj_mask)
    full = flat[full_pix].astype(np.float64)
    dist, nn = cKDTree(dpts[above]).query(full, k=1, distance_upper_bound=2 * params.voxel_size)
    ok = np.isfinite(dist)
    full_labels = np.full(len(full), -1)
    full_labels[ok] = labels[nn[ok]]
    keep = np.flatnonzero(counts >= params.min_cluster_points)
    # objects stand on the table: the plane projection of each cluster's centre lies on table points
    table = dpts[table_mask]
    centres = np.array([dpts[above][labels == lab].mean(axis=0) for lab in keep]).reshape(-1, 3)
    on_plane = centres - (centres @ plane[:3] + plane[3])[:, None] * plane[:3]
    gap, _ = cKDTree(table).query(on_plane, k=1)
    off = int((gap > params.max_table_gap).sum())
    if off:
        out.messages.append(f'{off} cluster(s) not standing on the table plane dropped')
    for lab in keep[gap <= params.max_table_gap]:
        sel = full_labels == lab
        cp = full[sel]
        lo, hi = cp.min(axis=0), cp.max(axis=0)
        if organized:
            px = full_pix[sel]
            rows, cols = np.divmod(px, image_size[0])
            patch = (int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1)
            out.clusters.append(Cluster(cp, lo, hi, patch, px))
        else:
            patch = project_box(lo, hi, intrinsics, image_size) if intrinsics is not None else None
            out.clusters.append(Cluster(cp, lo, hi, patch))
    return out

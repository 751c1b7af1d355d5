"""Bottom-up tabletop segmentation (thesis section 4.3.1).

Table plane, then the objects standing on it. Planes come from RANSAC (Open3D segment_plane) on a
voxel-downsampled cloud, extracted one after the other (largest first, each one's inliers removed,
up to `max_planes`). The table is the plane a user means by it:

- it faces up: its normal is within `up_tolerance_deg` of `up`, the direction against gravity in
  the cloud's frame (from tf in the node; for a file, the camera optical frame's -y, REP 103), and
  the sensor is on its upper side (it lies below the sensor). This passes over the back wall, the
  ceiling and any side wall however large they are.
- it is a surface: at least `min_plane_points` of its inliers lie in connected parts some 6 cm
  wide or more (_region), not along the line where a wall crosses the plane or scattered where
  RANSAC laid a plane through clutter. Each plane is refitted by least squares to its inliers
  until they stop changing, so the result does not depend on RANSAC's draw.
- it has objects on it: clusters (Open3D cluster_dbscan, Euclidean clustering) of points between
  `min_height` and `max_height` above it whose centres project onto the surface's points.
- it is level: within LEVEL_DEG of the largest such plane (gravity's normal, better known from
  the scene than from a camera's -y; RANSAC planes laid through clutter are tilted).
- among such planes, the highest one (nearest below the sensor): the table, not the floor it
  stands on, however much floor is in view. A plane lying less than `max_height` above a larger
  one (or a few plane_distance below it) and over it (a stack of books, a laptop, a second
  RANSAC piece of the same floor) is one of that plane's objects or part of it, not a table.
- when no plane has objects, the largest upward plane is reported with "no objects".

With `up=None` any plane counts (normal turned towards the sensor) and the largest one with objects
on it wins (the segmentation before gravity was taken into account).

Each cluster's 2D image patch: for an organized (H, W, 3) cloud the bounding box of the cluster's
own pixels (exact, no camera model needed); for an unorganized cloud with pinhole intrinsics, the
cluster's 3D box projected (as the thesis does). Problems are reported in `Segmentation.messages`,
never raised: bad input gives empty results. CPU (time.process_time, every thread of the process)
and wall time of each stage are in `Segmentation.cpu_ms` and `.wall_ms`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.spatial import cKDTree

from . import open3d_lib

if TYPE_CHECKING:
    import open3d as o3d
else:     # the compiled module alone: not the package's visualization start-up (open3d_lib)
    o3d = open3d_lib.load()

Array = NDArray[np.float64]

#: "up" in a camera optical frame (x right, y down, z forward; REP 103): -y
CAMERA_UP = (0.0, -1.0, 0.0)
#: planes closer than this to parallel count as parallel when one may lie on the other
PARALLEL_DEG = 20.0
#: a support surface is level: within this of the largest upward plane's normal
LEVEL_DEG = 10.0
#: inliers up to this many grid cells (2 voxels each) from a plane's surface still support objects
SUPPORT_CELLS = 5
#: after a plane is found, RANSAC goes on without the points within BAND x plane_distance of it
BAND = 3.0


@dataclass(frozen=True)
class SegmentParams:
    voxel_size: float = 0.01             #: m, downsampling for RANSAC and clustering
    plane_distance: float = 0.01         #: m, RANSAC inlier distance
    ransac_iterations: int = 500
    ransac_probability: float = 0.999    #: RANSAC stops early once this sure of its plane (Open3D)
    #: organized clouds: pixel stride of the cloud that is downsampled
    grid_stride: int = 2
    min_plane_points: int = 200          #: a plane with fewer (downsampled) inliers is "no table"
    min_height: float = 0.01             #: m above the plane for an object point
    max_height: float = 0.5              #: m above the plane
    cluster_eps: float = 0.02            #: m, DBSCAN neighbourhood (Euclidean clustering tolerance)
    min_cluster_points: int = 30         #: downsampled points; smaller clusters are dropped
    #: m, a cluster's centre projected on the plane must be this close to a table point
    max_table_gap: float = 0.05
    #: m from the sensor; farther points are ignored (None: all)
    max_range: float | None = None
    #: planes RANSAC extracts (largest first) as table candidates
    max_planes: int = 6
    #: against gravity, cloud frame; None: any plane
    up: tuple[float, float, float] | None = CAMERA_UP
    up_tolerance_deg: float = 60.0       #: largest angle between the table's normal and up
    seed: int = 0

    def __post_init__(self) -> None:
        if self.up is not None:
            u = np.asarray(self.up, dtype=np.float64)
            if u.shape != (3,) or not np.all(np.isfinite(u)) or np.linalg.norm(u) < 1e-9:
                raise ValueError(f'up must be a finite non-zero 3-vector, got {self.up!r}')
        if not 0.0 < self.up_tolerance_deg < 90.0:
            raise ValueError(f'up_tolerance_deg must be in (0, 90), got {self.up_tolerance_deg}')
        if self.max_planes < 1:
            raise ValueError(f'max_planes must be at least 1, got {self.max_planes}')


@dataclass(frozen=True)
class Cluster:
    points: Array                                   #: (N, 3) full-resolution points of the object
    box_min: Array
    box_max: Array
    #: (u0, v0, u1, v1) image box, or None without intrinsics
    patch: tuple[int, int, int, int] | None = None
    #: flat pixel index of each point (organized clouds)
    pixels: NDArray[np.int64] | None = None


@dataclass
class Segmentation:
    plane: Array | None = None                      #: (a, b, c, d), normal towards the camera
    clusters: list[Cluster] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    #: every RANSAC plane and what became of it
    planes: list[dict[str, Any]] = field(default_factory=list)
    #: downsample, plane, clusters (process CPU)
    cpu_ms: dict[str, float] = field(default_factory=dict)
    wall_ms: dict[str, float] = field(default_factory=dict)      #: the same stages, wall clock


def finite_points(points: Array) -> Array:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return pts[np.all(np.isfinite(pts), axis=1)]


def project_box(box_min: Array, box_max: Array, intrinsics: tuple[float, float, float, float],
                size: tuple[int, int]) -> tuple[int, int, int, int] | None:
    """The image rectangle (u0, v0, u1, v1) covering a 3D box's 8 corners (camera optical frame,
    z forward), clipped to size = (width, height); None if it lies behind the camera or
    off-image."""
    fx, fy, cx, cy = intrinsics
    corners = np.array(np.meshgrid(*zip(box_min, box_max, strict=True), indexing='ij'))
    corners = corners.reshape(3, -1).T
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


def refine_plane(points: Array, plane: Array, distance: float, iterations: int = 8) -> Array:
    """Least-squares plane (centroid, smallest principal axis) of the points within distance of
    plane, repeated with the new plane's inliers until they no longer change (at most
    `iterations` times): a fixed point that does not depend on which of the nearly equal
    hypotheses RANSAC returned (Open3D's segment_plane differs from run to run, seed or not).
    Unit normal with the camera (origin) on its positive side."""
    plane = np.asarray(plane, dtype=np.float64) / np.linalg.norm(plane[:3])
    mask = None
    for _ in range(iterations):
        new = np.abs(points @ plane[:3] + plane[3]) <= distance
        if int(new.sum()) < 3 or (mask is not None and np.array_equal(new, mask)):
            break
        mask = new
        on = points[mask]
        c = on.mean(axis=0)
        normal = np.linalg.svd(on - c, full_matrices=False)[2][2]
        plane = np.append(normal, -normal @ c)
    return -plane if plane[3] < 0 else plane


@dataclass
class _Candidate:
    plane: Array                 #: unit normal towards the sensor
    on: NDArray[np.bool_]        #: inliers among the downsampled points
    up_cos: float | None         #: cos(normal, up), None without up
    info: dict[str, Any]         #: what Segmentation.planes reports of it
    #: the inliers that hold objects up: its surface and next to it (_region)
    region: NDArray[np.bool_]
    objects: _Objects | None = None

    @property
    def size(self) -> int:
        return int(self.info['points'])


@dataclass
class _Objects:
    above: NDArray[np.int64]     #: indices (into the downsampled points) between min and max height
    labels: NDArray[np.int64]    #: DBSCAN label of each of above (-1: noise)
    standing: NDArray[np.int64]  #: labels of the clusters kept (big enough, standing on the plane)
    messages: list[str]


def _region(plane: Array, on: NDArray[np.bool_], dpts: Array,
            params: SegmentParams) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """(surface, support) masks of the plane's inliers. Surface: the inliers on a 2D grid in the
    plane (cells of 2 voxels; closed, so that gaps of a cell are bridged) that survive an opening
    by a 3x3 cell square (what is narrower than about 3 cells goes): not the line along which a
    back wall crosses the table's plane (the wall's strip above the table would look like an
    object standing on it), not the scattered inliers of a plane RANSAC laid through clutter.
    Support: every inlier within SUPPORT_CELLS cells of the surface, so the narrow strips of table
    between objects and their shadows still hold up what stands there."""
    idx = np.flatnonzero(on)
    surface = np.zeros(len(dpts), dtype=bool)
    support = np.zeros(len(dpts), dtype=bool)
    if len(idx) == 0:
        return surface, support
    uv = dpts[idx] @ _plane_frame(plane[:3]).T
    lo = uv.min(axis=0)
    # at most 1000^2 cells
    cell = max(2.0 * params.voxel_size, float((uv.max(axis=0) - lo).max()) / 1000.0)
    # a margin of 2 cells for the closing
    ij = ((uv - lo) / cell).astype(np.int64) + 2
    grid = np.zeros(ij.max(axis=0) + 3, dtype=bool)
    grid[ij[:, 0], ij[:, 1]] = True
    square = np.ones((3, 3), dtype=bool)
    opened = ndimage.binary_opening(ndimage.binary_closing(grid, square), square)
    near = ndimage.binary_dilation(opened, square, iterations=SUPPORT_CELLS)
    surface[idx[opened[ij[:, 0], ij[:, 1]]]] = True
    support[idx[near[ij[:, 0], ij[:, 1]]]] = True
    return surface, support


def _objects_on(dpts: Array, cand: _Candidate, params: SegmentParams) -> _Objects:
    """The clusters between min_height and max_height above cand's plane, and those of them big
    enough and standing on it (centre projected onto the plane within max_table_gap of its
    points)."""
    plane = cand.plane
    hd = dpts @ plane[:3] + plane[3]
    above = (hd > params.min_height) & (hd < params.max_height)
    # Only what lies over the plane's own points can stand on it: a cheap box test in the plane
    # (2D) before clustering keeps e.g. the strip of back wall above a table out of DBSCAN.
    frame = _plane_frame(plane[:3])
    region = cand.region
    on2 = dpts[region] @ frame.T
    pad = max(0.1, 2.0 * params.max_table_gap)
    in2 = dpts[above] @ frame.T
    inside = np.all((in2 >= on2.min(axis=0) - pad) & (in2 <= on2.max(axis=0) + pad), axis=1)
    above = np.flatnonzero(above)[inside]
    none = np.zeros(0, dtype=np.int64)
    if len(above) < params.min_cluster_points:
        return _Objects(above, none, none,
                        [f'no objects above the table plane ({len(above)} points)'])
    obj = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(dpts[above]))
    labels = np.asarray(obj.cluster_dbscan(params.cluster_eps, params.min_cluster_points // 3 or 1),
                        dtype=np.int64)
    if labels.size == 0 or labels.max() < 0:
        return _Objects(above, labels, none, ['no clusters above the table plane'])
    messages = []
    good = labels >= 0
    counts = np.bincount(labels[good])
    small = int((counts < params.min_cluster_points).sum())
    if small:
        messages.append(f'{small} cluster(s) below {params.min_cluster_points} points dropped')
    keep = np.flatnonzero(counts >= params.min_cluster_points)
    if len(keep) == 0:
        return _Objects(above, labels, none, messages)
    # objects stand on the table: the plane projection of each cluster's centre lies on table points
    sums = np.stack([np.bincount(labels[good], weights=dpts[above][good][:, k],
                                 minlength=len(counts))
                     for k in range(3)], axis=1)
    centres = sums[keep] / counts[keep, None]
    on_plane = centres - (centres @ plane[:3] + plane[3])[:, None] * plane[:3]
    gap, _ = cKDTree(dpts[region]).query(on_plane, k=1)
    off = int((gap > params.max_table_gap).sum())
    if off:
        messages.append(f'{off} cluster(s) not standing on the table plane dropped')
    return _Objects(above, labels, keep[gap <= params.max_table_gap], messages)


def _plane_frame(normal: Array) -> Array:
    """(2, 3): two unit vectors spanning the plane of normal."""
    a = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, a)
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(normal, u)])


def _lies_on(a: _Candidate, b: _Candidate, dpts: Array, params: SegmentParams) -> bool:
    """Whether plane a is something standing on the larger plane b, or another piece of it:
    nearly parallel, its centre less than max_height above b (or a few plane_distance below: the
    same floor as two RANSAC planes), and over b (inside the box of b's points in b's plane)."""
    if a.size >= b.size or a.plane[:3] @ b.plane[:3] < math.cos(math.radians(PARALLEL_DEG)):
        return False
    ca = dpts[a.region].mean(axis=0)
    h = ca @ b.plane[:3] + b.plane[3]
    if not -3.0 * params.plane_distance < h < params.max_height:
        return False
    frame = _plane_frame(b.plane[:3])
    pb = dpts[b.region] @ frame.T
    pa = frame @ ca
    return bool(np.all(pa >= pb.min(axis=0)) and np.all(pa <= pb.max(axis=0)))


def _choose(cands: list[_Candidate], dpts: Array, params: SegmentParams) -> _Candidate | None:
    """The table among the candidate planes (module docstring); evaluates objects lazily."""
    if params.up is None:
        order = sorted(cands, key=lambda c: -c.size)
    else:
        # Level surfaces share one normal (gravity's): the largest upward plane's is a better "up"
        # than the given one (the camera's -y for a file), and a plane tilted against it (one RANSAC
        # laid through clutter) is no support surface.
        level = max(cands, key=lambda c: c.size).plane[:3]
        min_cos = math.cos(math.radians(LEVEL_DEG))
        for c in cands:
            if c.plane[:3] @ level < min_cos:
                angle = math.degrees(math.acos(np.clip(c.plane[:3] @ level, -1, 1)))
                c.info['verdict'] = f'{angle:.0f} deg from the largest upward plane (not level)'
        cands = [c for c in cands if c.plane[:3] @ level >= min_cos]
        order = []
        # highest (nearest below the sensor) first
        for c in sorted(cands, key=lambda c: c.plane[3]):
            host = next((b for b in cands if _lies_on(c, b, dpts, params)), None)
            if host is not None:
                c.info['verdict'] = (f'lies on the plane {host.info["height_m"]:.2f} m below the '
                                     'sensor (one of its objects)')
                continue
            order.append(c)
    for c in order:
        c.objects = _objects_on(dpts, c, params)
        if len(c.objects.standing):
            c.info['verdict'] = 'table'
            for o in order:
                if o is not c and o.objects is None:
                    o.info['verdict'] = ('lower than the table' if params.up is not None
                                         else 'smaller than the table')
            return c
        c.info['verdict'] = 'no objects on it'
    if not cands:
        return None
    best = max(cands, key=lambda c: c.size)       # no plane has objects: the largest one
    best.info['verdict'] = 'table (no objects on it)'
    if best.objects is None:
        best.objects = _objects_on(dpts, best, params)
    return best


def segment_tabletop(points: Array, params: SegmentParams | None = None,
                     intrinsics: tuple[float, float, float, float] | None = None,
                     image_size: tuple[int, int] = (640, 480)) -> Segmentation:
    """Table plane, then object clusters on it (module docstring). `points` is (N, 3) or an
    organized (H, W, 3) cloud in the sensor's frame (NaNs allowed; `params.up` says which way is
    up in it). Organized clouds give each cluster's pixels and image box; unorganized ones give
    image boxes when intrinsics = (fx, fy, cx, cy) are given."""
    params = params or SegmentParams()
    out = Segmentation()
    clock = [time.perf_counter(), time.process_time()]

    def lap(stage: str) -> None:
        t, c = time.perf_counter(), time.process_time()
        out.wall_ms[stage] = out.wall_ms.get(stage, 0.0) + 1e3 * (t - clock[0])
        out.cpu_ms[stage] = out.cpu_ms.get(stage, 0.0) + 1e3 * (c - clock[1])
        clock[:] = [t, c]

    result = _segment(points, params, intrinsics, image_size, out, lap)
    for stage in ('downsample', 'plane', 'clusters'):
        out.wall_ms.setdefault(stage, 0.0)
        out.cpu_ms.setdefault(stage, 0.0)
    return result


def _segment(points: Array, params: SegmentParams,
             intrinsics: tuple[float, float, float, float] | None,
             image_size: tuple[int, int], out: Segmentation, lap: Any) -> Segmentation:
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
    # finite in each coordinate: 0.05 ms for a VGA cloud's quarter, against 1.2 through the sum
    # of the three (which also dropped finite points whose sum overflows)
    finite = np.isfinite(coarse[:, 0]) & np.isfinite(coarse[:, 1]) & np.isfinite(coarse[:, 2])
    pts = coarse[finite].astype(np.float64)
    if len(pts) == 0:
        out.messages.append('cloud has 0 finite points')
        lap('downsample')
        return out
    if params.max_range is not None:
        pts = pts[np.einsum('ij,ij->i', pts, pts) <= params.max_range ** 2]
        if len(pts) == 0:
            out.messages.append(f'no points within max_range {params.max_range} m')
            lap('downsample')
            return out
    down = (o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
            .voxel_down_sample(params.voxel_size))
    # RANSAC runs on a 2x coarser voxel grid (a tenth of the time); each plane is then refitted by
    # least squares to its inliers on the voxel_size grid.
    rest = np.asarray(down.voxel_down_sample(2.0 * params.voxel_size).points)
    lap('downsample')
    if len(down.points) < max(params.min_plane_points, 3):
        out.messages.append(f'no table plane: {len(down.points)} points after downsampling, '
                            f'need at least {params.min_plane_points}')
        return out
    o3d.utility.random.seed(params.seed)
    dpts = np.asarray(down.points)
    up = (None if params.up is None
          else np.asarray(params.up, dtype=np.float64) / np.linalg.norm(params.up))
    min_cos = math.cos(math.radians(params.up_tolerance_deg))
    cands: list[_Candidate] = []
    largest = 0
    for _ in range(params.max_planes):
        if len(rest) < 3:
            break
        plane, inliers = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(rest)).segment_plane(
            params.plane_distance, 3, params.ransac_iterations, params.ransac_probability)
        plane = refine_plane(dpts, np.asarray(plane, dtype=np.float64), params.plane_distance, 1)
        # the next RANSAC runs on what is left off a wider band (depth noise grows as z^2: at 2 m
        # a wall would otherwise come back as a second and third plane)
        keep = np.abs(rest @ plane[:3] + plane[3]) > BAND * params.plane_distance
        keep[np.asarray(inliers, dtype=np.int64)] = False
        rest = rest[keep]
        up_cos = None if up is None else float(plane[:3] @ up)
        if up_cos is None or up_cos >= min_cos:      # a candidate: refined to its fixed point
            plane = refine_plane(dpts, plane, params.plane_distance)
            up_cos = None if up is None else float(plane[:3] @ up)
        on = np.abs(dpts @ plane[:3] + plane[3]) <= params.plane_distance
        n_on = int(on.sum())
        largest = max(largest, n_on)
        if n_on < params.min_plane_points:
            break                                   # the planes left are smaller still
        info: dict[str, Any] = {
            'points': n_on, 'normal': [round(float(v), 4) for v in plane[:3]],
            'height_m': round(float(plane[3]), 4),
            'angle_to_up_deg': (None if up_cos is None
                                else round(math.degrees(math.acos(np.clip(up_cos, -1, 1))), 1))}
        out.planes.append(info)
        if up_cos is not None and up_cos < min_cos:
            info['verdict'] = ('above the sensor or facing away from it' if up_cos <= 0 else
                               f'more than {params.up_tolerance_deg:g} deg from up')
            continue
        surface, region = _region(plane, on, dpts, params)
        info['points'] = n_on = int(surface.sum())
        if n_on < params.min_plane_points:
            info['verdict'] = 'no surface (scattered inliers: a plane through clutter)'
            continue
        cands.append(_Candidate(plane, on, up_cos, info, region))
    if not cands:
        if not out.planes:
            out.messages.append(f'no table plane: best plane has {largest} inliers, '
                                f'need {params.min_plane_points}')
        elif up is None or all('surface' in p.get('verdict', '') for p in out.planes):
            out.messages.append(f'no table plane: none of the {len(out.planes)} plane(s) of '
                                f'{params.min_plane_points}+ points is a surface '
                                f'(scattered inliers)')
        else:
            out.messages.append(f'no table plane: none of the {len(out.planes)} plane(s) of '
                                f'{params.min_plane_points}+ points lies below the sensor within '
                                f'{params.up_tolerance_deg:g} deg of up '
                                f'{tuple(round(float(v), 3) for v in up)} '
                                '(walls, ceiling; is up right?)')
        lap('plane')
        return out
    lap('plane')
    table = _choose(cands, dpts, params)
    assert table is not None and table.objects is not None
    out.plane = plane = table.plane
    objs = table.objects
    out.messages.extend(objs.messages)
    if len(objs.standing) == 0:
        lap('clusters')
        return out
    # Full-resolution points: assign each object point to the nearest downsampled clustered point.
    # NaN rows compare False, so no finiteness pass over the full cloud is needed
    hf = flat @ plane[:3].astype(flat.dtype) + plane[3]
    full_pix = np.flatnonzero((hf > params.min_height) & (hf < params.max_height))
    if params.max_range is not None:    # the range of the band's points only, not the cloud's
        band = flat[full_pix]
        full_pix = full_pix[np.einsum('ij,ij->i', band, band) <= params.max_range ** 2]
    kept = np.isin(objs.labels, objs.standing)
    seeds, seed_labels = dpts[objs.above][kept], objs.labels[kept]
    lo, hi = seeds.min(axis=0) - 2 * params.voxel_size, seeds.max(axis=0) + 2 * params.voxel_size
    full = flat[full_pix].astype(np.float64)
    near = np.all((full >= lo) & (full <= hi), axis=1)     # the objects' box only
    full_pix, full = full_pix[near], full[near]
    dist, nn = cKDTree(seeds).query(full, k=1, distance_upper_bound=2 * params.voxel_size)
    ok = np.isfinite(dist)
    full_labels = np.full(len(full), -1)
    full_labels[ok] = seed_labels[nn[ok]]
    for lab in objs.standing:
        sel = full_labels == lab
        cp = full[sel]
        lo, hi = cp.min(axis=0), cp.max(axis=0)
        patch: tuple[int, int, int, int] | None
        if organized:
            px = full_pix[sel]
            rows, cols = np.divmod(px, image_size[0])
            patch = (int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1)
            out.clusters.append(Cluster(cp, lo, hi, patch, px))
        else:
            patch = project_box(lo, hi, intrinsics, image_size) if intrinsics is not None else None
            out.clusters.append(Cluster(cp, lo, hi, patch))
    lap('clusters')
    return out

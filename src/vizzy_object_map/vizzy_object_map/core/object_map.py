"""The object map: persistent labelled 3D objects fused from geometry and recognitions.

Two kinds of evidence reach the map, each in the map's fixed frame (base_link):

- **Geometry** (:class:`GeometryObservation`): where something is and how large, without a name:
  the objects the tabletop segmentation finds on a support plane (thesis section 4.3.1) and the
  cylinders fitted to them (section 4.3.3), from the RGB-D cloud.
- **Recognitions** (:class:`Recognition`): what is at a pixel of a camera image, without depth:
  the foveated CNN's second pass (section 2.3.2, Fig. 2.5) names the object under its fixation,
  since the classifier learned from views foveated at an object and labelled with the object
  under the fovea. A recognition is tied to the front-most object whose projected box holds its
  pixel (occlusion); with a depth point it can also start an object of its own.

Positions are fused as Gaussians (the linear Kalman update of a static state, with a floor on
the covariance because a view's bias is not white noise); sizes as running means; names as
evidence: each recognition adds its score to its label's tally (a reject label such as
``background`` counts against every name). An object is

- *established* once geometry has seen it ``established_geometry`` times, or once it is
  confirmed; objects that are not established are forgotten ``tentative_timeout_s`` after they
  were last seen, so a one-off (a segmentation artefact, a recognition on the wall) fades;
- *confirmed* (what the map publishes as found) once ``min_recognitions`` recognitions named it
  with a name holding at least ``min_label_share`` of its evidence, and geometry has seen it too
  (or, without geometry, once ``min_recognitions_without_geometry`` recognitions named it).

Objects closer than ``merge_radius_m``, or whose boxes overlap by ``merge_overlap`` of the smaller
one, are merged (a cluster split in one view and whole in the next).
Everything is plain numpy; nothing here knows ROS.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

FloatArray = NDArray[np.float64]

CLUSTER = 'cluster'
CYLINDER = 'cylinder'
RECOGNITION = 'recognition'
GEOMETRY_KINDS = (CLUSTER, CYLINDER)
DEFAULT_REJECT_LABEL = 'background'
#: size given to an object a recognition starts before any geometry has seen it [m]
DEFAULT_OBJECT_SIZE = (0.06, 0.06, 0.06)


@dataclass(frozen=True)
class MapConfig:
    """The map's rules; each is a node parameter of the same name (see parameters.PARAMETERS)."""

    association_radius_m: float = 0.06
    merge_radius_m: float = 0.03
    merge_overlap: float = 0.5
    min_recognition_score: float = 0.3
    min_recognitions: int = 2
    min_recognitions_without_geometry: int = 4
    min_label_share: float = 0.4
    established_geometry: int = 3
    tentative_timeout_s: float = 5.0
    min_sigma_m: float = 0.005
    reject_label: str = DEFAULT_REJECT_LABEL
    projection_margin_px: float = 4.0

    def __post_init__(self) -> None:
        for name in ('association_radius_m', 'merge_radius_m', 'tentative_timeout_s',
                     'min_sigma_m'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be a positive finite number, got {value}')
        if not 0.0 <= self.min_recognition_score <= 1.0:
            raise ValueError(f'min_recognition_score must be in [0, 1], '
                             f'got {self.min_recognition_score}')
        if not 0.0 < self.merge_overlap <= 1.0:
            raise ValueError(f'merge_overlap must be in (0, 1], got {self.merge_overlap}')
        if not 0.0 <= self.min_label_share <= 1.0:
            raise ValueError(f'min_label_share must be in [0, 1], got {self.min_label_share}')
        for name in ('min_recognitions', 'min_recognitions_without_geometry',
                     'established_geometry'):
            if getattr(self, name) < 1:
                raise ValueError(f'{name} must be at least 1, got {getattr(self, name)}')


@dataclass(frozen=True)
class GeometryObservation:
    """Where something is: centre (3,), covariance (3, 3) and extents (3,) [m] in the map frame,
    at stamp [s]; kind CLUSTER or CYLINDER."""

    position: FloatArray
    covariance: FloatArray
    size: FloatArray
    stamp: float
    kind: str = CLUSTER


@dataclass(frozen=True)
class CameraView:
    """A camera at an image's stamp: intrinsics k (3, 3), the optical frame's pose (4, 4) in the
    map frame, and the image size [px]."""

    k: FloatArray
    pose: FloatArray
    width: int
    height: int

    @property
    def origin(self) -> FloatArray:
        return np.asarray(self.pose[:3, 3], dtype=np.float64)

    def to_camera(self, points: FloatArray) -> FloatArray:
        """(N, 3) map-frame points in the optical frame."""
        r, t = self.pose[:3, :3], self.pose[:3, 3]
        return (np.asarray(points, np.float64) - t) @ r

    def project(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(pixels (N, 2), depths (N,)) of map-frame points; pixels of points behind the camera
        are NaN."""
        cam = self.to_camera(np.atleast_2d(points))
        z = cam[:, 2]
        with np.errstate(divide='ignore', invalid='ignore'):
            uv = (cam @ np.asarray(self.k, np.float64).T)[:, :2] / z[:, None]
        uv[z <= 1e-6] = np.nan
        return uv, z


@dataclass(frozen=True)
class Recognition:
    """A name for what lies at pixel (u, v) of a camera image at stamp [s], with the classifier's
    score; point (3,) with covariance (3, 3): the map-frame surface point at that pixel when a
    depth sensor saw it (None otherwise)."""

    u: float
    v: float
    label: str
    score: float
    stamp: float
    point: FloatArray | None = None
    point_covariance: FloatArray | None = None


@dataclass
class MapObject:
    """One object of the map (see the module docstring for established and confirmed)."""

    id: int
    position: FloatArray
    covariance: FloatArray
    size: FloatArray
    first_seen: float
    last_seen: float
    evidence: dict[str, float] = field(default_factory=dict)
    observations: int = 0
    recognitions: int = 0          #: recognitions that named a class (not the reject label)
    geometry: int = 0              #: cluster and cylinder observations
    cylinders: int = 0
    size_weight: float = 0.0

    def ranked_labels(self, reject_label: str) -> list[tuple[str, float]]:
        """(label, share of all evidence) best first, the reject label left out."""
        total = sum(self.evidence.values())
        if total <= 0:
            return []
        named = [(k, v / total) for k, v in self.evidence.items() if k != reject_label]
        return sorted(named, key=lambda kv: (-kv[1], kv[0]))

    def label(self, reject_label: str) -> tuple[str, float]:
        """(best name, its share of the evidence), or ('', 0) while unnamed."""
        ranked = self.ranked_labels(reject_label)
        return ranked[0] if ranked else ('', 0.0)


def _fuse(x: FloatArray, p: FloatArray, z: FloatArray, r: FloatArray,
          min_var: float) -> tuple[FloatArray, FloatArray]:
    """Kalman update of a static state x ~ N(x, p) with a measurement z ~ N(x, r); the result's
    variances are kept at or above min_var (each view's bias is not white noise)."""
    s = p + r
    gain = p @ np.linalg.inv(s)
    x_new = x + gain @ (z - x)
    p_new = (np.eye(3) - gain) @ p
    p_new = 0.5 * (p_new + p_new.T)
    w, v = np.linalg.eigh(p_new)
    p_new = (v * np.maximum(w, min_var)) @ v.T
    return x_new, p_new


def segment_entry(origin: FloatArray, end: FloatArray, lo: FloatArray,
                  hi: FloatArray) -> FloatArray:
    """Where the segment origin -> end enters each axis-aligned box [lo_i, hi_i] (N, 3), as the
    fraction t in [0, 1] of the way (0 when origin is inside); inf where it misses. The slab
    method, vectorized over the boxes."""
    o, d = np.asarray(origin, np.float64), np.asarray(end, np.float64) - np.asarray(origin,
                                                                                   np.float64)
    with np.errstate(divide='ignore', invalid='ignore'):
        a, b = (lo - o) / d, (hi - o) / d
    near, far = np.minimum(a, b), np.maximum(a, b)
    parallel = np.abs(d) < 1e-12
    outside = parallel & ((o < lo) | (o > hi))
    near = np.where(parallel, -np.inf, near)
    far = np.where(parallel, np.inf, far)
    t0 = np.maximum(near.max(axis=1), 0.0)
    t1 = np.minimum(far.min(axis=1), 1.0)
    return np.where((t0 <= t1) & ~outside.any(axis=1), t0, np.inf)


def _box_corners(centres: FloatArray, sizes: FloatArray) -> FloatArray:
    """(N, 8, 3) corners of axis-aligned boxes."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                     np.float64)
    return centres[:, None, :] + 0.5 * sizes[:, None, :] * signs[None]


class ObjectMap:
    """Labelled 3D objects fused over time (module docstring). Not thread-safe: one owner."""

    def __init__(self, config: MapConfig | None = None) -> None:
        self.config = config or MapConfig()
        self._objects: dict[int, MapObject] = {}
        self._next_id = 0
        self.merged = 0                 #: objects merged into another so far
        self.expired = 0                #: objects forgotten so far
        self.unplaced = 0               #: recognitions that matched no object and had no depth

    def __len__(self) -> int:
        return len(self._objects)

    def __iter__(self) -> Iterable[MapObject]:
        return iter(list(self._objects.values()))

    def clear(self) -> None:
        self._objects.clear()

    def reconfigure(self, **changes: object) -> None:
        """New rules (MapConfig fields); the objects are kept."""
        self.config = replace(self.config, **changes)  # type: ignore[arg-type]

    # --- states -----------------------------------------------------------------------------

    def is_confirmed(self, obj: MapObject) -> bool:
        cfg = self.config
        label, share = obj.label(cfg.reject_label)
        if not label or share < cfg.min_label_share:
            return False
        needed = cfg.min_recognitions if obj.geometry else cfg.min_recognitions_without_geometry
        return obj.recognitions >= needed

    def is_established(self, obj: MapObject) -> bool:
        return obj.geometry >= self.config.established_geometry or self.is_confirmed(obj)

    def objects(self, *, confirmed_only: bool = False) -> list[MapObject]:
        """The objects (by id), or only the confirmed ones."""
        out = [o for _, o in sorted(self._objects.items())]
        return [o for o in out if self.is_confirmed(o)] if confirmed_only else out

    def get(self, object_id: int) -> MapObject | None:
        return self._objects.get(object_id)

    # --- geometry ---------------------------------------------------------------------------

    def _new(self, position: FloatArray, covariance: FloatArray, size: FloatArray,
             stamp: float) -> MapObject:
        obj = MapObject(self._next_id, np.array(position, np.float64),
                        np.array(covariance, np.float64), np.array(size, np.float64),
                        stamp, stamp)
        self._objects[obj.id] = obj
        self._next_id += 1
        return obj

    def add_geometry(self, observations: Sequence[GeometryObservation]) -> list[int]:
        """Fuse one sensor frame's geometry (each object seen at most once per call: a one to
        one assignment by distance, gated at association_radius_m); unmatched observations
        start objects. Returns the object id each observation went to."""
        obs = [o for o in observations if np.isfinite(o.position).all()]
        objects = self.objects()
        ids: list[int] = [-1] * len(obs)
        if obs and objects:
            z = np.array([o.position for o in obs])
            x = np.array([o.position for o in objects])
            d = np.linalg.norm(z[:, None, :] - x[None, :, :], axis=2)
            gate = self.config.association_radius_m
            cost = np.where(d <= gate, d, 1e6)
            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows, cols, strict=True):
                if d[r, c] <= gate:
                    ids[r] = objects[c].id
        for i, o in enumerate(obs):
            obj = self._objects[ids[i]] if ids[i] >= 0 else self._new(
                o.position, o.covariance, o.size, o.stamp)
            if ids[i] >= 0:
                obj.position, obj.covariance = _fuse(obj.position, obj.covariance, o.position,
                                                     o.covariance, self.config.min_sigma_m ** 2)
            self._update_size(obj, o)
            obj.geometry += 1
            obj.cylinders += o.kind == CYLINDER
            obj.observations += 1
            obj.last_seen = max(obj.last_seen, o.stamp)
            ids[i] = obj.id
        self._merge_close()
        return ids

    @staticmethod
    def _update_size(obj: MapObject, o: GeometryObservation) -> None:
        # cylinders measure the whole object (radius and height); a cluster only what is seen
        weight = 3.0 if o.kind == CYLINDER else 1.0
        size = np.asarray(o.size, np.float64)
        if obj.size_weight == 0.0:
            obj.size = size.copy()
        else:
            obj.size = (obj.size * obj.size_weight + size * weight) / (obj.size_weight + weight)
        obj.size_weight += weight

    # --- recognitions -----------------------------------------------------------------------

    def first_on_ray(self, origin: FloatArray, point: FloatArray, beyond_m: float = 0.05,
                     shrink: float = 0.8) -> MapObject | None:
        """The first object the ray from origin (a camera) through point (3D) enters, up to
        beyond_m past the point: what the camera sees there. Boxes are shrunk across (x, y) to
        `shrink` of their extent, so a ray grazing a rotated box's loose corner does not count;
        their height (z) is kept: objects stand on a table and a bottle's neck is in sight."""
        objects = self.objects()
        if not objects:
            return None
        o, p = np.asarray(origin, np.float64), np.asarray(point, np.float64)
        length = float(np.linalg.norm(p - o))
        if length < 1e-9:
            return None
        end = o + (p - o) * (1.0 + beyond_m / length)
        centres = np.array([x.position for x in objects])
        half = 0.5 * np.array([x.size for x in objects]) * np.array([shrink, shrink, 1.0])
        t = segment_entry(o, end, centres - half, centres + half)
        i = int(np.argmin(t))
        return objects[i] if np.isfinite(t[i]) else None

    def objects_at_pixel(self, view: CameraView, u: float, v: float) -> list[int]:
        """Ids of the objects whose projected box holds pixel (u, v) (within
        projection_margin_px), front-most first."""
        objects = self.objects()
        if not objects:
            return []
        centres = np.array([o.position for o in objects])
        sizes = np.array([o.size for o in objects])
        corners = _box_corners(centres, sizes).reshape(-1, 3)
        uv, z = view.project(corners)
        uv = uv.reshape(len(objects), 8, 2)
        in_front = (z.reshape(len(objects), 8) > 0).all(axis=1)
        m = self.config.projection_margin_px
        with np.errstate(invalid='ignore'):
            lo, hi = np.nanmin(uv, axis=1) - m, np.nanmax(uv, axis=1) + m
            inside = (in_front & (lo[:, 0] <= u) & (u <= hi[:, 0])
                      & (lo[:, 1] <= v) & (v <= hi[:, 1]))
        _, depth = view.project(centres)
        order = [i for i in np.argsort(depth) if inside[i]]
        return [objects[i].id for i in order]

    def add_recognitions(self, recognitions: Sequence[Recognition],
                         view: CameraView) -> list[int | None]:
        """Add the names of one image's recognitions (those scoring at least
        min_recognition_score). Each goes to the front-most object under its pixel (or, with a
        depth point, to the object nearest that point within association_radius_m); a named
        recognition that finds no object but has a point starts one. Returns the object id of
        each recognition, or None where it went nowhere (too weak, no object and no depth, or a
        reject with no object under it)."""
        cfg = self.config
        out: list[int | None] = []
        for rec in recognitions:
            if not (rec.score >= cfg.min_recognition_score and math.isfinite(rec.u)
                    and math.isfinite(rec.v)):
                out.append(None)
                continue
            target = self._recognition_target(rec, view)
            if target is None:
                if rec.label == cfg.reject_label or rec.point is None:
                    self.unplaced += rec.label != cfg.reject_label
                    out.append(None)
                    continue
                cov = (rec.point_covariance if rec.point_covariance is not None
                       else np.eye(3) * cfg.association_radius_m ** 2)
                target = self._new(rec.point, cov, np.array(DEFAULT_OBJECT_SIZE), rec.stamp)
                target.size_weight = 0.0
            elif rec.point is not None and rec.point_covariance is not None and not target.geometry:
                target.position, target.covariance = _fuse(
                    target.position, target.covariance, rec.point, rec.point_covariance,
                    cfg.min_sigma_m ** 2)
            target.evidence[rec.label] = target.evidence.get(rec.label, 0.0) + float(rec.score)
            target.observations += 1
            target.recognitions += rec.label != cfg.reject_label
            target.last_seen = max(target.last_seen, rec.stamp)
            out.append(target.id)
        self._merge_close()
        return out

    def _recognition_target(self, rec: Recognition, view: CameraView) -> MapObject | None:
        """The object a recognition names. Without a point: the front-most object whose box holds
        its pixel. With one (the 3D point the pixel shows: the eyes' fixation point, or a depth
        sensor's surface point): the first object the camera's ray through the point enters (an
        object in front of the fixated one is what the image shows there: occlusion), else the
        object whose extent comes nearest to the point, within association_radius_m; None if
        there is none (the caller may start an object at the point)."""
        if rec.point is None:
            under = self.objects_at_pixel(view, rec.u, rec.v)
            return self._objects[under[0]] if under else None
        point = np.asarray(rec.point, np.float64)
        hit = self.first_on_ray(view.origin, point)
        if hit is not None:
            return hit
        best, best_d = None, math.inf
        for obj in self._objects.values():
            # the point lies within the object's half extent of its centre
            d = float(np.linalg.norm(obj.position - point)) - 0.5 * float(np.max(obj.size))
            if d <= self.config.association_radius_m and d < best_d:
                best, best_d = obj, d
        return best

    # --- upkeep -----------------------------------------------------------------------------

    def _merge_close(self) -> None:
        """Merge pairs of objects whose centres are closer than merge_radius_m, or whose boxes
        overlap by at least merge_overlap of the smaller box (a large object segmented in two
        pieces in one view), the closest pair first, until none is left."""
        radius, overlap = self.config.merge_radius_m, self.config.merge_overlap
        while True:
            objects = self.objects()
            if len(objects) < 2:
                return
            x = np.array([o.position for o in objects])
            d = np.linalg.norm(x[:, None] - x[None], axis=2)
            np.fill_diagonal(d, np.inf)
            sizes = np.array([o.size for o in objects])
            lo, hi = x - 0.5 * sizes, x + 0.5 * sizes
            inter = np.prod(np.clip(np.minimum(hi[:, None], hi[None]) - np.maximum(lo[:, None],
                                                                                    lo[None]),
                                    0.0, None), axis=2)
            vol = np.prod(sizes, axis=1)
            share = inter / np.maximum(np.minimum(vol[:, None], vol[None]), 1e-12)
            np.fill_diagonal(share, 0.0)
            candidates = (d <= radius) | (share >= overlap)
            if not candidates.any():
                return
            i, j = np.unravel_index(int(np.argmin(np.where(candidates, d, np.inf))), d.shape)
            keep, gone = sorted((objects[i], objects[j]), key=lambda o: o.id)
            keep.position, keep.covariance = _fuse(keep.position, keep.covariance, gone.position,
                                                   gone.covariance, self.config.min_sigma_m ** 2)
            total = keep.size_weight + gone.size_weight
            if total > 0:
                keep.size = (keep.size * keep.size_weight + gone.size * gone.size_weight) / total
            keep.size_weight = total
            for label, value in gone.evidence.items():
                keep.evidence[label] = keep.evidence.get(label, 0.0) + value
            keep.observations += gone.observations
            keep.recognitions += gone.recognitions
            keep.geometry += gone.geometry
            keep.cylinders += gone.cylinders
            keep.first_seen = min(keep.first_seen, gone.first_seen)
            keep.last_seen = max(keep.last_seen, gone.last_seen)
            del self._objects[gone.id]
            self.merged += 1

    def expire(self, now: float) -> list[int]:
        """Forget the objects that are not established and were last seen more than
        tentative_timeout_s before now; returns their ids."""
        gone = [o.id for o in self._objects.values()
                if not self.is_established(o)
                and now - o.last_seen > self.config.tentative_timeout_s]
        for oid in gone:
            del self._objects[oid]
        self.expired += len(gone)
        return gone

    def unrecognised(self) -> list[MapObject]:
        """Established objects that are not confirmed yet: where a look would add most."""
        return [o for o in self.objects() if self.is_established(o) and not self.is_confirmed(o)]


__all__ = ['CLUSTER', 'CYLINDER', 'CameraView', 'DEFAULT_OBJECT_SIZE', 'DEFAULT_REJECT_LABEL',
           'GEOMETRY_KINDS', 'GeometryObservation', 'MapConfig', 'MapObject', 'ObjectMap',
           'RECOGNITION', 'Recognition']

"""One page that tells the story of the demo's head: it looks for the objects on the table and
names them. `demo_output/summary.png`.

    .venv/bin/python -m vizzy_runtime.demo_summary bags/demo_<time> [-o demo_output/summary.png]

`make demo` calls summarize_bag() on the bag it recorded. It reads the bag once (BagReader, in
log-time order; then one more message: the frame panel 1 chose), decodes only what it draws, and
draws three rows of panels. The top row is the story (what the head named, the map it built, how
recall grew), the rows below how it came about; the page's title says how many of the objects on
the table the map named right by the end.

1. The left camera (/vizzy/left/image_raw) at the frame whose foveation detections
   (/foveation/detections) were the most confidently correct. Each detections message is checked
   against the simulator's ground truth (/sim/ground_truth/objects, ns 'objects'; not the
   supports, table and stands): the true objects are projected into the left camera at the
   message's stamp (camera pose from the recorded /tf, intrinsics from /vizzy/left/camera_info;
   an object's projected box bounds the projection of its marker's shape: a cylinder's rims, a
   sphere, a box's corners; objects not wholly in front of the camera are left out). A detection
   is *correct* when the true object whose projected box holds the detection's fixation
   (fixation_u, fixation_v; the nearest to the camera if several boxes hold it) is of the
   detection's label, an object's class being its name's prefix before '_' (can_lying is a can).
   The message with the largest summed score of correct detections wins (ties: the later).
   Without ground truth, or when no detection was ever correct, the frame is that of the last
   detections (their final pass), as it was before, and without detections the last frame; the
   title says which rule chose the frame and why. The message's detections (the best five) are
   boxes, ranked, with a + at their fixation: green when correct, magenta when wrong (naming the
   true object under the fixation), cyan when unchecked (no ground truth); the true objects'
   projected boxes are dashed white with their names, and every fixation point of /gaze/state
   over the run is projected into the frame, coloured by when.
2. The object map at the end: a top view in base_link (x forward, y left) of the last
   /objects/map against the ground truth. Confirmed objects are filled footprints (their
   axis-aligned size) with label and label share, green when paired with a true object of their
   class within 5 cm (a line to it), red otherwise (a dotted line to the nearest true object);
   established but unconfirmed objects are grey dashed outlines; the true objects are outlines
   with their names, the table a grey area. The title gives that map's recall, precision, false
   and misnamed objects at 5 cm (vizzy_vision.object_scoring.score, false objects at 10 cm).
3. Recall and precision over time [sim s]: at each /objects/map, its confirmed objects against
   the true objects with vizzy_vision.object_scoring.score: recall and precision at 5 cm, recall
   at 10 cm dashed (precision is not drawn while nothing is confirmed); on the right axis the
   number of confirmed and of established unconfirmed objects. Each value holds until the next
   map, the last one until the end of the run.
4. The foveated image (/foveation/image) of panel 1's frame (else the one nearest in time),
   else the last one.
5. The cylinders found (/cylinders: each one's footprint, an upright one a circle of its radius
   at its axis) against the ground truth, in base_link.
6. A top view of the stereo points (/stereo/points, every cloud) and of the Sensory Ego-Sphere
   cells (/ses/cells, the last non-empty message, coloured by their information field), in
   base_link (transformed with /tf at each message's stamp).
7. The gaze over time (/gaze/state): version, vergence and tilt, the saccades and who held the
   gaze.
8. The multiple-object tracks (/mot/tracks): each track id's box centre in image coordinates
   over time, and its last box. Drawn only when there is a track; otherwise the gaze spans the
   last row and the page's title says why the tracks are not drawn (the missing topic).

Every panel is its own subfigure (constrained layout), so a long title or legend takes room
from its own panel only; legends and notes sit beside or below the axes, never over an image or
a plot. A panel whose topics are missing or empty says so in words ("no /cylinders in the bag")
instead of a plot. summarize_bag() returns every panel with whether it had data, its note and its
facts: the numbers drawn (panel 1: the rule that chose the frame, its stamp, correct and wrong
detections, their summed score; 2: the last map's counts, pairs and score; 3: the curves; 4: the
foveated image's stamp and whether it is panel 1's frame's). Time
axes are header stamps (sim time in the simulator), in seconds from the earliest stamp of the
messages drawn.
"""

from __future__ import annotations

import argparse
import bisect
import math
import sys
from collections import OrderedDict, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vizzy_vision.frames import matrices_from_transforms, quaternions_to_matrices
from vizzy_vision.object_scoring import Labelled, score

from . import msgs
from .bag import BagReader
from .convert import image_to_numpy, pointcloud2_to_array
from .tf import TransformBuffer

FIGSIZE = (20.0, 17.0)   # inches
DPI = 100                # -> 2000 x 1700 px
TOP_FRAME = 'base_link'  # the top views' frame: the waist, which never moves (x forward, y left)

LEFT_IMAGE = '/vizzy/left/image_raw'
LEFT_INFO = '/vizzy/left/camera_info'
GAZE = '/gaze/state'
DETECTIONS = '/foveation/detections'
FOVEATED = '/foveation/image'
POINTS = '/stereo/points'
CELLS = '/ses/cells'
CYLINDERS = '/cylinders'
GROUND_TRUTH = '/sim/ground_truth/objects'
TRACKS = '/mot/tracks'
OBJECT_MAP = '/objects/map'
TF, TF_STATIC = '/tf', '/tf_static'
TOPICS = (LEFT_IMAGE, LEFT_INFO, GAZE, DETECTIONS, FOVEATED, POINTS, CELLS, CYLINDERS,
          GROUND_TRUTH, TRACKS, OBJECT_MAP, TF, TF_STATIC)

RECENT_IMAGES = 48            # raw left frames kept to find the one the detections belong to
POINTS_PER_CLOUD = 4000       # stereo points kept per cloud (evenly subsampled)
MARKER_CUBE, MARKER_SPHERE, MARKER_CYLINDER = 1, 2, 3
MATCH_MARGIN_M = 0.03         # a found cylinder matches a true one within its radius + this (xy)
SUPPORTS = ('table', 'stand')  # true objects' classes that hold the others: not to be found
SCORE_RADIUS_M = 0.05         # a map object names a true object within this (object_scoring)
WIDE_RADIUS_M = 0.10          # the looser radius of the dashed recall curve
FALSE_RADIUS_M = 0.10         # a map object with no true object this near is a false object
MIN_DEPTH_M = 0.05            # a true object is projected when all its box is this far in front
SHOWN_DETECTIONS = 5          # panel 1 draws at most this many detections, best first
CORRECT, WRONG, UNCHECKED = 'lime', 'magenta', 'cyan'
TITLE_CHARS_PER_IN = 11.5     # panel titles are wrapped at this many characters per inch
ROW_HEIGHTS = (7.6, 5.6, 3.8)  # the page's rows [relative]
LEGEND_CHARS_PER_IN = 16      # 8 pt legend text, characters per inch
BELOW_IN = 0.5                # legends under a panel: this far under its axes [in]


@dataclass
class Panel:
    """One panel of the page: what it shows, whether it had data, and what it says about it.
    facts: the numbers it drew (panel 1: the rule that chose its frame; 2 and 3: the scores;
    4: which foveated image)."""
    key: str
    title: str
    topics: tuple[str, ...]
    has_data: bool = False
    note: str = ''
    facts: dict[str, Any] = field(default_factory=dict)


@dataclass
class _Cloud:
    stamp: int
    frame: str
    xyz: np.ndarray
    value: np.ndarray | None = None
    rgb: np.ndarray | None = None


@dataclass
class _MapObject:
    """One object of an /objects/map message (only what the page draws)."""
    id: str
    label: str
    share: float
    confirmed: bool
    established: bool
    position: np.ndarray     # (3,) in the message's frame
    size: np.ndarray         # (3,) axis-aligned extents in the message's frame


@dataclass
class _Truth:
    """A ground-truth object placed in the top frame."""
    name: str
    kind: str                # its class: the name's prefix before '_' (can_lying: can)
    shape: str               # cylinder, sphere or box
    outline: np.ndarray      # (N, 2) top-view footprint
    centre: np.ndarray       # (3,)
    radius: float            # half its first extent (a cylinder's radius)
    shell: np.ndarray        # (M, 3) points bounding its shape (_marker_footprint)

    @property
    def support(self) -> bool:
        return self.kind in SUPPORTS


@dataclass
class _Choice:
    """Panel 1's frame and what is drawn on it."""
    rule: str                                  # 'most confident correct', 'last detections',
    #                                            'last frame' or 'none'
    why: str = ''                              # the rule in words, for the title
    frame: tuple[int, str, bytes] | None = None
    detections: list[tuple[Any, bool | None, str]] = field(default_factory=list)
    #                                            (detection, correct, true object under it)
    boxes: list[tuple[str, np.ndarray]] = field(default_factory=list)   # (name, u0 v0 u1 v1)
    pass_fixation: tuple[float, float] | None = None
    notes: list[str] = field(default_factory=list)
    facts: dict[str, Any] = field(default_factory=dict)


@dataclass
class _Data:
    """What the page needs, gathered in one pass over the bag."""
    bag_dir: Path | None = None
    counts: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    errors: list[str] = field(default_factory=list)
    tf: _TfHistory = field(default_factory=lambda: _TfHistory())
    recent_images: OrderedDict[int, tuple[str, bytes]] = field(default_factory=OrderedDict)
    image_log: dict[int, int] = field(default_factory=dict)   # left frame stamp -> log time
    last_image: tuple[int, str, bytes] | None = None
    det_frame: tuple[int, str, bytes] | None = None   # the frame of det_arrays
    det_stamp: int | None = None
    det_arrays: list[Any] = field(default_factory=list)
    det_unmatched: int = 0                             # detections whose frame was not found
    det_msgs: list[tuple[int, str, Any]] = field(default_factory=list)  # every one with detections
    K: np.ndarray | None = None
    image_size: tuple[int, int] | None = None          # (width, height) from camera_info
    # (stamp, frame, x, y, z, saccade, source, ver, verg, tilt)
    gaze: list[tuple] = field(default_factory=list)
    foveated: tuple[int, str, bytes] | None = None
    foveated_log: dict[int, int] = field(default_factory=dict)  # its stamp -> log time
    clouds: list[_Cloud] = field(default_factory=list)
    cells: _Cloud | None = None
    cylinders: list[tuple[int, str, list[tuple]]] = field(default_factory=list)
    markers: list[Any] | None = None
    maps: list[tuple[int, str, list[_MapObject]]] = field(default_factory=list)
    tracks: dict[int, list[tuple]] = field(default_factory=lambda: defaultdict(list))
    first_stamp: int | None = None
    last_stamp: int | None = None


class _TfHistory:
    """/tf and /tf_static from a bag, looked up at a stamp (each frame's latest transform at or
    before it; its first one for earlier stamps). No interpolation: the simulator publishes /tf
    at each image's stamp, so perception outputs stamped like an image find exact transforms."""

    def __init__(self) -> None:
        self.static: dict[str, tuple[str, np.ndarray]] = {}
        self.dynamic: dict[str, tuple[str, list[int], list[np.ndarray]]] = {}

    def add(self, transforms: list[Any], static: bool) -> None:
        if not transforms:
            return
        trans = np.array([(t.transform.translation.x, t.transform.translation.y,
                           t.transform.translation.z) for t in transforms])
        quats = np.array([(t.transform.rotation.x, t.transform.rotation.y,
                           t.transform.rotation.z, t.transform.rotation.w) for t in transforms])
        mats = matrices_from_transforms(trans, quats)
        for t, m in zip(transforms, mats, strict=True):
            parent, child = t.header.frame_id.lstrip('/'), t.child_frame_id.lstrip('/')
            if static:
                self.static[child] = (parent, m)
                continue
            stamp = _ns(t.header.stamp)
            _, stamps, ms = self.dynamic.setdefault(child, (parent, [], []))
            i = bisect.bisect_right(stamps, stamp)
            stamps.insert(i, stamp)
            ms.insert(i, m)

    def at(self, stamp: int) -> TransformBuffer:
        buf = TransformBuffer()
        for child, (parent, m) in self.static.items():
            buf.set_transform(parent, child, m)
        for child, (parent, stamps, ms) in self.dynamic.items():
            i = max(bisect.bisect_right(stamps, stamp) - 1, 0)
            buf.set_transform(parent, child, ms[i])
        return buf

    def transform(self, points: np.ndarray, target: str, source: str, stamp: int) -> np.ndarray:
        """(N, 3) points in source at stamp -> target; LookupError when not connected."""
        return self.at(stamp).transform_points(target, source, points).reshape(-1, 3)


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _read(bag_dir: Path) -> _Data:
    d = _Data(bag_dir=bag_dir)
    reader = BagReader(bag_dir)
    for topic, typename, data, log_ns, _pub_ns in reader.messages(topics=TOPICS):
        d.counts[topic] += 1
        try:
            if topic == LEFT_IMAGE:
                # Images are decoded only for the frames drawn; keep the recent raw ones.
                msg_stamp = _image_stamp(data, typename)
                _first(d, msg_stamp)
                raw = bytes(data)
                d.last_image = (msg_stamp, typename, raw)
                d.recent_images[msg_stamp] = (typename, raw)
                d.image_log.setdefault(msg_stamp, log_ns)
                while len(d.recent_images) > RECENT_IMAGES:
                    d.recent_images.popitem(last=False)
                continue
            if topic == FOVEATED:
                fov_stamp = _image_stamp(data, typename)
                d.foveated = (fov_stamp, typename, bytes(data))
                d.foveated_log.setdefault(fov_stamp, log_ns)
                continue
            msg = msgs.deserialize(data, typename)
            _take(d, topic, msg)
        except Exception as err:  # noqa: BLE001 - one bad message must not lose the page
            d.errors.append(f'{topic}: {type(err).__name__}: {err}')
    return d


def _fetch_frame(d: _Data, stamp: int) -> tuple[int, str, bytes] | None:
    """The left frame of this stamp: from the recent ones, else read again from the bag (only
    the log time it was recorded at)."""
    if stamp in d.recent_images:
        return (stamp, *d.recent_images[stamp])
    log_ns = d.image_log.get(stamp)
    if log_ns is None or d.bag_dir is None:
        return None
    for _topic, typename, data, _log, _pub in BagReader(d.bag_dir).messages(
            topics=(LEFT_IMAGE,), start_ns=log_ns, stop_ns=log_ns + 1):
        if _image_stamp(data, typename) == stamp:
            return stamp, typename, bytes(data)
    return None


def _fetch_foveated(d: _Data, stamp: int) -> tuple[int, str, bytes] | None:
    """The foveated image of the left frame stamped stamp (else the nearest one in time: the
    frame itself may have been suppressed in a saccade, or come before the recording caught
    foveation's output), read again from the bag; None when there is none."""
    if not d.foveated_log or d.bag_dir is None:
        return None
    best = min(d.foveated_log, key=lambda s: (abs(s - stamp), s > stamp))
    log_ns = d.foveated_log[best]
    for _topic, typename, data, _log, _pub in BagReader(d.bag_dir).messages(
            topics=(FOVEATED,), start_ns=log_ns, stop_ns=log_ns + 1):
        if _image_stamp(data, typename) == best:
            return best, typename, bytes(data)
    return None


def _first(d: _Data, stamp: int) -> None:
    if stamp > 0 and (d.first_stamp is None or stamp < d.first_stamp):
        d.first_stamp = stamp
    if d.last_stamp is None or stamp > d.last_stamp:
        d.last_stamp = stamp


def _image_stamp(data: Any, typename: str) -> int:
    # Decoding the whole Image just for its stamp costs a copy of the pixels; it is still cheap
    # next to reading the bag, and it does not depend on CDR layout details.
    return _ns(msgs.deserialize(data, typename).header.stamp)


def _take(d: _Data, topic: str, msg: Any) -> None:
    if topic in (TF, TF_STATIC):
        d.tf.add(list(msg.transforms), static=topic == TF_STATIC)
        return
    stamp = _ns(msg.header.stamp) if hasattr(msg, 'header') else 0
    frame = msg.header.frame_id.lstrip('/') if hasattr(msg, 'header') else ''
    _first(d, stamp)
    if topic == LEFT_INFO:
        k = np.asarray(msg.k, dtype=np.float64).reshape(3, 3)
        if np.isfinite(k).all() and k[0, 0] > 0 and k[1, 1] > 0:
            d.K = k
            d.image_size = (int(msg.width), int(msg.height))
    elif topic == GAZE:
        p = msg.fixation_point
        d.gaze.append((stamp, frame, p.x, p.y, p.z, bool(msg.in_saccade),
                       msg.active_source or 'idle',
                       msg.version, msg.vergence, msg.tilt))
    elif topic == DETECTIONS:
        # Keep the newest detections whose frame is still among the recent images (one array per
        # pass, all with the frame's stamp), and every message with a detection.
        if len(msg.detections):
            d.det_msgs.append((stamp, frame, msg))
            if stamp == d.det_stamp:
                d.det_arrays.append(msg)
            elif stamp in d.recent_images:
                d.det_stamp, d.det_arrays = stamp, [msg]
                d.det_frame = (stamp, *d.recent_images[stamp])
            else:
                d.det_unmatched += 1
    elif topic in (POINTS, CELLS):
        arr = pointcloud2_to_array(msg).reshape(-1)
        names = arr.dtype.names or ()
        if not {'x', 'y', 'z'} <= set(names):
            raise ValueError('no x, y, z fields')
        xyz = np.stack([arr['x'], arr['y'], arr['z']], axis=1).astype(np.float64)
        ok = np.isfinite(xyz).all(axis=1)
        value = arr['information'].astype(np.float64) if 'information' in names else None
        rgb = None
        if 'rgb' in names and arr.dtype['rgb'].itemsize == 4:
            packed = np.ascontiguousarray(arr['rgb']).view(np.uint32)
            rgb = np.stack([(packed >> 16) & 255, (packed >> 8) & 255, packed & 255],
                           axis=1) / 255.0
        idx = np.flatnonzero(ok)
        if topic == POINTS and idx.size > POINTS_PER_CLOUD:
            idx = idx[np.linspace(0, idx.size - 1, POINTS_PER_CLOUD).astype(int)]
        cloud = _Cloud(stamp, frame, xyz[idx], None if value is None else value[idx],
                       None if rgb is None else rgb[idx])
        if topic == POINTS:
            if idx.size:
                d.clouds.append(cloud)
        elif idx.size:
            d.cells = cloud
    elif topic == CYLINDERS:
        d.cylinders.append((stamp, frame, [
            (c.label, np.array([c.center.x, c.center.y, c.center.z]),
             np.array([c.axis.x, c.axis.y, c.axis.z]), float(c.radius), float(c.height),
             float(c.confidence)) for c in msg.cylinders]))
    elif topic == GROUND_TRUTH:
        objects = [m for m in msg.markers if m.ns == 'objects' and m.action == 0]
        if objects:
            d.markers = objects
    elif topic == OBJECT_MAP:
        d.maps.append((stamp, frame or TOP_FRAME, [
            _MapObject(str(o.id), str(o.label), float(o.label_share), bool(o.confirmed),
                       bool(o.established),
                       np.array([o.position.x, o.position.y, o.position.z], np.float64),
                       np.array([o.size.x, o.size.y, o.size.z], np.float64))
            for o in msg.objects]))
    elif topic == TRACKS:
        for t in msg.tracks:
            d.tracks[int(t.id)].append((stamp, t.center_u, t.center_v, t.width, t.height, t.label))


# --- geometry --------------------------------------------------------------------------------

def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of (N, 2) points, counter-clockwise."""
    pts = sorted(set(map(tuple, np.round(points, 9))))
    if len(pts) <= 2:
        return np.array(pts)

    def half(seq: list) -> list:
        out: list = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out
    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def cylinder_footprint(center: np.ndarray, axis: np.ndarray, radius: float, height: float,
                       n: int = 48) -> np.ndarray:
    """Top-view (x, y) outline of a solid cylinder: the hull of its two end circles. An upright
    cylinder gives a circle of its radius around its axis; a lying one a rectangle-like shape."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a) if np.linalg.norm(a) > 1e-9 else np.array([0.0, 0.0, 1.0])
    u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = radius * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v)
    ends = [np.asarray(center) + s * 0.5 * height * a for s in (-1, 1)]
    pts = np.vstack([e + ring for e in ends])
    return _hull(pts[:, :2])


def _marker_footprint(m: Any, to_top: np.ndarray) -> tuple[str, np.ndarray, np.ndarray,
                                                          np.ndarray]:
    """(shape, outline (N, 2), centre (3,), shell (M, 3)) of a ground-truth marker in the top
    frame; the shell's points bound the shape (a cylinder's two rims, points on a sphere, a box's
    corners): their projection's box is the shape's."""
    rot = quaternions_to_matrices(np.array([[m.pose.orientation.x, m.pose.orientation.y,
                                             m.pose.orientation.z, m.pose.orientation.w]]))[0]
    R = to_top[:3, :3] @ rot
    c = to_top[:3, :3] @ np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z]) \
        + to_top[:3, 3]
    sx, sy, sz = m.scale.x, m.scale.y, m.scale.z
    ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], 1)
    if m.type == MARKER_CYLINDER:
        rims = np.vstack([ring * [sx / 2, sy / 2, 0] + [0, 0, k * sz / 2] for k in (-1, 1)])
        return 'cylinder', cylinder_footprint(c, R[:, 2], sx / 2, sz), c, rims @ R.T + c
    if m.type == MARKER_SPHERE:
        # Points on the sphere: rings at 15 degree steps of latitude.
        shell = np.vstack([np.cos(lat) * ring + [0, 0, np.sin(lat)]
                           for lat in np.radians(np.arange(-90, 91, 15))]) * sx / 2
        return ('sphere', c[:2] + sx / 2 * np.stack([np.cos(ang), np.sin(ang)], 1), c,
                shell @ R.T + c)
    corners = np.array([[i * sx, j * sy, k * sz] for i in (-.5, .5) for j in (-.5, .5)
                        for k in (-.5, .5)]) @ R.T + c
    return 'box', _hull(corners[:, :2]), c, corners


def object_class(name: str) -> str:
    """A ground-truth object's class from its name: the prefix before '_' (can_lying: can)."""
    return name.split('_', 1)[0]


def _place_truth(d: _Data, top: str) -> tuple[list[_Truth], list[str]]:
    """The ground-truth objects (supports included) placed in the top frame, and notes."""
    truth: list[_Truth] = []
    notes: list[str] = []
    if not d.markers:
        return [], [f'no scene ground truth in the bag ({GROUND_TRUTH})']
    for m in d.markers:
        try:
            frame = m.header.frame_id.lstrip('/') or top
            to_top = (np.eye(4) if frame == top
                      else d.tf.at(_ns(m.header.stamp)).lookup_transform(top, frame))
            shape, poly, c, shell = _marker_footprint(m, to_top)
        except (LookupError, ValueError) as err:
            notes.append(f'ground truth not placed: {err}'[:100])
            break
        name = m.text or f'{shape}_{m.id}'
        truth.append(_Truth(name, object_class(name), shape, poly, c, m.scale.x / 2, shell))
    return truth, notes


def _project(d: _Data, truths: list[_Truth], stamp: int,
             cam: str) -> list[tuple[_Truth, np.ndarray, float]]:
    """Each true object wholly in front of the camera at stamp as (truth, its projected box
    (u0, v0, u1, v1) [px], distance of its centre from the camera [m]); LookupError without tf."""
    assert d.K is not None
    T = d.tf.at(stamp).lookup_transform(cam, TOP_FRAME)
    out = []
    for t in truths:
        pc = t.shell @ T[:3, :3].T + T[:3, 3]
        if (pc[:, 2] <= MIN_DEPTH_M).any():
            continue
        uvw = pc @ d.K.T
        uv = uvw[:, :2] / uvw[:, 2:3]
        box = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
        out.append((t, box, float(np.linalg.norm(T[:3, :3] @ t.centre + T[:3, 3]))))
    return out


def _judge(projected: list[tuple[_Truth, np.ndarray, float]],
           detections: list[Any]) -> list[tuple[bool, str]]:
    """(correct, the true object under its fixation or '') of each detection: the nearest true
    object whose projected box holds the detection's fixation is of the detection's label."""
    out = []
    for det in detections:
        u, v = float(det.fixation_u), float(det.fixation_v)
        under = [(dist, t) for t, (u0, v0, u1, v1), dist in projected
                 if u0 <= u <= u1 and v0 <= v <= v1]
        if not under:
            out.append((False, ''))
            continue
        t = min(under, key=lambda x: x[0])[1]
        out.append((t.kind == det.label, t.name))
    return out


def _choose_frame(d: _Data) -> _Choice:
    """Panel 1's frame (module docstring, panel 1)."""
    truth, truth_notes = _place_truth(d, TOP_FRAME)
    objects = [t for t in truth if not t.support]
    choice = _Choice('none')
    candidates = [(stamp, frame or _left_frame_id(d), msg) for stamp, frame, msg in d.det_msgs
                  if stamp in d.image_log]
    why = ''
    if not d.det_msgs:
        why = 'no detections'
    elif not objects:
        why = 'no ground truth to check the detections'
        choice.notes.extend(n for n in truth_notes if 'not placed' in n)
    elif d.K is None:
        why = f'no usable {LEFT_INFO} to project the ground truth'
    elif not candidates:
        why = 'no detections message\'s frame in the bag'
    else:
        best: tuple | None = None
        for stamp, cam, msg in candidates:
            try:
                projected = _project(d, objects, stamp, cam)
            except LookupError as err:
                choice.notes.append(f'ground truth not projected: {err}'[:100])
                why = 'the ground truth could not be projected'
                best = None
                break
            verdicts = _judge(projected, list(msg.detections))
            total = sum(det.score for det, (ok, _) in zip(msg.detections, verdicts, strict=True)
                        if ok)
            if total > 0 and (best is None or total >= best[0]):
                best = (total, stamp, msg, projected, verdicts)
        if best is not None:
            total, stamp, msg, projected, verdicts = best
            frame = _fetch_frame(d, stamp)
            if frame is not None:
                dets = list(zip(msg.detections, verdicts, strict=True))
                n_ok = sum(ok for _, (ok, _) in dets)
                passes = sorted({int(det.pass_index) for det in msg.detections})
                choice = _Choice(
                    'most confident correct',
                    f'the most confidently correct detections of {len(candidates)} '
                    f'{DETECTIONS} messages: {n_ok} of {len(dets)} right '
                    f'(pass {"/".join(map(str, passes))}), summed score {total:.2f}',
                    frame, [(det, ok, name) for det, (ok, name) in dets],
                    [(t.name, box) for t, box, _ in projected],
                    (float(msg.fixation_u), float(msg.fixation_v)), choice.notes)
                choice.facts = {'rule': choice.rule, 'stamp_ns': stamp, 'correct': n_ok,
                                'wrong': len(dets) - n_ok, 'score_sum': float(total),
                                'messages': len(candidates)}
                return choice
            why = 'the frame of the best detections is not decodable'
        elif not why:
            why = f'none of {len(candidates)} {DETECTIONS} messages had a correct detection'
    # The fallback: the final pass of the last detections whose frame is in the bag, else the
    # last frame.
    if d.det_frame is not None:
        stamp = d.det_frame[0]
        final = max(d.det_arrays, key=lambda a: max(det.pass_index for det in a.detections))
        shown = list(final.detections)
        marks: list[tuple[bool | None, str]] = [(None, '')] * len(shown)
        boxes: list[tuple[str, np.ndarray]] = []
        if objects and d.K is not None:
            try:
                seen = _project(d, objects, stamp, _left_frame_id(d, d.det_frame))
                marks = list(_judge(seen, shown))
                boxes = [(t.name, box) for t, box, _ in seen]
            except LookupError as err:
                choice.notes.append(f'ground truth not projected: {err}'[:100])
        choice = _Choice('last detections', f'the last detections\' frame ({why})', d.det_frame,
                         [(det, ok, name) for det, (ok, name) in zip(shown, marks, strict=True)],
                         boxes, (float(final.fixation_u), float(final.fixation_v)), choice.notes)
        n_ok = sum(ok is True for _, ok, _ in choice.detections)
        choice.facts = {'rule': choice.rule, 'stamp_ns': stamp, 'correct': n_ok,
                        'wrong': sum(ok is False for _, ok, _ in choice.detections),
                        'score_sum': float(sum(det.score for det, ok, _ in choice.detections
                                               if ok)),
                        'messages': len(candidates)}
        return choice
    if d.last_image is not None:
        choice = _Choice('last frame', f'the last frame ({why})', d.last_image,
                         notes=choice.notes)
        choice.facts = {'rule': choice.rule, 'stamp_ns': d.last_image[0]}
    return choice


# --- drawing ---------------------------------------------------------------------------------

def _empty(ax: Any, text: str) -> None:
    ax.set_xticks([])
    ax.set_yticks([])
    ax.text(0.5, 0.5, _wrap(text.split('\n'), 44), ha='center', va='center', fontsize=12,
            color='0.3', transform=ax.transAxes)


def _missing(d: _Data, *topics: str) -> str:
    """'no /a in the bag' for the first topic absent, else ''."""
    for t in topics:
        if not d.counts.get(t):
            return f'no {t} in the bag'
    return ''


def _wrap(notes: list[str], width: int) -> str:
    import textwrap
    return '\n'.join(textwrap.fill(n, width) for n in notes if n)


def _title(ax: Any, *lines: str) -> None:
    """A panel's title, left-aligned: its name, then the lines wrapped to its panel's width."""
    fig, panel = ax.get_figure(root=True), ax.get_figure(root=False)   # its own subfigure
    chars = int(0.85 * panel.bbox.width / fig.dpi * TITLE_CHARS_PER_IN)
    ax.set_title(lines[0] + '\n' + _wrap(list(lines[1:]), max(40, chars)), fontsize=10,
                 loc='left')


def _below(ax: Any, handles: list | None = None, notes: list[str] | None = None,
           ncol: int = 2, labels: list[str] | None = None) -> None:
    """The legend (and notes, as its title) under the axes, past its tick labels and x label;
    labels wrapped so that the legend is no wider than the panel."""
    from matplotlib.transforms import ScaledTranslation
    notes = [n for n in (notes or []) if n]
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    if labels is None:
        labels = [h.get_label() for h in handles]
    if not handles and not notes:
        return
    fig, panel = ax.get_figure(root=True), ax.get_figure(root=False)
    inches = 0.85 * panel.bbox.width / fig.dpi
    chars = max(24, int(inches * LEGEND_CHARS_PER_IN / max(ncol, 1)) - 5)
    leg = ax.legend(handles=handles, labels=[_wrap([lb], chars) for lb in labels],
                    loc='upper center', bbox_to_anchor=(0.5, 0.0), ncol=ncol,
                    bbox_transform=ax.transAxes + ScaledTranslation(0, -BELOW_IN,
                                                                    fig.dpi_scale_trans),
                    fontsize=8, frameon=False, title=_wrap(notes, int(inches * 15)) or None,
                    title_fontsize=8, borderaxespad=0.0)
    leg.get_title().set_color('0.25')


def _beside(ax: Any, handles: list | None = None, notes: list[str] | None = None,
            width: int = 34) -> None:
    """The legend (and notes) right of the axes, off the plot; labels wrapped at width."""
    notes = [n for n in (notes or []) if n]
    if handles is None:
        handles = ax.get_legend_handles_labels()[0]
    if not handles and not notes:
        return
    for h in handles:
        h.set_label(_wrap([h.get_label()], width))
    ax.legend(handles=handles, loc='upper left', bbox_to_anchor=(1.03, 1.0), fontsize=8,
              frameon=False, borderaxespad=0.0)
    if notes:
        ax.text(1.03, 0.0, _wrap(notes, width + 4), transform=ax.transAxes, fontsize=8,
                va='bottom', ha='left', color='0.25')


def _t(d: _Data, stamp: int) -> float:
    return (stamp - (d.first_stamp or 0)) / 1e9


def _decode_image(typename: str, raw: bytes) -> np.ndarray:
    img = image_to_numpy(msgs.deserialize(raw, typename))
    return img if img.ndim == 3 else np.repeat(img[..., None], 3, axis=2)


def _left_frame_id(d: _Data, frame: tuple[int, str, bytes] | None = None) -> str:
    frame = frame or d.det_frame or d.last_image
    if frame is None:
        return 'left_camera_optical_frame'
    return msgs.deserialize(frame[2],
                            frame[1]).header.frame_id.lstrip('/') or 'left_camera_optical_frame'


def _draw_left(ax: Any, d: _Data, p: Panel, choice: _Choice) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle
    p.facts = dict(choice.facts)
    if choice.frame is None:
        p.note = _missing(d, LEFT_IMAGE) or f'{LEFT_IMAGE}: no decodable frame'
        _empty(ax, p.note)
        return
    stamp, typename, raw = choice.frame
    img = _decode_image(typename, raw)
    h, w = img.shape[:2]
    ax.imshow(img, extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xlabel('u [px]')
    ax.set_ylabel('v [px]')
    p.has_data = True
    notes = list(choice.notes)
    _title(ax, p.title, f'{LEFT_IMAGE} at t = {_t(d, stamp):.2f} s, chosen as {choice.why}')
    handles: list[Any] = []
    # Fixation points of the whole run, seen from this frame's camera pose.
    if d.gaze and d.K is not None:
        try:
            pts = np.array([g[2:5] for g in d.gaze], dtype=np.float64)
            frames = np.array([g[1] or TOP_FRAME for g in d.gaze])
            times = np.array([_t(d, g[0]) for g in d.gaze])
            cam, buf = _left_frame_id(d, choice.frame), d.tf.at(stamp)
            cam_pts = np.empty_like(pts)
            for f in set(frames):
                sel = frames == f
                cam_pts[sel] = buf.transform_points(cam, f, pts[sel]).reshape(-1, 3)
            # One dot per distinct fixation (the state repeats the accepted one at a fixed rate).
            distinct = np.r_[True, np.any(np.abs(np.diff(pts, axis=0)) > 1e-6, axis=1)]
            front = distinct & (cam_pts[:, 2] > 0.05)
            uvw = cam_pts[front] @ d.K.T
            uv = uvw[:, :2] / uvw[:, 2:3]
            inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
            ax.plot(uv[inside, 0], uv[inside, 1], '-', color='white', lw=0.8, alpha=0.6)
            sc = ax.scatter(uv[inside, 0], uv[inside, 1], c=times[front][inside], cmap='plasma',
                            vmin=times.min(), vmax=max(times.max(), times.min() + 1e-3), s=30,
                            edgecolors='white', linewidths=0.6, zorder=3)
            handles.append(Line2D([], [], marker='o', ls='-', color='0.6', mfc='tab:purple',
                                  mec='0.3', ms=6, lw=0.8,
                                  label=f'{int(distinct.sum())} fixation points ({GAZE}; '
                                        'colour: when)'))
            cbar = ax.figure.colorbar(sc, ax=ax, fraction=0.035, pad=0.01)
            cbar.set_label('time the fixation began [s]', fontsize=8)
            cbar.ax.tick_params(labelsize=8)
            out = int(distinct.sum() - inside.sum())
            if out:
                notes.append(f'{out} of {int(distinct.sum())} fixations outside this view')
        except (LookupError, ValueError) as err:
            notes.append(f'fixation track not drawn: {err}'[:90])
    elif not d.gaze:
        notes.append(f'no {GAZE} in the bag')
    else:
        notes.append(f'no usable {LEFT_INFO}: fixation track not drawn')
    # The true objects' projected boxes, then the detections on top.
    for name, (u0, v0, u1, v1) in choice.boxes:
        if u1 < 0 or v1 < 0 or u0 >= w or v0 >= h:
            continue
        ax.add_patch(Rectangle((u0, v0), u1 - u0, v1 - v0, fill=False, ec='white', lw=0.8,
                               ls=(0, (3, 3)), alpha=0.8, zorder=2))
        ax.text(min(max(u0, 0), w - 1), min(v1, h - 1), name, color='white', fontsize=6.5,
                va='top', ha='left', zorder=2, clip_on=True,
                bbox=dict(fc='black', ec='none', alpha=0.45, pad=0.5))
    if choice.boxes:
        handles.append(Rectangle((0, 0), 1, 1, fill=False, ec='0.3', lw=0.8, ls=(0, (3, 3)),
                                 label='true objects\' projected boxes (ground truth)'))
    dets = sorted(choice.detections, key=lambda x: -x[0].score)[:SHOWN_DETECTIONS]
    seen: set[bool | None] = set()
    fixations: dict[tuple[float, float, str], list[int]] = {}
    for rank, (det, ok, under) in reversed(list(enumerate(dets, 1))):   # the best on top
        col = UNCHECKED if ok is None else CORRECT if ok else WRONG
        b = det.box
        ax.add_patch(Rectangle((b.x_offset - 0.5, b.y_offset - 0.5), b.width, b.height,
                               fill=False, ec=col, lw=2.0, zorder=4))
        fixations.setdefault((float(det.fixation_u), float(det.fixation_v), col), []).append(rank)
        what = f'{rank}: {det.label} {det.score:.2f}' + (
            f' (on {under})' if ok is False and under else ' (on nothing)' if ok is False else '')
        ax.text(b.x_offset, max(b.y_offset - 3, 8), what, color='black', fontsize=7.5,
                va='bottom', zorder=6, clip_on=True,
                bbox=dict(fc=col, ec='none', alpha=0.85, pad=1))
        seen.add(ok)
    # Each fixation once, over the labels, with the ranks of the detections made there.
    for (u, v, col), ranks in fixations.items():
        ax.plot([u], [v], marker='+', color=col, ms=14, mew=2.4, ls='none', zorder=8)
        ax.text(u + 5, v + 5, ','.join(map(str, sorted(ranks))), color=col, fontsize=8,
                fontweight='bold', va='top', zorder=8, clip_on=True,
                bbox=dict(fc='black', ec='none', alpha=0.55, pad=0.8))
    for ok, words in ((True, 'correct detection (rank: label score): the true object under '
                             'its fixation + has its label'),
                      (False, 'wrong detection (on: the true object under its fixation +)'),
                      (None, 'detection (rank: label score), unchecked: no ground truth')):
        if ok in seen:
            col = UNCHECKED if ok is None else CORRECT if ok else WRONG
            handles.append(Line2D([], [], marker='+', ms=10, mew=2, color=col, lw=2,
                                  label=words))
    if not choice.detections:
        notes.append(_missing(d, DETECTIONS) or (
            f'{DETECTIONS}: the frames of its {d.det_unmatched} detection messages are not in the '
            'bag' if d.det_unmatched else f'{DETECTIONS}: no message with a detection'))
    elif len(choice.detections) > len(dets):
        notes.append(f'the {len(dets)} best of {len(choice.detections)} detections drawn')
    _below(ax, handles, notes, ncol=2)
    p.note = '; '.join(notes)


def _draw_foveated(ax: Any, d: _Data, p: Panel, choice: _Choice) -> None:
    if d.foveated is None:
        p.note = _missing(d, FOVEATED) or f'{FOVEATED}: no frame'
        _empty(ax, p.note)
        return
    which, chosen = 'last frame', d.foveated
    if choice.frame is not None and choice.rule != 'last frame':
        at = _fetch_foveated(d, choice.frame[0])
        if at is not None:
            dt = (at[0] - choice.frame[0]) * 1e-9
            which = ("panel 1's frame" if at[0] == choice.frame[0]
                     else f"{dt:+.2f} s from panel 1's frame")
            chosen = at
    msg = msgs.deserialize(chosen[2], chosen[1])
    p.facts = {'frame': which, 'stamp_ns': chosen[0]}
    img = image_to_numpy(msg)
    h, w = img.shape[:2]
    ax.imshow(img if img.ndim == 3 else img, cmap=None if img.ndim == 3 else 'gray',
              extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.set_xlabel('u [px]')
    ax.set_ylabel('v [px]')
    _title(ax, p.title, f'{FOVEATED}, {which}, t = {_t(d, _ns(msg.header.stamp)):.2f} s '
                        '(sharp at the fovea, blurred outward)')
    p.has_data = True


def plt_viridis_mid() -> tuple:
    from matplotlib import colormaps
    return colormaps['viridis'](0.6)


def _robust_limits(xy: np.ndarray, pad: float = 0.15, cap: float = 6.0) -> tuple[tuple, tuple]:
    """Axis limits holding all but the outermost 2 % of many points (all of a few), at most cap
    m."""
    q = 2 if len(xy) > 1000 else 0
    lo = np.nanpercentile(xy, q, axis=0) - pad
    hi = np.nanpercentile(xy, 100 - q, axis=0) + pad
    lo, hi = np.maximum(lo, -cap), np.minimum(hi, cap)
    return (lo[0], hi[0]), (lo[1], hi[1])


def _top_axes(ax: Any, top: str) -> None:
    ax.set_xlabel(f'x [m] (forward, {top})')
    ax.set_ylabel(f'y [m] (left, {top})')
    ax.set_aspect('equal', adjustable='box')
    ax.grid(True, lw=0.4, alpha=0.5)


def _fit_box(ax: Any, pts: np.ndarray, pad: float) -> None:
    ax.set_xlim(pts[:, 0].min() - pad, pts[:, 0].max() + pad)
    ax.set_ylim(pts[:, 1].min() - pad, pts[:, 1].max() + pad)


def _to_top(d: _Data, cloud: _Cloud, top: str) -> np.ndarray:
    if cloud.frame == top:
        return cloud.xyz
    return d.tf.transform(cloud.xyz, top, cloud.frame, cloud.stamp)


def _draw_points(ax: Any, d: _Data, p: Panel, top: str) -> None:
    notes, xy_all = [], []
    if d.clouds:
        placed = []
        for c in d.clouds:
            try:
                placed.append((_to_top(d, c, top), c.rgb))
            except LookupError as err:
                notes.append(f'{POINTS} not placed: {err}'[:100])
                break
        if placed:
            xyz = np.vstack([q for q, _ in placed])
            rgbs = [r for _, r in placed if r is not None]
            rgb = np.vstack(rgbs) if len(rgbs) == len(placed) else None
            ax.scatter(xyz[:, 0], xyz[:, 1], s=1.5 if len(xyz) > 2000 else 10,
                       c=rgb if rgb is not None else '0.4',
                       alpha=0.5, lw=0, rasterized=True)
            xy_all.append(xyz[:, :2])
    else:
        notes.append(_missing(d, POINTS) or f'{POINTS}: every cloud empty')
    if d.cells is not None:
        try:
            xyz = _to_top(d, d.cells, top)
            val = d.cells.value
            sc = ax.scatter(xyz[:, 0], xyz[:, 1], s=9, marker='s',
                            c=val if val is not None else 'tab:blue', cmap='viridis', lw=0,
                            alpha=0.85)
            if val is not None:
                cbar = ax.figure.colorbar(sc, ax=ax, fraction=0.04, pad=0.01)
                cbar.set_label('SES cell information (-log|Σ|)', fontsize=8)
                cbar.ax.tick_params(labelsize=8)
            xy_all.append(xyz[:, :2])
        except LookupError as err:
            notes.append(f'{CELLS} not placed: {err}'[:100])
    else:
        notes.append(_missing(d, CELLS) or f'{CELLS}: no observed cell yet')
    if not xy_all:
        p.note = '; '.join(notes)
        _empty(ax, '\n'.join(notes))
        return
    p.has_data = True
    from matplotlib.artist import Artist
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon
    handles: list[Artist] = [Line2D([], [], marker='o', ls='none', color='0.45', ms=4,
                                    label=f'stereo points, {len(d.clouds)} clouds (their own '
                                          'colour)')] if d.clouds else []
    if d.cells is not None:
        handles.append(Line2D([], [], marker='s', ls='none', color=plt_viridis_mid(), ms=5,
                              label=f'SES cells (last {CELLS}, {len(d.cells.xyz)} cells)'))
    truth, _ = _place_truth(d, top)
    for t in truth:
        ax.add_patch(Polygon(t.outline, closed=True, fc='none', ec='k', lw=0.7, zorder=4))
    if truth:
        handles.append(Polygon(np.zeros((3, 2)), fc='none', ec='k', lw=0.7,
                               label='scene objects, table (ground truth)'))
    ax.plot([0], [0], marker='^', color='k', ms=8, ls='none', zorder=5)
    handles.append(Line2D([], [], marker='^', color='k', ms=7, ls='none',
                          label=f'{top} origin (the robot)'))
    xy = np.vstack(xy_all + [np.zeros((1, 2))])
    (x0, x1), (y0, y1) = _robust_limits(xy)
    x0 = min(x0, -0.2)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    outside = int(((xy[:, 0] < x0) | (xy[:, 0] > x1) | (xy[:, 1] < y0) | (xy[:, 1] > y1)).sum())
    if outside:
        notes.append(f'{outside} points beyond the view')
    _top_axes(ax, top)
    _title(ax, p.title, f'{POINTS} + {CELLS}, top view in {top}')
    _below(ax, handles, notes)
    p.note = '; '.join(notes)


def _draw_truth(ax: Any, truth: list[_Truth], names: bool = True) -> list[np.ndarray]:
    """The true objects' outlines with their names (the supports filled, unnamed); returns the
    outlines drawn."""
    from matplotlib.patches import Polygon
    for t in truth:
        if t.support:
            ax.add_patch(Polygon(t.outline, closed=True, fc='0.93', ec='0.6', lw=1, zorder=0))
            continue
        ax.add_patch(Polygon(t.outline, closed=True, fc='none', ec='0.15', lw=1.1, zorder=2))
        if names:
            ax.text(t.centre[0], t.centre[1] - t.radius - 0.012, t.name, fontsize=7,
                    ha='center', va='top', color='0.15', zorder=6)
    return [t.outline for t in truth]


def _draw_cylinders(ax: Any, d: _Data, p: Panel, top: str) -> None:
    from matplotlib.patches import Polygon
    outlines: list[np.ndarray] = []
    truth, notes = _place_truth(d, top)
    found_all, last = [], None
    for stamp, frame, cyls in d.cylinders:
        if not cyls:
            continue
        try:
            placed = []
            for label, c, a, r, h, conf in cyls:
                if frame == top:
                    cc, aa = c, a
                else:
                    T = d.tf.at(stamp).lookup_transform(top, frame)
                    cc, aa = T[:3, :3] @ c + T[:3, 3], T[:3, :3] @ a
                placed.append((label, cc, aa, r, h, conf))
        except LookupError as err:
            notes.append(f'{CYLINDERS} not placed: {err}'[:100])
            break
        found_all.extend(placed)
        last = (stamp, placed)
    if not truth and not found_all:
        if d.cylinders:
            notes.insert(0, f'{CYLINDERS}: {len(d.cylinders)} messages, none with a cylinder')
        else:
            notes.insert(0, _missing(d, CYLINDERS))
        p.note = '; '.join(n for n in notes if n)
        _empty(ax, '\n'.join(n for n in notes if n))
        return
    p.has_data = bool(found_all)
    first_gt = {'table': True, 'cylinder': True, 'other': True}
    for t in truth:
        key = 'table' if t.support else 'cylinder' if t.shape == 'cylinder' else 'other'
        style = {'table': dict(fc='0.93', ec='0.6', lw=1, zorder=0),
                 'cylinder': dict(fc='none', ec='tab:green', lw=2, zorder=2),
                 'other': dict(fc='none', ec='0.45', lw=1, ls='--', zorder=1)}[key]
        label = {'table': 'table (truth)', 'cylinder': 'true cylinder',
                 'other': 'other true object'}[key]
        ax.add_patch(Polygon(t.outline, closed=True, label=label if first_gt[key] else None,
                             **style))
        first_gt[key] = False
        outlines.append(t.outline)
        if not t.support:
            ax.text(t.centre[0], t.centre[1] - t.radius - 0.012, t.name, fontsize=7,
                    ha='center', va='top',
                    color='darkgreen' if t.shape == 'cylinder' else '0.35', zorder=5)
    first = True
    for _label, c, a, r, h, _conf in found_all:
        poly = cylinder_footprint(c, a, r, h)
        ax.add_patch(Polygon(poly, closed=True, fc='tab:red', ec='none', alpha=0.15, zorder=3,
                             label=f'found, all {len(d.cylinders)} msgs\n(darker: more often)'
                             if first else None))
        first = False
    if last:
        for i, (_label, c, a, r, h, _conf) in enumerate(last[1]):
            poly = cylinder_footprint(c, a, r, h)
            ax.add_patch(Polygon(poly, closed=True, fc='none', ec='tab:red', lw=1.6, zorder=4,
                                 label=f'found, last msg\n(t = {_t(d, last[0]):.2f} s)'
                                 if i == 0 else None))
            ax.plot([c[0]], [c[1]], '+', color='tab:red', ms=6, zorder=4)
            outlines.append(poly)
    # Which true cylinders were found at least once (centre within its radius + margin, in xy).
    gt_cyl = [(t.name, t.centre, t.radius) for t in truth
              if t.shape == 'cylinder' and not t.support]
    if gt_cyl and found_all:
        hit = [n for n, c, r in gt_cyl
               if any(np.hypot(*(f[1][:2] - c[:2])) < r + MATCH_MARGIN_M for f in found_all)]
        miss = [n for n, _, _ in gt_cyl if n not in hit]
        stray = 0 if not last else sum(
            not any(np.hypot(*(f[1][:2] - c[:2])) < r + MATCH_MARGIN_M for _, c, r in gt_cyl)
            for f in last[1])
        notes.insert(0, f'true cylinders found at least once: {len(hit)}/{len(gt_cyl)}'
                        + (f' (missed: {", ".join(miss)})' if miss else '')
                        + (f'; last message: {stray} of {len(last[1])} not at a true cylinder'
                           if last else ''))
    if not found_all:
        notes.insert(0, _missing(d, CYLINDERS) or
                     f'{CYLINDERS}: {len(d.cylinders)} messages, none with a cylinder')
    _fit_box(ax, np.vstack(outlines) if outlines else np.zeros((1, 2)), 0.06)
    _top_axes(ax, top)
    _title(ax, p.title, f'{CYLINDERS} vs {GROUND_TRUTH}, top view in {top}')
    _beside(ax, None, notes)
    p.note = '; '.join(n for n in notes if n)


def _truth_labelled(truth: list[_Truth]) -> list[Labelled]:
    return [Labelled(t.kind, (float(t.centre[0]), float(t.centre[1]), float(t.centre[2])))
            for t in truth if not t.support]


def _map_in_top(d: _Data, stamp: int, frame: str, objects: list[_MapObject],
                top: str) -> list[_MapObject]:
    """The map's objects with their centres in the top frame (sizes stay axis-aligned in the
    map's frame, which is base_link in the graph); LookupError without tf."""
    if frame == top or not objects:
        return objects
    T = d.tf.at(stamp).lookup_transform(top, frame)
    return [_MapObject(o.id, o.label, o.share, o.confirmed, o.established,
                       T[:3, :3] @ o.position + T[:3, 3], o.size) for o in objects]


def _labelled(objects: list[_MapObject]) -> list[Labelled]:
    return [Labelled(o.label, (float(o.position[0]), float(o.position[1]),
                               float(o.position[2]))) for o in objects]


def _assignment(cost: np.ndarray) -> list[tuple[int, int]]:
    """Minimum-cost assignment of a rectangular cost matrix, the smaller side wholly assigned:
    (row, column) pairs. The Hungarian algorithm (potentials, O(n^2 m)) in plain Python, as
    scipy.optimize.linear_sum_assignment solves it (which this package does not depend on)."""
    c = np.asarray(cost, np.float64)
    flip = c.shape[0] > c.shape[1]
    if flip:
        c = c.T
    n, m = c.shape
    if n == 0:
        return []
    u, v = [0.0] * (n + 1), [0.0] * (m + 1)
    owner, way = [0] * (m + 1), [0] * (m + 1)   # column j's row (1-based; 0: none)
    for i in range(1, n + 1):
        owner[0], j0 = i, 0
        minv, used = [math.inf] * (m + 1), [False] * (m + 1)
        while owner[j0]:
            used[j0] = True
            i0, delta, j1 = owner[j0], math.inf, 0
            for j in range(1, m + 1):
                if not used[j]:
                    cur = c[i0 - 1, j - 1] - u[i0] - v[j]
                    if cur < minv[j]:
                        minv[j], way[j] = cur, j0
                    if minv[j] < delta:
                        delta, j1 = minv[j], j
            for j in range(m + 1):
                if used[j]:
                    u[owner[j]] += delta
                    v[j] -= delta
                else:
                    minv[j] -= delta
            j0 = j1
        while j0:
            j1 = way[j0]
            owner[j0] = owner[j1]
            j0 = j1
    pairs = [(owner[j] - 1, j - 1) for j in range(1, m + 1) if owner[j]]
    return sorted((b, a) for a, b in pairs) if flip else sorted(pairs)


def _pairs(reported: list[Labelled], truths: list[Labelled], radius_m: float) -> dict[int, int]:
    """object_scoring's one-to-one pairing (same label, within radius_m, the assignment on
    distance): reported index -> true index."""
    if not reported or not truths:
        return {}
    r = np.array([x.position for x in reported]).reshape(-1, 3)
    t = np.array([x.position for x in truths]).reshape(-1, 3)
    dist = np.linalg.norm(r[:, None] - t[None], axis=2)
    ok = np.array([[a.label == b.label for b in truths] for a in reported]) & (dist <= radius_m)
    return {i: j for i, j in _assignment(np.where(ok, dist, 1e6)) if ok[i, j]}


def _score_words(s: Any) -> str:
    prec = (f'precision {s.precision:.2f} ({s.found}/{s.reported})' if s.reported
            else 'precision - (nothing confirmed)')
    return (f'recall {s.recall:.2f} ({s.found}/{s.truths}), {prec}, '
            f'{s.false_objects} false object{"s" if s.false_objects != 1 else ""}, '
            f'{s.misnamed} misnamed at {100 * s.radius_m:.0f} cm')


def _draw_object_map(ax: Any, d: _Data, p: Panel, top: str) -> None:
    from matplotlib.patches import Patch, Rectangle
    truth, notes = _place_truth(d, top)
    objects = [t for t in truth if not t.support]
    if not d.maps and not truth:
        p.note = '; '.join([_missing(d, OBJECT_MAP) or f'{OBJECT_MAP}: no message'] + notes)
        _empty(ax, p.note.replace('; ', '\n'))
        return
    outlines = _draw_truth(ax, truth)
    handles: list[Any] = []
    if any(t.support for t in truth):
        handles.append(Patch(fc='0.93', ec='0.6', label='table (ground truth)'))
    if objects:
        handles.append(Patch(fc='none', ec='0.15', label=f'true object ({GROUND_TRUTH})'))
    sub = f'{OBJECT_MAP} vs {GROUND_TRUTH}, top view in {top}'
    if not d.maps:
        notes.insert(0, _missing(d, OBJECT_MAP) or f'{OBJECT_MAP}: no message')
        _title(ax, p.title, sub)
    else:
        p.has_data = True
        stamp, frame, raw_objects = d.maps[-1]
        try:
            placed = _map_in_top(d, stamp, frame, raw_objects, top)
        except LookupError as err:
            placed = []
            notes.append(f'{OBJECT_MAP} not placed: {err}'[:100])
        confirmed = [o for o in placed if o.confirmed]
        unnamed = [o for o in placed if o.established and not o.confirmed]
        tentative = len(placed) - len(confirmed) - len(unnamed)
        truths = _truth_labelled(truth)
        pairs = _pairs(_labelled(confirmed), truths, SCORE_RADIUS_M)
        for o in unnamed:
            x, y = o.position[:2]
            sx, sy = max(o.size[0], 0.01), max(o.size[1], 0.01)
            ax.add_patch(Rectangle((x - sx / 2, y - sy / 2), sx, sy, fill=False, ec='0.5',
                                   lw=1.2, ls='--', zorder=3))
            outlines.append(np.array([[x - sx / 2, y - sy / 2], [x + sx / 2, y + sy / 2]]))
        for i, o in enumerate(confirmed):
            x, y = o.position[:2]
            sx, sy = max(o.size[0], 0.01), max(o.size[1], 0.01)
            ok = i in pairs
            col, dark = (('tab:green', 'darkgreen') if ok else ('tab:red', 'darkred')) \
                if truths else ('tab:blue', 'navy')
            ax.add_patch(Rectangle((x - sx / 2, y - sy / 2), sx, sy, fc=col, ec=col, alpha=0.45,
                                   lw=1.2, zorder=4))
            ax.text(x, y + sy / 2 + 0.008, f'{o.label} {o.share:.2f}', fontsize=7.5,
                    ha='center', va='bottom', color=dark, fontweight='bold', zorder=7)
            outlines.append(np.array([[x - sx / 2, y - sy / 2], [x + sx / 2, y + sy / 2]]))
            if ok:
                c = objects[pairs[i]].centre
                ax.plot([x, c[0]], [y, c[1]], '-', color=dark, lw=1.5, zorder=5)
            elif objects:
                near = min(objects, key=lambda t: float(np.linalg.norm(t.centre - o.position)))
                ax.plot([x, near.centre[0]], [y, near.centre[1]], ':', color=dark, lw=1.5,
                        zorder=5)
        if confirmed and truths:
            handles.append(Patch(fc='tab:green', ec='tab:green', alpha=0.45,
                                 label='confirmed, right: label share; line to its true object '
                                       f'(same class, within {100 * SCORE_RADIUS_M:.0f} cm)'))
            handles.append(Patch(fc='tab:red', ec='tab:red', alpha=0.45,
                                 label='confirmed, wrong; dotted line to the nearest true object'))
        elif confirmed:
            handles.append(Patch(fc='tab:blue', ec='tab:blue', alpha=0.45,
                                 label='confirmed: label share (unchecked)'))
        if unnamed:
            handles.append(Patch(fc='none', ec='0.5', ls='--',
                                 label='established, not confirmed (unnamed)'))
        s = score(_labelled(confirmed), truths, SCORE_RADIUS_M, FALSE_RADIUS_M)
        if truths:
            sub += f', t = {_t(d, stamp):.1f} s: ' + _score_words(s)
        else:
            sub += f', t = {_t(d, stamp):.1f} s'
            notes.append('no true objects: not scored')
        _title(ax, p.title, sub)
        notes.insert(0, f'last map: {len(confirmed)} confirmed, {len(unnamed)} established '
                        f'unconfirmed, {tentative} tentative (not drawn)')
        p.facts = {'stamp_ns': stamp, 'confirmed': len(confirmed), 'unconfirmed': len(unnamed),
                   'tentative': tentative, 'pairs': {confirmed[i].id: objects[j].name
                                                     for i, j in pairs.items()},
                   'wrong': [o.id for i, o in enumerate(confirmed) if i not in pairs],
                   **({'score': s.as_dict()} if truths else {})}
    _fit_box(ax, np.vstack([np.asarray(o).reshape(-1, 2) for o in outlines])
             if outlines else np.zeros((1, 2)), 0.05)
    _top_axes(ax, top)
    _beside(ax, handles, notes)
    p.note = '; '.join(n for n in notes if n)


def _draw_recall(ax: Any, d: _Data, p: Panel, top: str) -> None:
    from matplotlib.ticker import MaxNLocator
    if not d.maps:
        p.note = _missing(d, OBJECT_MAP) or f'{OBJECT_MAP}: no message'
        _empty(ax, p.note)
        return
    p.has_data = True
    truth, notes = _place_truth(d, top)
    truths = _truth_labelled(truth)
    rows = []
    for stamp, frame, objects in d.maps:
        try:
            placed = _map_in_top(d, stamp, frame, objects, top)
        except LookupError as err:
            notes.append(f'{OBJECT_MAP} not placed: {err}'[:100])
            continue
        confirmed = _labelled([o for o in placed if o.confirmed])
        unnamed = sum(o.established and not o.confirmed for o in placed)
        s5 = score(confirmed, truths, SCORE_RADIUS_M, FALSE_RADIUS_M)
        s10 = score(confirmed, truths, WIDE_RADIUS_M, FALSE_RADIUS_M)
        rows.append((_t(d, stamp), s5.recall, s5.precision if confirmed else math.nan,
                     s10.recall, len(confirmed), unnamed, s5.false_objects))
    if not rows:
        p.note = '; '.join(notes)
        _empty(ax, p.note)
        return
    t, r5, p5, r10, n_conf, n_unnamed, n_false = (np.array(c, np.float64) for c in zip(*rows,
                                                                                        strict=True))
    p.facts = {'t_s': t.tolist(), 'recall_5cm': r5.tolist(), 'precision_5cm': p5.tolist(),
               'recall_10cm': r10.tolist(), 'confirmed': n_conf.astype(int).tolist(),
               'unconfirmed': n_unnamed.astype(int).tolist(),
               'false_objects': n_false.astype(int).tolist(), 'truths': len(truths)}
    # Each value holds until the next map; the last one until the end of the run (at least a
    # sliver, so that it shows).
    end = max(_t(d, d.last_stamp or 0), float(t[-1] + 0.02 * max(t[-1] - t[0], 1.0)))
    t, r5, p5, r10, n_conf, n_unnamed = (np.r_[t, end], *(np.r_[c, c[-1]] for c in
                                                          (r5, p5, r10, n_conf, n_unnamed)))
    handles = []
    right = ax.twinx()
    handles += right.step(t, n_conf, where='post', color='tab:green', lw=1.6, alpha=0.8,
                          label='confirmed objects [count, right axis]')
    handles += right.step(t, n_unnamed, where='post', color='0.55', lw=1.2, ls=':',
                          label='established, unconfirmed [count, right axis]')
    right.set_ylabel('objects in the map [count]', fontsize=9)
    right.set_ylim(0, max(float(np.nanmax(np.r_[n_conf, n_unnamed])), len(truths), 1) * 1.1)
    right.yaxis.set_major_locator(MaxNLocator(integer=True))
    right.tick_params(labelsize=9)
    if truths:
        handles += ax.step(t, r5, where='post', color='tab:blue', lw=2.2,
                           label=f'recall at {100 * SCORE_RADIUS_M:.0f} cm')
        handles += ax.step(t, r10, where='post', color='deepskyblue', lw=1.6, ls='--',
                           zorder=3, label=f'recall at {100 * WIDE_RADIUS_M:.0f} cm')
        handles += ax.step(t, p5, where='post', color='tab:orange', lw=2.0,
                           label=f'precision at {100 * SCORE_RADIUS_M:.0f} cm '
                                 '(none while nothing is confirmed)')
        sub = (f'{OBJECT_MAP} confirmed objects vs {len(truths)} true objects '
               f'(vizzy_vision.object_scoring); last: recall {r5[-1]:.2f} at '
               f'{100 * SCORE_RADIUS_M:.0f} cm, {r10[-1]:.2f} at {100 * WIDE_RADIUS_M:.0f} cm, '
               + (f'precision {p5[-1]:.2f}' if n_conf[-1] else 'nothing confirmed'))
    else:
        notes.append('no true objects: recall and precision not scored')
        sub = f'{OBJECT_MAP}: objects in the map (no ground truth to score them)'
    ax.set_zorder(right.get_zorder() + 1)   # the rates over the counts
    ax.patch.set_visible(False)
    ax.set_ylim(-0.02, 1.05)
    ax.set_xlim(min(0.0, float(t.min())), max(float(t.max()), 1.0))
    ax.set_xlabel('time [s] (sim, from the earliest stamp)')
    ax.set_ylabel('recall, precision [share of 1]')
    ax.grid(True, lw=0.4, alpha=0.5)
    _title(ax, p.title, sub)
    _below(ax, handles, notes)
    p.note = '; '.join(n for n in notes if n)


def _draw_tracks(ax: Any, d: _Data, p: Panel) -> None:
    if not d.tracks:
        p.note = _missing(d, TRACKS) or f'{TRACKS}: {d.counts[TRACKS]} messages, no track'
        _empty(ax, p.note)
        return
    from matplotlib.patches import Rectangle
    p.has_data = True
    w, h = d.image_size or (max(max(s[1] for s in v) for v in d.tracks.values()) + 1,
                            max(max(s[2] for s in v) for v in d.tracks.values()) + 1)
    ids = sorted(d.tracks, key=lambda i: -len(d.tracks[i]))
    shown, rest = ids[:10], ids[10:]
    colours = [f'C{k}' for k in range(10)]
    for k, tid in enumerate(sorted(shown)):
        s = d.tracks[tid]
        u = np.array([x[1] for x in s])
        v = np.array([x[2] for x in s])
        label = s[-1][5]
        ax.plot(u, v, '-o', color=colours[k], ms=3, lw=1.2,
                label=f'track {tid} ({label}, {len(s)} frames, '
                      f't {max(_t(d, s[0][0]), 0):.1f} to {_t(d, s[-1][0]):.1f} s)')
        ax.add_patch(Rectangle((u[-1] - s[-1][3] / 2, v[-1] - s[-1][4] / 2), s[-1][3], s[-1][4],
                               fill=False, ec=colours[k], lw=1, ls='--'))
        ax.text(u[-1], v[-1], str(tid), color=colours[k], fontsize=9, fontweight='bold')
    for tid in rest:
        s = d.tracks[tid]
        ax.plot([x[1] for x in s], [x[2] for x in s], '-', color='0.6', lw=0.8,
                label=f'{len(rest)} shorter tracks' if tid == rest[0] else None)
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_aspect('equal')
    ax.set_xlabel('u [px] (box centre)')
    ax.set_ylabel('v [px] (box centre)')
    ax.grid(True, lw=0.4, alpha=0.5)
    _title(ax, p.title, f'{TRACKS}: box centres over time in the (moving) left image; dashed: '
                        'last box')
    _below(ax, None, None, ncol=1)


def _draw_gaze(ax: Any, d: _Data, p: Panel) -> None:
    if not d.gaze:
        p.note = _missing(d, GAZE) or f'{GAZE}: no state'
        _empty(ax, p.note)
        return
    p.has_data = True
    t = np.array([_t(d, g[0]) for g in d.gaze])
    for idx, name, col in ((7, 'version (left +)', 'tab:blue'), (8, 'vergence', 'tab:orange'),
                           (9, 'tilt (down +)', 'tab:purple')):
        ax.plot(t, np.degrees([g[idx] for g in d.gaze]), color=col, lw=1.4, label=name)
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + 0.12 * (hi - lo))   # room for the holder strip above the curves
    sacc = np.array([g[5] for g in d.gaze])
    first = True
    for a, b in _runs(sacc):
        ax.axvspan(t[a], t[min(b, len(t) - 1)], color='0.8', alpha=0.6, lw=0,
                   label='in saccade' if first else None)
        first = False
    # Who held the gaze: a colour strip along the top.
    sources = [g[6] for g in d.gaze]
    others = iter(['tab:red', 'tab:green', 'tab:brown', 'tab:pink', 'tab:olive', 'tab:cyan'] * 9)
    palette = {s: '0.25' if s == 'idle' else next(others) for s in sorted(set(sources))}
    start = 0
    for i in range(1, len(sources) + 1):
        if i == len(sources) or sources[i] != sources[start]:
            end_t = t[i] if i < len(t) else t[-1]
            ax.axvspan(t[start], end_t, ymin=0.94, ymax=1.0, color=palette[sources[start]], lw=0)
            start = i
    handles, labels = ax.get_legend_handles_labels()
    from matplotlib.patches import Patch
    for s, c in palette.items():
        handles.append(Patch(color=c))
        labels.append(f'gaze held by: {s} (top strip)')
    ax.set_xlabel('time [s] (sim, from the earliest stamp)')
    ax.set_ylabel('eye angle [deg]')
    ax.grid(True, lw=0.4, alpha=0.5)
    n_sacc = len(_runs(sacc))
    _title(ax, p.title, f'{GAZE}: eye angles, {n_sacc} saccade{"s" if n_sacc != 1 else ""} '
                        '(grey), who held the gaze (top strip)')
    ax.legend(handles, labels, loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize=8,
              frameon=False, borderaxespad=0.0)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs of the runs of True (end exclusive)."""
    f = np.r_[False, np.asarray(flags, bool), False]
    edges = np.flatnonzero(np.diff(f.astype(int)))
    return list(zip(edges[::2], edges[1::2], strict=True))


def _panels() -> dict[str, Panel]:
    return {
        'left': Panel('left', '1. Left camera: what the head looked at, and what it named there',
                      (LEFT_IMAGE, LEFT_INFO, GAZE, DETECTIONS, GROUND_TRUTH)),
        'object_map': Panel('object_map', '2. The object map at the end vs the scene\'s ground '
                                          'truth', (OBJECT_MAP, GROUND_TRUTH)),
        'recall': Panel('recall', '3. Objects found and named over time',
                        (OBJECT_MAP, GROUND_TRUTH)),
        'foveated': Panel('foveated', '4. Foveated image (what the recogniser sees)',
                          (FOVEATED,)),
        'cylinders': Panel('cylinders', '5. Cylinders found vs the scene\'s ground truth',
                           (CYLINDERS, GROUND_TRUTH)),
        'points': Panel('points', '6. 3D: stereo points and Sensory Ego-Sphere cells',
                        (POINTS, CELLS)),
        'gaze': Panel('gaze', '7. Gaze over time', (GAZE,)),
        'tracks': Panel('tracks', '8. Multiple-object tracks', (TRACKS,)),
    }


def summarize_bag(bag_dir: str | Path, out_path: str | Path, *,
                  figsize: tuple[float, float] = FIGSIZE,
                  dpi: int = DPI) -> dict[str, Any]:
    """Draw the one-page summary of a demo bag into out_path (PNG).

    Returns {'path': str, 'panels': {key: Panel}, 'with_data': [keys], 'empty': [keys],
    'errors': [undecodable messages]}: every panel of _panels(), drawn or not (the tracks panel
    is left off the page when there is no track; its note says why). Never raises for missing or
    empty topics: the panel says so.
    """
    from matplotlib.figure import Figure
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    d = _read(Path(bag_dir))
    top = TOP_FRAME
    panels = _panels()
    try:
        choice = _choose_frame(d)
    except Exception as err:  # noqa: BLE001 - the other panels still count
        choice = _Choice('none', notes=[f'frame not chosen: {type(err).__name__}: {err}'[:160]])
    draw = {'left': lambda ax, dd, pp: _draw_left(ax, dd, pp, choice),
            'object_map': lambda ax, dd, pp: _draw_object_map(ax, dd, pp, top),
            'recall': lambda ax, dd, pp: _draw_recall(ax, dd, pp, top),
            'foveated': lambda ax, dd, pp: _draw_foveated(ax, dd, pp, choice),
            'cylinders': lambda ax, dd, pp: _draw_cylinders(ax, dd, pp, top),
            'points': lambda ax, dd, pp: _draw_points(ax, dd, pp, top),
            'gaze': _draw_gaze, 'tracks': _draw_tracks}
    fig = Figure(figsize=figsize, dpi=dpi,
                 layout=ConstrainedLayoutEngine(w_pad=0.1, h_pad=0.1, wspace=0.06))
    rows: Any = fig.subfigures(3, 1, height_ratios=ROW_HEIGHTS)
    with_tracks = bool(d.tracks)
    # Each panel is a subfigure of its row that lays itself out: a long title or legend takes
    # room from its own panel only.
    layout = [(('left', 'object_map', 'recall'), (1.35, 1.2, 0.95)),
              (('foveated', 'cylinders', 'points'), (1.0, 1.0, 1.0)),
              (('gaze', 'tracks'), (2.2, 1.0)) if with_tracks else (('gaze',), (1.0,))]
    axes: dict[str, Any] = {}
    for row, (keys, widths) in zip(rows, layout, strict=True):
        cells = row.subfigures(1, len(keys), width_ratios=widths, squeeze=False)[0]
        for key, cell in zip(keys, cells, strict=True):
            axes[key] = cell.subplots()
    for key, panel in panels.items():
        if key not in axes:
            _draw_tracks_note(d, panel)
            continue
        ax = axes[key]
        try:
            draw[key](ax, d, panel)
        except Exception as err:  # noqa: BLE001 - one broken panel must not lose the page
            ax.clear()
            panel.has_data = False
            panel.note = f'could not draw: {type(err).__name__}: {err}'[:160]
            _empty(ax, panel.note)
        if not any(ax.get_title(loc=loc) for loc in ('left', 'center', 'right')):
            ax.set_title(panel.title, fontsize=10)
        ax.tick_params(labelsize=9)
    total = sum(d.counts.values())
    lines = [f'Vizzy demo summary: {Path(bag_dir).name} ({total} messages read on the '
             f'{sum(1 for t in TOPICS if d.counts.get(t))} topics drawn)']
    sc = panels['object_map'].facts.get('score')
    if sc:
        lines.append(f'By the end of the run the object map named {sc["found"]} of the '
                     f'{sc["truths"]} objects on the table right (recall {sc["recall"]:.2f} at '
                     f'{100 * sc["radius_m"]:.0f} cm); '
                     + (f'{sc["reported"]} confirmed, precision {sc["precision"]:.2f}, '
                        f'{sc["false_objects"]} where nothing is' if sc['reported']
                        else 'it confirmed nothing'))
    lines += [f'{p.title}: not drawn, {p.note}' for k, p in panels.items() if k not in axes]
    fig.suptitle('\n'.join(lines), fontsize=14)
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi, format='png')
    return {'path': str(out), 'panels': panels,
            'with_data': [k for k, p in panels.items() if p.has_data],
            'empty': [k for k, p in panels.items() if not p.has_data],
            'errors': d.errors}


def _draw_tracks_note(d: _Data, p: Panel) -> None:
    """The tracks panel left off the page: its note, as the panel would say it."""
    p.note = _missing(d, TRACKS) or f'{TRACKS}: {d.counts[TRACKS]} messages, no track'


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', help='a bag directory recorded by `make demo`')
    parser.add_argument('-o', '--output', default='demo_output/summary.png', help='PNG to write')
    ns = parser.parse_args(argv)
    from .bag import BagError
    try:
        result = summarize_bag(ns.bag, ns.output)
    except (BagError, OSError) as exc:   # a mistyped bag path: one line, exit 2
        print(f'demo_summary: {exc}', file=sys.stderr)
        return 2
    print(f'summary page: {result["path"]}')
    for key, panel in result['panels'].items():
        print(f'  {key:10} {"data" if panel.has_data else "EMPTY":5}  {panel.note}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

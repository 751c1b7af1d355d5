"""One page that says what the demo's graph saw and did: `demo_output/summary.png`.

    .venv/bin/python -m vizzy_runtime.demo_summary bags/demo_<time> [-o demo_output/summary.png]

`make demo` calls summarize_bag() on the bag it recorded. It reads the bag once (BagReader, in
log-time order), decodes only what it draws, and draws six panels:

1. the left camera (/vizzy/left/image_raw) at the stamp of the last foveation detections
   (/foveation/detections: the final pass's best boxes), with every fixation point of
   /gaze/state over the run projected into that image (camera pose from the recorded /tf at the
   frame's stamp, intrinsics from /vizzy/left/camera_info); the last frame when no detections;
2. the last foveated image (/foveation/image);
3. a top view of the stereo points (/stereo/points, every cloud) and of the Sensory Ego-Sphere
   cells (/ses/cells, the last non-empty message, coloured by their information field), in
   base_link (x forward, y left; transformed with /tf at each message's stamp);
4. the cylinders found (/cylinders: each one's footprint, an upright one a circle of its radius
   at its axis) against the simulator's ground truth (/sim/ground_truth/objects), in base_link;
5. the multiple-object tracks (/mot/tracks): each track id's box centre in image coordinates
   over time, and its last box;
6. the gaze over time (/gaze/state): version, vergence and tilt, the saccades and who held the
   gaze.

A panel whose topics are missing or empty says so in words ("no /cylinders in the bag") instead
of a plot; summarize_bag() returns which panels had data. Time axes are header stamps (sim time
in the simulator), in seconds from the earliest stamp of the messages drawn.
"""

from __future__ import annotations

import argparse
import bisect
import sys
from collections import OrderedDict, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vizzy_vision.frames import matrices_from_transforms, quaternions_to_matrices

from . import msgs
from .bag import BagReader
from .convert import image_to_numpy, pointcloud2_to_array
from .tf import TransformBuffer

FIGSIZE = (16.0, 10.0)   # inches
DPI = 110                # -> 1760 x 1100 px
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
TF, TF_STATIC = '/tf', '/tf_static'
TOPICS = (LEFT_IMAGE, LEFT_INFO, GAZE, DETECTIONS, FOVEATED, POINTS, CELLS, CYLINDERS,
          GROUND_TRUTH, TRACKS, TF, TF_STATIC)

RECENT_IMAGES = 48            # raw left frames kept to find the one the detections belong to
POINTS_PER_CLOUD = 4000       # stereo points kept per cloud (evenly subsampled)
MARKER_CUBE, MARKER_SPHERE, MARKER_CYLINDER = 1, 2, 3
MATCH_MARGIN_M = 0.03         # a found cylinder matches a true one within its radius + this (xy)


@dataclass
class Panel:
    """One panel of the page: what it shows, whether it had data, and what it says about it."""
    key: str
    title: str
    topics: tuple[str, ...]
    has_data: bool = False
    note: str = ''


@dataclass
class _Cloud:
    stamp: int
    frame: str
    xyz: np.ndarray
    value: np.ndarray | None = None
    rgb: np.ndarray | None = None


@dataclass
class _Data:
    """What the page needs, gathered in one pass over the bag."""
    counts: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    errors: list[str] = field(default_factory=list)
    tf: _TfHistory = field(default_factory=lambda: _TfHistory())
    recent_images: OrderedDict[int, tuple[str, bytes]] = field(default_factory=OrderedDict)
    last_image: tuple[int, str, bytes] | None = None
    det_frame: tuple[int, str, bytes] | None = None   # the frame of det_arrays
    det_stamp: int | None = None
    det_arrays: list[Any] = field(default_factory=list)
    det_unmatched: int = 0                             # detections whose frame was not found
    K: np.ndarray | None = None
    image_size: tuple[int, int] | None = None          # (width, height) from camera_info
    # (stamp, frame, x, y, z, saccade, source, ver, verg, tilt)
    gaze: list[tuple] = field(default_factory=list)
    foveated: tuple[int, str, bytes] | None = None
    clouds: list[_Cloud] = field(default_factory=list)
    cells: _Cloud | None = None
    cylinders: list[tuple[int, str, list[tuple]]] = field(default_factory=list)
    markers: list[Any] | None = None
    tracks: dict[int, list[tuple]] = field(default_factory=lambda: defaultdict(list))
    first_stamp: int | None = None


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
    d = _Data()
    reader = BagReader(bag_dir)
    for topic, typename, data, _log_ns, _pub_ns in reader.messages(topics=TOPICS):
        d.counts[topic] += 1
        try:
            if topic == LEFT_IMAGE:
                # Images are decoded only for the frames drawn; keep the recent raw ones.
                msg_stamp = _image_stamp(data, typename)
                _first(d, msg_stamp)
                raw = bytes(data)
                d.last_image = (msg_stamp, typename, raw)
                d.recent_images[msg_stamp] = (typename, raw)
                while len(d.recent_images) > RECENT_IMAGES:
                    d.recent_images.popitem(last=False)
                continue
            if topic == FOVEATED:
                d.foveated = (0, typename, bytes(data))
                continue
            msg = msgs.deserialize(data, typename)
            _take(d, topic, msg)
        except Exception as err:  # noqa: BLE001 - one bad message must not lose the page
            d.errors.append(f'{topic}: {type(err).__name__}: {err}')
    return d


def _first(d: _Data, stamp: int) -> None:
    if stamp > 0 and (d.first_stamp is None or stamp < d.first_stamp):
        d.first_stamp = stamp


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
        # pass, all with the frame's stamp).
        if len(msg.detections):
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


def _marker_footprint(m: Any, to_top: np.ndarray) -> tuple[str, np.ndarray, np.ndarray]:
    """(kind, outline (N, 2), centre (3,)) of a ground-truth marker in the top frame."""
    rot = quaternions_to_matrices(np.array([[m.pose.orientation.x, m.pose.orientation.y,
                                             m.pose.orientation.z, m.pose.orientation.w]]))[0]
    R = to_top[:3, :3] @ rot
    c = to_top[:3, :3] @ np.array([m.pose.position.x, m.pose.position.y, m.pose.position.z]) \
        + to_top[:3, 3]
    sx, sy, sz = m.scale.x, m.scale.y, m.scale.z
    if m.type == MARKER_CYLINDER:
        return 'cylinder', cylinder_footprint(c, R[:, 2], sx / 2, sz), c
    if m.type == MARKER_SPHERE:
        ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
        return 'sphere', c[:2] + sx / 2 * np.stack([np.cos(ang), np.sin(ang)], 1), c
    corners = np.array([[i * sx, j * sy, k * sz] for i in (-.5, .5) for j in (-.5, .5)
                        for k in (-.5, .5)])
    return 'box', _hull((corners @ R.T + c)[:, :2]), c


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


def _t(d: _Data, stamp: int) -> float:
    return (stamp - (d.first_stamp or 0)) / 1e9


def _decode_image(typename: str, raw: bytes) -> np.ndarray:
    img = image_to_numpy(msgs.deserialize(raw, typename))
    return img if img.ndim == 3 else np.repeat(img[..., None], 3, axis=2)


def _draw_left(ax: Any, d: _Data, p: Panel) -> None:
    frame = d.det_frame or d.last_image
    if frame is None:
        p.note = _missing(d, LEFT_IMAGE) or f'{LEFT_IMAGE}: no decodable frame'
        _empty(ax, p.note)
        return
    stamp, typename, raw = frame
    img = _decode_image(typename, raw)
    h, w = img.shape[:2]
    ax.imshow(img, extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xlabel('u [px]')
    ax.set_ylabel('v [px]')
    p.has_data = True
    notes = []
    which = 'at the last detections' if d.det_frame else 'last frame'
    ax.set_title(f'{p.title}\n{LEFT_IMAGE}, {which}, t = {_t(d, stamp):.2f} s', fontsize=10)
    # Fixation points of the whole run, seen from this frame's camera pose.
    if d.gaze and d.K is not None:
        try:
            pts = np.array([g[2:5] for g in d.gaze], dtype=np.float64)
            frames = np.array([g[1] or TOP_FRAME for g in d.gaze])
            times = np.array([_t(d, g[0]) for g in d.gaze])
            cam, buf = _left_frame(d), d.tf.at(stamp)
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
            ax.plot(uv[inside, 0], uv[inside, 1], '-', color='white', lw=0.8, alpha=0.7)
            sc = ax.scatter(uv[inside, 0], uv[inside, 1], c=times[front][inside], cmap='plasma',
                            vmin=times.min(), vmax=max(times.max(), times.min() + 1e-3), s=40,
                            edgecolors='white', linewidths=0.6, zorder=3,
                            label=f'fixation points of {GAZE} ({int(distinct.sum())} distinct)')
            cbar = ax.figure.colorbar(sc, ax=ax, fraction=0.035, pad=0.01)
            cbar.set_label('time the fixation began [s]', fontsize=8)
            cbar.ax.tick_params(labelsize=7)
            out = int(distinct.sum() - inside.sum())
            if out:
                notes.append(f'{out} of {int(distinct.sum())} fixations outside this view')
        except (LookupError, ValueError) as err:
            notes.append(f'fixation track not drawn: {err}'[:90])
    elif not d.gaze:
        notes.append(f'no {GAZE} in the bag')
    else:
        notes.append(f'no usable {LEFT_INFO}: fixation track not drawn')
    if d.det_frame:
        final = max(det.pass_index for a in d.det_arrays for det in a.detections)
        dets = sorted((det for a in d.det_arrays for det in a.detections
                       if det.pass_index == final),
                      key=lambda det: -det.score)[:3]
        from matplotlib.patches import Rectangle
        for i, det in reversed(list(enumerate(dets))):   # the best drawn last, on top
            b = det.box
            ax.add_patch(Rectangle((b.x_offset - 0.5, b.y_offset - 0.5), b.width, b.height,
                                   fill=False,
                                   ec='lime' if i == 0 else 'cyan', lw=2.2 if i == 0 else 1.2,
                                   zorder=4 - i,
                                   label=('best detection' if i == 0 else
                                          'next detections' if i == 1 else None)))
            ax.text(b.x_offset, b.y_offset - 4, f'{det.label} {det.score:.2f}', color='black',
                    fontsize=8, va='bottom', zorder=6 - i,
                    bbox=dict(fc='lime' if i == 0 else 'cyan', ec='none', alpha=0.8, pad=1))
        a0 = d.det_arrays[0]
        ax.plot([a0.fixation_u], [a0.fixation_v], marker='+', color='red', ms=14, mew=2, ls='none',
                label='fovea of the first pass')
    else:
        notes.append(_missing(d, DETECTIONS) or (
            f'{DETECTIONS}: the frames of its {d.det_unmatched} detection messages are not in the '
            'bag'
            if d.det_unmatched else f'{DETECTIONS}: no message with a detection'))
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc='lower left', fontsize=7, framealpha=0.8)
    if notes:
        p.note = '; '.join(notes)
        ax.text(0.99, 0.99, '\n'.join(notes), transform=ax.transAxes, ha='right', va='top',
                fontsize=7, color='white', bbox=dict(fc='black', alpha=0.6, ec='none'))


def _left_frame(d: _Data) -> str:
    frame = d.det_frame or d.last_image
    assert frame is not None
    return msgs.deserialize(frame[2],
                            frame[1]).header.frame_id.lstrip('/') or 'left_camera_optical_frame'


def _draw_foveated(ax: Any, d: _Data, p: Panel) -> None:
    if d.foveated is None:
        p.note = _missing(d, FOVEATED) or f'{FOVEATED}: no frame'
        _empty(ax, p.note)
        return
    msg = msgs.deserialize(d.foveated[2], d.foveated[1])
    img = image_to_numpy(msg)
    h, w = img.shape[:2]
    ax.imshow(img if img.ndim == 3 else img, cmap=None if img.ndim == 3 else 'gray',
              extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.set_xlabel('u [px]')
    ax.set_ylabel('v [px]')
    ax.set_title(f'{p.title}\n{FOVEATED}, last frame, t = {_t(d, _ns(msg.header.stamp)):.2f} s '
                 '(sharp at the fovea, blurred outward)', fontsize=10)
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
                       alpha=0.5, lw=0, rasterized=True,
                       label=f'stereo points, {len(placed)} clouds (their own colour)')
            xy_all.append(xyz[:, :2])
    else:
        notes.append(_missing(d, POINTS) or f'{POINTS}: every cloud empty')
    if d.cells is not None:
        try:
            xyz = _to_top(d, d.cells, top)
            val = d.cells.value
            sc = ax.scatter(xyz[:, 0], xyz[:, 1], s=9, marker='s',
                            c=val if val is not None else 'tab:blue', cmap='viridis', lw=0,
                            alpha=0.85, label=f'SES cells (last {CELLS}, {len(xyz)} cells)')
            if val is not None:
                cbar = ax.figure.colorbar(sc, ax=ax, fraction=0.04, pad=0.01)
                cbar.set_label('SES cell information (-log|Σ|)', fontsize=8)
                cbar.ax.tick_params(labelsize=7)
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
    for _i, (_name, _kind, poly, _c, _r) in enumerate(truth):
        ax.add_patch(Polygon(poly, closed=True, fc='none', ec='k', lw=0.7, zorder=4))
    if truth:
        handles.append(Polygon(np.zeros((3, 2)), fc='none', ec='k', lw=0.7,
                               label='scene objects, table (ground truth)'))
    ax.plot([0], [0], marker='^', color='k', ms=8, ls='none', zorder=5)
    handles.append(Line2D([], [], marker='^', color='k', ms=7, ls='none',
                          label=f'{top} origin (the robot)'))
    xy = np.vstack(xy_all + [np.zeros((1, 2))])
    (x0, x1), (y0, y1) = _robust_limits(xy)
    ax.set_xlim(min(x0, -0.2), x1)
    ax.set_ylim(y0, y1)
    outside = int(((xy[:,
                       0] < min(x0,
                                -0.2)) | (xy[:, 0] > x1) | (xy[:, 1] < y0) | (xy[:, 1] > y1)).sum())
    if outside:
        notes.append(f'{outside} points beyond the view')
    _top_axes(ax, top)
    ax.set_title(f'{p.title}\n{POINTS} + {CELLS}, top view in {top}', fontsize=10)
    ax.legend(handles=handles, loc='upper right', fontsize=7, framealpha=0.85)
    if notes:
        p.note = '; '.join(notes)
        ax.text(0.01, 0.01, '\n'.join(notes), transform=ax.transAxes, fontsize=7, va='bottom',
                bbox=dict(fc='white', alpha=0.8, ec='none'))


def _place_truth(d: _Data, top: str) -> tuple[list[tuple[str, str, np.ndarray, np.ndarray, float]],
                                               list[str]]:
    """The ground-truth objects as (name, kind, top-view outline, centre, radius), and notes."""
    truth, notes = [], []
    if not d.markers:
        return [], [f'no scene ground truth in the bag ({GROUND_TRUTH})']
    for m in d.markers:
        try:
            frame = m.header.frame_id.lstrip('/') or top
            to_top = (np.eye(4) if frame == top
                      else d.tf.at(_ns(m.header.stamp)).lookup_transform(top, frame))
            kind, poly, c = _marker_footprint(m, to_top)
        except (LookupError, ValueError) as err:
            notes.append(f'ground truth not placed: {err}'[:100])
            break
        truth.append((m.text or f'{kind} {m.id}', kind, poly, c, m.scale.x / 2))
    return truth, notes


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
    for name, kind, poly, c, r in truth:
        is_table = name.startswith('table')
        key = 'table' if is_table else 'cylinder' if kind == 'cylinder' else 'other'
        style = {'table': dict(fc='0.92', ec='0.6', lw=1, zorder=0),
                 'cylinder': dict(fc='none', ec='tab:green', lw=2, zorder=2),
                 'other': dict(fc='none', ec='0.45', lw=1, ls='--', zorder=1)}[key]
        label = {'table': 'table (truth)', 'cylinder': 'true cylinder',
                 'other': 'other true object'}[key]
        ax.add_patch(Polygon(poly, closed=True, label=label if first_gt[key] else None, **style))
        first_gt[key] = False
        outlines.append(poly)
        if not is_table:
            ax.text(c[0], c[1] - r - 0.012, name, fontsize=6.5, ha='center', va='top',
                    color='darkgreen' if kind == 'cylinder' else '0.35', zorder=5)
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
    gt_cyl = [(n, c, r) for n, k, _, c, r in truth if k == 'cylinder']
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
    pts = np.vstack(outlines) if outlines else np.zeros((1, 2))
    pad = 0.08
    ax.set_xlim(pts[:, 0].min() - pad, pts[:, 0].max() + pad)
    ax.set_ylim(pts[:, 1].min() - pad, pts[:, 1].max() + pad)
    _top_axes(ax, top)
    ax.set_title(f'{p.title}\n{CYLINDERS} vs {GROUND_TRUTH}, top view in {top}', fontsize=10,
                 loc='left')
    ax.set_anchor('W')
    ax.legend(loc='upper left', bbox_to_anchor=(1.02, 1.0), fontsize=7, framealpha=0.85)
    p.note = '; '.join(n for n in notes if n)
    if p.note:
        ax.text(1.02, 0.0, _wrap(notes, 26), transform=ax.transAxes, fontsize=7, va='bottom',
                ha='left', bbox=dict(fc='white', alpha=0.85, ec='0.8'), zorder=6)


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
    ax.set_title(f'{p.title}\n{TRACKS}: box centres over time in the (moving) left image; '
                 'dashed: last box', fontsize=10)
    ax.legend(loc='upper right', fontsize=7, framealpha=0.85)


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
        labels.append(f'gaze held by: {s}')
    ax.set_xlabel('time [s] (header stamps, from the earliest one)')
    ax.set_ylabel('angle [deg]')
    ax.grid(True, lw=0.4, alpha=0.5)
    n_sacc = len(_runs(sacc))
    ax.set_title(f'{p.title}\n{GAZE}: eye angles, {n_sacc} saccade{"s" if n_sacc != 1 else ""} '
                 '(grey), holder (top strip)',
                 fontsize=10)
    ax.legend(handles, labels, loc='lower left', fontsize=7, ncol=2, framealpha=0.85)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs of the runs of True (end exclusive)."""
    f = np.r_[False, np.asarray(flags, bool), False]
    edges = np.flatnonzero(np.diff(f.astype(int)))
    return list(zip(edges[::2], edges[1::2], strict=True))


def summarize_bag(bag_dir: str | Path, out_path: str | Path, *,
                  figsize: tuple[float, float] = FIGSIZE,
                  dpi: int = DPI) -> dict[str, Any]:
    """Draw the one-page summary of a demo bag into out_path (PNG).

    Returns {'path': str, 'panels': {key: Panel}, 'with_data': [keys], 'empty': [keys],
    'errors': [undecodable messages]}. Never raises for missing or empty topics: the panel says so.
    """
    from matplotlib.figure import Figure

    d = _read(Path(bag_dir))
    top = TOP_FRAME
    panels = {
        'left': Panel('left', '1. Left camera: where the head looked, what foveation found',
                      (LEFT_IMAGE, LEFT_INFO, GAZE, DETECTIONS)),
        'foveated': Panel('foveated', '2. Foveated image (what the recogniser sees)', (FOVEATED,)),
        'points': Panel('points', '3. 3D: stereo points and Sensory Ego-Sphere cells',
                        (POINTS, CELLS)),
        'cylinders': Panel('cylinders', '4. Cylinders found vs the scene\'s ground truth',
                           (CYLINDERS, GROUND_TRUTH)),
        'tracks': Panel('tracks', '5. Multiple-object tracks', (TRACKS,)),
        'gaze': Panel('gaze', '6. Gaze over time', (GAZE,)),
    }
    fig = Figure(figsize=figsize, dpi=dpi)
    axes = fig.subplots(2, 3)
    draw = (_draw_left, _draw_foveated, lambda ax, dd, pp: _draw_points(ax, dd, pp, top),
            lambda ax, dd, pp: _draw_cylinders(ax, dd, pp, top), _draw_tracks, _draw_gaze)
    for ax, (_key, panel), fn in zip(axes.flat, panels.items(), draw, strict=True):
        try:
            fn(ax, d, panel)
        except Exception as err:  # noqa: BLE001 - one broken panel must not lose the page
            ax.clear()
            panel.has_data = False
            panel.note = f'could not draw: {type(err).__name__}: {err}'[:160]
            _empty(ax, panel.note)
        if not any(ax.get_title(loc=loc) for loc in ('left', 'center', 'right')):
            ax.set_title(panel.title, fontsize=10)
        ax.tick_params(labelsize=8)
    total = sum(d.counts.values())
    fig.suptitle(f'Vizzy demo summary: {Path(bag_dir).name} ({total} messages read on the '
                 f'{sum(1 for t in TOPICS if d.counts.get(t))} topics drawn)', fontsize=13)
    fig.subplots_adjust(left=0.04, right=0.97, bottom=0.055, top=0.9, wspace=0.3, hspace=0.3)
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi, format='png')
    return {'path': str(out), 'panels': panels,
            'with_data': [k for k, p in panels.items() if p.has_data],
            'empty': [k for k, p in panels.items() if not p.has_data],
            'errors': d.errors}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', help='a bag directory recorded by `make demo`')
    parser.add_argument('-o', '--output', default='demo_output/summary.png', help='PNG to write')
    ns = parser.parse_args(argv)
    result = summarize_bag(ns.bag, ns.output)
    print(f'summary page: {result["path"]}')
    for key, panel in result['panels'].items():
        print(f'  {key:10} {"data" if panel.has_data else "EMPTY":5}  {panel.note}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

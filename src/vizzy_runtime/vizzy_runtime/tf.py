"""A tf buffer: stamped transforms of each frame (/tf, /tf_static), composed on demand.

Works on real rclpy and on the bundled runtime alike (it imports only from vizzy_runtime.ros), and
needs no tf2_ros (neither rclpy tier ships it). It keeps what tf2's BufferCore keeps, with hard
bounds on what a foreign publisher can make it hold (issue 28, item 3):

- **history**: each /tf edge (parent -> child) keeps its samples by stamp for ``cache_time_s``
  (10 s, tf2's default) behind its newest one, and at most ``max_samples`` (4096) of them;
  /tf_static edges (and transforms set without a stamp) are one time-independent sample;
- **lookups at a stamp**: ``lookup_transform(target, source, stamp)`` takes each /tf edge of the
  chain at that stamp, interpolated between the two samples around it
  (vizzy_vision.pose_history.interpolate_poses: spherical for the rotation, linear for the
  translation); without a stamp it means "latest", each edge's newest sample, as before;
- **stamps outside the history**: older than an edge's oldest sample kept raises
  ExtrapolationError (a LookupError) naming the edge and the history it has; newer than its
  newest sample by at most ``max_extrapolation_s`` (0.05 s: /tf may lag an image slightly) gets
  the newest sample held (counted in ``held_lookups``), later than that raises
  ExtrapolationError, unless ``timeout_s`` > 0 waits that long for the /tf that covers the stamp
  (tf2's lookup timeout, for a worker thread; never the executor's);
- **loops are refused**: an edge that would close a loop with the tree (its child is an ancestor
  of its parent) is not stored and the tree keeps working; so is a /tf edge for a frame that
  /tf_static publishes (a static frame is never re-parented by a dynamic one, which could make a
  loop later). Refused edges raise TransformRefusedError (a ValueError naming each one) after the
  rest of the message was stored; the listener logs it in one throttled line;
- **bounded frames**: a /tf frame not updated for ``cache_time_s`` is forgotten (swept at most
  once a second, when new frame names arrive; ``clock``, time.monotonic by default, tells when a
  transform arrived, so a foreign far-future stamp cannot expire the real tree), and at most
  ``max_frames`` (10,000) frames have a parent: a new frame past that is refused. The memory of a
  buffer is thus at most about max_frames x max_samples samples, and a stream of new names costs
  at most max_frames frames (bench/tf_buffer.py measures it);
- **lookups walk the two chains under the lock** (O(depth), no copy of the tree) up to their
  common ancestor, so a frame elsewhere in the tree, a broken one included, costs nothing.

Transforms are 4x4 homogeneous numpy matrices (float64); lookup_transform returns one, not a
geometry_msgs/TransformStamped. Stamps are seconds (float), or anything with sec and nanosec (a
builtin_interfaces/Time, a header's stamp), or with nanoseconds (an rclpy Time).

    buffer = TransformBuffer()
    listener = TransformListener(buffer, node)          # subscribes /tf and /tf_static
    T = buffer.lookup_transform('base_link', 'ego')     # latest: maps points in ego into base_link
    T = buffer.lookup_transform('ego', 'left_camera_optical_frame', image.header.stamp)
    points_base = buffer.transform_points('base_link', 'ego', points)   # (N, 3)

As in tf2, lookup_transform(target_frame, source_frame) is the transform that takes coordinates
expressed in source_frame to target_frame (the pose of source_frame in target_frame), and an
unknown or disconnected frame raises LookupError with a message that names it. Like tf2, a leading
'/' in a frame id is ignored, and a frame that gets a new parent is re-parented (a tree, not a
graph; its history starts anew under the new parent).
"""

from __future__ import annotations

import bisect
import itertools
import math
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from vizzy_vision.frames import matrices_from_transforms
from vizzy_vision.pose_history import interpolate_poses

__all__ = ['ExtrapolationError', 'FramePoses', 'TF_STATIC_TOPIC', 'TF_TOPIC', 'TransformBuffer',
           'TransformListener', 'TransformRefusedError', 'stamp_to_seconds']

# Relative, so each namespaced head keeps its own tree (the multi-robot idiom); at the root
# namespace they resolve to /tf and /tf_static, tf2_ros's names.
TF_TOPIC = 'tf'
TF_STATIC_TOPIC = 'tf_static'

CACHE_TIME_S = 10.0           # tf2's default cache length
MAX_SAMPLES = 4096            # per edge: 41 s at 100 Hz, 4 s at 1 kHz
MAX_FRAMES = 10_000           # frames with a parent (a robot has tens to hundreds)
MAX_EXTRAPOLATION_S = 0.05    # a stamp this far past an edge's newest sample gets that sample
SWEEP_PERIOD_S = 1.0          # least time between two sweeps of expired frames
_SHOWN_FRAMES = 20            # frames named in an unknown-frame message


def stamp_to_seconds(stamp: Any) -> float:
    """Seconds of a float, a builtin_interfaces/Time (sec, nanosec) or an rclpy Time."""
    if type(stamp) is float:        # set_transforms' stamps, already seconds
        return stamp
    if hasattr(stamp, 'sec') and hasattr(stamp, 'nanosec'):
        return float(stamp.sec) + 1e-9 * float(stamp.nanosec)
    if hasattr(stamp, 'nanoseconds'):
        return 1e-9 * float(stamp.nanoseconds)
    return float(stamp)


class ExtrapolationError(LookupError):
    """A lookup at a stamp that an edge's kept history does not cover (too old, or newer than its
    newest sample by more than the tolerance)."""

    def __init__(self, message: str, *, frame: str, stamp: float, oldest: float,
                 newest: float) -> None:
        super().__init__(message)
        self.frame, self.stamp, self.oldest, self.newest = frame, stamp, oldest, newest


class TransformRefusedError(ValueError):
    """Transforms not stored: each (parent, child, why). The others of the batch were stored."""

    def __init__(self, refused: list[tuple[str, str, str]]) -> None:
        self.refused = refused
        shown = '; '.join(f'{p!r} -> {c!r}: {why}' for p, c, why in refused[:3])
        more = f' (and {len(refused) - 3} more)' if len(refused) > 3 else ''
        super().__init__(f'refused {len(refused)} transform(s): {shown}{more}')


def _strip(frame_id: str) -> str:
    return frame_id[1:] if frame_id.startswith('/') else frame_id


def _inverse(m: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    inv = np.eye(4)
    inv[:3, :3] = m[:3, :3].T
    inv[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return inv


# Rotation matrix entries as quadratic forms of an (unnormalized) quaternion (x, y, z, w), over
# its squared norm: R = (q q^T).flat @ _QUAT_TO_ROT / |q|^2 (scipy's Rotation.as_matrix terms).
_QUAT_TO_ROT = np.zeros((16, 9))
for _entry, _terms in enumerate((
        ((0, 0, 1), (1, 1, -1), (2, 2, -1), (3, 3, 1)), ((0, 1, 2), (2, 3, -2)),
        ((0, 2, 2), (1, 3, 2)), ((0, 1, 2), (2, 3, 2)), ((0, 0, -1), (1, 1, 1), (2, 2, -1),
                                                         (3, 3, 1)),
        ((1, 2, 2), (0, 3, -2)), ((0, 2, 2), (1, 3, -2)), ((1, 2, 2), (0, 3, 2)),
        ((0, 0, -1), (1, 1, -1), (2, 2, 1), (3, 3, 1)))):
    for _k, _l, _c in _terms:
        _QUAT_TO_ROT[4 * _k + _l, _entry] = _c


def _pose_matrices(poses: np.ndarray) -> np.ndarray:
    """(N, 7) translations and quaternions (x y z, x y z w) -> (N, 4, 4), as
    vizzy_vision.frames.matrices_from_transforms (which checks them: ValueError naming a bad
    one) without scipy's per-call overhead (the /tf path)."""
    t, q = poses[:, :3], poses[:, 3:]
    norm2 = np.einsum('ij,ij->i', q, q)
    if not (np.isfinite(t).all() and np.isfinite(norm2).all() and (norm2 >= 1e-18).all()):
        # a bad value (raises, naming it), or a norm^2 out of float range: the reference
        return matrices_from_transforms(t, q)
    m = np.zeros((len(poses), 4, 4))
    m[:, :3, :3] = ((q[:, :, None] * q[:, None, :]).reshape(-1, 16) @ _QUAT_TO_ROT
                    / norm2[:, None]).reshape(-1, 3, 3)
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


class _Edge:
    """A frame's parent and its pose in it: one sample (static) or samples by stamp."""

    __slots__ = ('matrices', 'parent', 'received', 'stamps')

    def __init__(self, parent: str, static: bool, received: float) -> None:
        self.parent = parent
        self.stamps: list[float] | None = None if static else []
        self.matrices: list[np.ndarray] = []
        self.received = received

    @property
    def static(self) -> bool:
        return self.stamps is None


# One edge's part of a lookup: a matrix, or (weight, before, after) to interpolate.
_Part = np.ndarray | tuple[float, np.ndarray, np.ndarray]


class TransformBuffer:
    """Stamped parent -> child transforms of a frame tree, composed on lookup. Thread-safe.

    Module docstring: history, stamps, loops and the bounds. Counters (read, never reset):
    held_lookups (answered with an edge's newest sample for a stamp just past it),
    old_samples_ignored (older than the history kept), frames_expired, refused (edges refused,
    by reason: 'loop', 'static frame', 'frame limit').
    """

    def __init__(self, cache_time_s: float = CACHE_TIME_S, *, max_samples: int = MAX_SAMPLES,
                 max_frames: int = MAX_FRAMES,
                 max_extrapolation_s: float = MAX_EXTRAPOLATION_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not (cache_time_s > 0 and max_samples >= 2 and max_frames >= 1
                and max_extrapolation_s >= 0):
            raise ValueError(f'cache_time_s {cache_time_s} must be > 0, max_samples '
                             f'{max_samples} >= 2, max_frames {max_frames} >= 1, '
                             f'max_extrapolation_s {max_extrapolation_s} >= 0')
        self.cache_time_s = float(cache_time_s)
        self.max_samples = int(max_samples)
        self.max_frames = int(max_frames)
        self.max_extrapolation_s = float(max_extrapolation_s)
        self._clock = clock
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)   # a lookup waiting for /tf
        self._edges: dict[str, _Edge] = {}      # child -> its edge
        self._children: dict[str, int] = {}     # parent -> number of children
        self._last_sweep = -math.inf
        self.held_lookups = 0
        self.old_samples_ignored = 0
        self.frames_expired = 0
        self.refused: dict[str, int] = {}

    def keep_at_least(self, seconds: float) -> None:
        """Keep at least this much history [s] (a user that looks that far back)."""
        with self._lock:
            self.cache_time_s = max(self.cache_time_s, float(seconds))

    # --- filling --------------------------------------------------------------------------------

    def set_transforms(self, parents: Sequence[str], children: Sequence[str],
                       matrices: np.ndarray, stamps: Sequence[float] | None = None) -> None:
        """Set the pose (N, 4, 4) of each children[i] in parents[i] at stamps[i] [s]; without
        stamps the transforms are static (time-independent, as from /tf_static).

        A bad frame id raises ValueError and nothing is stored; edges refused (a loop, a static
        frame on /tf, the frame limit) raise TransformRefusedError after the others were stored.
        """
        matrices = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        if not len(parents) == len(children) == len(matrices):
            raise ValueError(f'{len(parents)} parents, {len(children)} children and '
                             f'{len(matrices)} matrices')
        if stamps is not None and len(stamps) != len(children):
            raise ValueError(f'{len(stamps)} stamps for {len(children)} transforms')
        edges = []
        for parent, child in zip(parents, children, strict=True):
            parent, child = _strip(parent), _strip(child)
            if not parent or not child:
                raise ValueError(f'empty frame id in transform {parent!r} -> {child!r}')
            if parent == child:
                raise ValueError(f'transform from {parent!r} to itself')
            edges.append((parent, child))
        if stamps is not None:
            times = [stamp_to_seconds(s) for s in stamps]
            bad = [f'{p}->{c}' for (p, c), t in zip(edges, times, strict=True)
                   if not math.isfinite(t)]
            if bad:
                raise ValueError(f'non-finite stamp in transform(s) {bad}')
        refused = []
        with self._lock:
            now = self._clock()
            for i, (parent, child) in enumerate(edges):
                why = self._insert(parent, child, matrices[i].copy(),
                                   None if stamps is None else times[i], now)
                if why is not None:
                    refused.append((parent, child, why))
            self._changed.notify_all()
        if refused:
            raise TransformRefusedError(refused)

    def set_transform(self, parent: str, child: str, matrix: np.ndarray,
                      stamp: Any = None) -> None:
        """Set the pose (4x4) of child in parent (at stamp; without one: static)."""
        self.set_transforms([parent], [child], np.asarray(matrix)[None],
                            None if stamp is None else [stamp_to_seconds(stamp)])

    def set_transform_messages(self, transforms: Iterable[Any], *, static: bool = False) -> None:
        """Add geometry_msgs/TransformStamped messages (a tf2_msgs/TFMessage's transforms) at
        their header stamps, or as static transforms (static=True: /tf_static).

        A message with a non-finite value or a zero quaternion raises ValueError naming it, and
        nothing of the batch is stored; refused edges: as set_transforms.
        """
        # every /tf message of every reader comes here (65 a second in the graph): one pass over
        # the messages, one array, and the matrices in a few vectorized steps (issue 27)
        transforms = list(transforms)
        if not transforms:
            return
        parents: list[str] = []
        children: list[str] = []
        values: list[float] = []
        for t in transforms:
            parents.append(t.header.frame_id)
            children.append(t.child_frame_id)
            tr, rot = t.transform.translation, t.transform.rotation
            values += (tr.x, tr.y, tr.z, rot.x, rot.y, rot.z, rot.w)
        poses = np.array(values, dtype=np.float64).reshape(-1, 7)
        try:
            matrices = _pose_matrices(poses)
        except ValueError as exc:
            bad = [f'{p}->{c}' for p, c, pose in zip(parents, children, poses, strict=True)
                   if not (np.isfinite(pose).all() and np.linalg.norm(pose[3:]) >= 1e-9)]
            raise ValueError(f'{exc} in transform(s) {bad}') from None
        stamps = None if static else [stamp_to_seconds(t.header.stamp) for t in transforms]
        self.set_transforms(parents, children, matrices, stamps)

    def _insert(self, parent: str, child: str, m: np.ndarray, stamp: float | None,
                now: float) -> str | None:
        """Store one edge (under the lock); why it was refused, or None."""
        edge = self._edges.get(child)
        if edge is not None and edge.static and stamp is not None:
            return self._refuse('static frame', f'{child!r} is static (tf_static, under '
                                                f'{edge.parent!r}): /tf may not move it')
        if edge is None or edge.parent != parent:
            loop = self._loop(parent, child)
            if loop:
                return self._refuse('loop', 'would close a loop: ' + ' -> '.join(loop))
        if edge is None:
            if now - self._last_sweep >= SWEEP_PERIOD_S:
                self._sweep(now)
            if len(self._edges) >= self.max_frames:
                return self._refuse('frame limit', f'the buffer holds max_frames '
                                                   f'{self.max_frames} frames already')
        if edge is None or edge.parent != parent or edge.static != (stamp is None):
            if edge is not None:
                self._drop(child, edge)
            edge = self._edges[child] = _Edge(parent, stamp is None, now)
            self._children[parent] = self._children.get(parent, 0) + 1
        edge.received = now
        if edge.stamps is None:
            edge.matrices[:] = [m]
            return None
        assert stamp is not None
        stamps, mats = edge.stamps, edge.matrices
        if stamps and stamp < stamps[-1] - self.cache_time_s:
            self.old_samples_ignored += 1     # older than the history kept (tf2: TF_OLD_DATA)
            return None
        i = bisect.bisect_left(stamps, stamp)
        if i < len(stamps) and stamps[i] == stamp:
            mats[i] = m
        else:
            stamps.insert(i, stamp)
            mats.insert(i, m)
        cut = max(bisect.bisect_left(stamps, stamps[-1] - self.cache_time_s),
                  len(stamps) - self.max_samples)
        if cut > 0:
            del stamps[:cut], mats[:cut]
        return None

    def _refuse(self, reason: str, text: str) -> str:
        self.refused[reason] = self.refused.get(reason, 0) + 1
        return text

    def _loop(self, parent: str, child: str) -> list[str] | None:
        """The loop child -> parent -> ... -> child an edge would close, or None (O(depth))."""
        path = [child, parent]
        frame = parent
        while frame != child:
            edge = self._edges.get(frame)
            if edge is None or len(path) > len(self._edges) + 1:
                return None
            frame = edge.parent
            path.append(frame)
        return path

    def _drop(self, child: str, edge: _Edge) -> None:
        del self._edges[child]
        left = self._children[edge.parent] - 1
        if left:
            self._children[edge.parent] = left
        else:
            del self._children[edge.parent]

    def _sweep(self, now: float) -> None:
        """Forget the /tf frames not updated for cache_time_s (under the lock)."""
        self._last_sweep = now
        old = now - self.cache_time_s
        expired = [(c, e) for c, e in self._edges.items() if not e.static and e.received < old]
        for child, edge in expired:
            self._drop(child, edge)
        self.frames_expired += len(expired)

    def clear(self) -> None:
        """Forget every transform."""
        with self._lock:
            self._edges.clear()
            self._children.clear()

    # --- queries --------------------------------------------------------------------------------

    def all_frames(self) -> set[str]:
        """Every frame id known (parents and children)."""
        with self._lock:
            return set(self._edges) | set(self._children)

    def parent(self, frame_id: str) -> str | None:
        """The parent of frame_id, or None for a root or an unknown frame."""
        with self._lock:
            edge = self._edges.get(_strip(frame_id))
        return edge.parent if edge else None

    def is_static(self, frame_id: str) -> bool | None:
        """Whether frame_id's transform is static (None: a root or an unknown frame)."""
        with self._lock:
            edge = self._edges.get(_strip(frame_id))
        return edge.static if edge else None

    def stats(self) -> dict[str, int]:
        """Frames and samples held, and the counters (for benchmarks and diagnostics)."""
        with self._lock:
            samples = sum(len(e.matrices) for e in self._edges.values())
            return {'frames': len(set(self._edges) | set(self._children)),
                    'edges': len(self._edges), 'samples': samples,
                    'held_lookups': self.held_lookups,
                    'old_samples_ignored': self.old_samples_ignored,
                    'frames_expired': self.frames_expired,
                    **{f'refused {k}': v for k, v in self.refused.items()}}

    def can_transform(self, target_frame: str, source_frame: str, stamp: Any = None) -> bool:
        """Is there a chain between the two frames (covering stamp, if given)?"""
        try:
            self.lookup_transform(target_frame, source_frame, stamp)
        except LookupError:
            return False
        return True

    def _chain(self, frame: str) -> list[str]:
        """frame, its parent, ... up to its root (under the lock)."""
        chain = [frame]
        edge = self._edges.get(frame)
        while edge is not None:
            if len(chain) > len(self._edges):      # loops are refused; never trust, though
                raise LookupError(f'the tf tree has a loop through {frame!r}')
            chain.append(edge.parent)
            edge = self._edges.get(edge.parent)
        return chain

    def _unknown(self, target: str, source: str) -> LookupError | None:
        missing = [f for f in (source, target) if f not in self._edges
                   and f not in self._children]
        if not missing:
            return None
        names = list(itertools.islice(itertools.chain(
            (f for f in self._children if f not in self._edges), self._edges),
            _SHOWN_FRAMES + 1))
        shown = ', '.join(names[:_SHOWN_FRAMES]) + (', ...' if len(names) > _SHOWN_FRAMES
                                                    else '')
        which = ' and '.join(repr(f) for f in missing)
        what = f'frame {which} is' if len(missing) == 1 else f'frames {which} are'
        return LookupError(f'{what} not in the tf tree (looking up {source!r} in {target!r}); '
                           f'known frames: {shown or "none yet"}')

    def _part(self, child: str, edge: _Edge, stamp: float | None,
              tolerance: float) -> _Part | ExtrapolationError:
        """One edge's matrix at stamp (under the lock), or why not."""
        stamps, mats = edge.stamps, edge.matrices
        if stamps is None or stamp is None:
            return mats[-1]
        if stamp >= stamps[-1]:
            if stamp == stamps[-1]:
                return mats[-1]
            if stamp - stamps[-1] <= tolerance:
                self.held_lookups += 1
                return mats[-1]
            return ExtrapolationError(
                f'no transform {edge.parent!r} -> {child!r} at {stamp:.4f} s yet: its newest is '
                f'{stamp - stamps[-1]:.4f} s older (at {stamps[-1]:.4f} s; tolerance '
                f'{tolerance:g} s)', frame=child, stamp=stamp, oldest=stamps[0],
                newest=stamps[-1])
        if stamp < stamps[0]:
            return ExtrapolationError(
                f'transform {edge.parent!r} -> {child!r} at {stamp:.4f} s is older than its '
                f'history ({stamps[0]:.4f} to {stamps[-1]:.4f} s kept, cache_time_s '
                f'{self.cache_time_s:g})', frame=child, stamp=stamp, oldest=stamps[0],
                newest=stamps[-1])
        i = bisect.bisect_right(stamps, stamp)          # stamps[i-1] <= stamp < stamps[i]
        if stamps[i - 1] == stamp:
            return mats[i - 1]
        w = (stamp - stamps[i - 1]) / (stamps[i] - stamps[i - 1])
        return (w, mats[i - 1], mats[i])

    def lookup_transform(self, target_frame: str, source_frame: str, stamp: Any = None, *,
                         timeout_s: float = 0.0,
                         max_extrapolation_s: float | None = None) -> np.ndarray:
        """4x4 transform taking coordinates in source_frame to target_frame, at stamp (seconds,
        a builtin_interfaces/Time or an rclpy Time; None: the latest of each edge).

        Raises LookupError naming the frame that is not in the tree, or both roots when the two
        frames are in different trees; ExtrapolationError (a LookupError) when an edge's history
        does not cover stamp (module docstring), after waiting up to timeout_s [s] for /tf that
        covers it. max_extrapolation_s overrides the buffer's tolerance for this lookup.
        """
        target, source = _strip(target_frame), _strip(source_frame)
        if not target or not source:
            raise LookupError('empty frame id: every transform needs a named frame '
                              f'(target {target_frame!r}, source {source_frame!r})')
        t = None if stamp is None else stamp_to_seconds(stamp)
        if target == source:
            return np.eye(4)
        deadline = time.monotonic() + timeout_s
        with self._lock:
            while True:
                parts = self._parts(target, source, t, max_extrapolation_s)
                late = isinstance(parts, ExtrapolationError) and parts.stamp > parts.newest
                wait = deadline - time.monotonic()
                if not late or wait <= 0:
                    break
                self._changed.wait(wait)
        if isinstance(parts, LookupError):
            raise parts
        s_parts, t_parts = parts
        return _inverse(_compose(t_parts)) @ _compose(s_parts)

    def _parts(self, target: str, source: str, t: float | None, tolerance: float | None
               ) -> tuple[list[_Part], list[_Part]] | LookupError:
        """The edges' matrices from source and from target up to their common ancestor."""
        unknown = self._unknown(target, source)
        if unknown is not None:
            return unknown
        s_chain, t_chain = self._chain(source), self._chain(target)
        if s_chain[-1] != t_chain[-1]:
            return LookupError(f'frames {source!r} and {target!r} are not connected: '
                               f'{source!r} is under {s_chain[-1]!r}, {target!r} under '
                               f'{t_chain[-1]!r}')
        on_target = {f: i for i, f in enumerate(t_chain)}
        common = next(i for i, f in enumerate(s_chain) if f in on_target)
        tol = self.max_extrapolation_s if tolerance is None else tolerance
        lists: list[list[_Part]] = []
        for chain in (s_chain[:common], t_chain[:on_target[s_chain[common]]]):
            out: list[_Part] = []
            for child in chain:
                part = self._part(child, self._edges[child], t, tol)
                if isinstance(part, ExtrapolationError):
                    return part
                out.append(part)
            lists.append(out)
        return lists[0], lists[1]

    def latest_common_time(self, target_frame: str, source_frame: str) -> float | None:
        """The newest stamp at which every /tf edge between the two frames has a sample (the
        oldest of their newest samples); None when the chain is static. LookupError as
        lookup_transform."""
        target, source = _strip(target_frame), _strip(source_frame)
        if target == source:
            return None
        with self._lock:
            unknown = self._unknown(target, source)
            if unknown is not None:
                raise unknown
            s_chain, t_chain = self._chain(source), self._chain(target)
            if s_chain[-1] != t_chain[-1]:
                raise LookupError(f'frames {source!r} and {target!r} are not connected')
            on_target = set(t_chain)
            common = next(f for f in s_chain if f in on_target)
            newest = [stamps[-1] for f in itertools.chain(
                itertools.takewhile(lambda f: f != common, s_chain),
                itertools.takewhile(lambda f: f != common, t_chain))
                if (stamps := self._edges[f].stamps) is not None]
        return min(newest) if newest else None

    def transform_points(self, target_frame: str, source_frame: str, points: np.ndarray,
                         stamp: Any = None) -> np.ndarray:
        """(N, 3) points in source_frame -> (N, 3) in target_frame (or one (3,) point)."""
        p = np.asarray(points, dtype=np.float64)
        m = self.lookup_transform(target_frame, source_frame, stamp)
        return p @ m[:3, :3].T + m[:3, 3]


def _compose(parts: list[_Part]) -> np.ndarray:
    """The pose of the chain's first frame in the frame above its last edge: the edges'
    matrices multiplied from the top, those to interpolate in one vectorized pass."""
    mats = [p for p in parts if not isinstance(p, tuple)]
    todo = [p for p in parts if isinstance(p, tuple)]
    if todo:
        between = iter(interpolate_poses([w for w, _, _ in todo], np.stack([a for _, a, _ in todo]),
                                         np.stack([b for _, _, b in todo])))
        mats = [next(between) if isinstance(p, tuple) else p for p in parts]
    pose = np.eye(4)
    for m in mats:
        pose = m @ pose
    return pose


class TransformListener:
    """Fills a TransformBuffer from /tf and /tf_static on a node (either rclpy).

    Topics `tf` and `tf_static`, relative to the node's namespace (/tf and /tf_static at the root).
    /tf: reliable, volatile, keep last 100 (tf2_ros' listener QoS), stored at each transform's
    stamp; /tf_static: reliable, transient local, keep last 100, so a late joiner still gets
    every static broadcaster's latched message, stored as static (time-independent). A bad message
    (NaN, zero quaternion, empty frame id) or a refused edge (a loop, a static frame on /tf, the
    frame limit) is logged in one throttled line naming it (and counted in the node's
    input_health, if it has one); the rest of the message is kept and the node keeps running.
    on_update(msg), if given, runs after each message went into the buffer.
    """

    def __init__(self, buffer: TransformBuffer, node: Any, *, tf_topic: str = TF_TOPIC,
                 tf_static_topic: str = TF_STATIC_TOPIC,
                 on_update: Callable[[Any], None] | None = None) -> None:
        from vizzy_runtime.node_tools import guarded
        from vizzy_runtime.ros import (
            DurabilityPolicy,
            HistoryPolicy,
            QoSProfile,
            ReliabilityPolicy,
            message,
        )

        self.buffer = buffer
        self._on_update = on_update
        tf_message = message('tf2_msgs/msg/TFMessage')
        dynamic_qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                                 reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.VOLATILE)
        static_qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                                reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._subs = [
            node.create_subscription(
                tf_message, tf_topic,
                guarded(node, 'skipped a TFMessage', self._on_tf,
                        topic=node.resolve_topic_name(tf_topic)), dynamic_qos),
            node.create_subscription(
                tf_message, tf_static_topic,
                guarded(node, 'skipped a TFMessage', self._on_tf_static,
                        topic=node.resolve_topic_name(tf_static_topic)),
                static_qos),
        ]

    def _on_tf(self, msg: Any) -> None:
        self._store(msg, static=False)

    def _on_tf_static(self, msg: Any) -> None:
        self._store(msg, static=True)

    def _store(self, msg: Any, static: bool) -> None:
        try:
            self.buffer.set_transform_messages(msg.transforms, static=static)
        except TransformRefusedError:
            if self._on_update is not None:    # the rest of the message was stored
                self._on_update(msg)
            raise
        if self._on_update is not None:
            self._on_update(msg)


class FramePoses:
    """Poses of frames in a fixed frame at a stamp, for data stamped in the past.

    A view of the buffer's history (TransformBuffer.lookup_transform at the stamp: each /tf edge
    interpolated there); it asks the buffer to keep at least max_age_s of it. A stamp the history
    does not cover (older than kept, or newer than the newest /tf by more than
    max_extrapolation_s) is answered with the latest transform and counted in latest_answers; no
    chain between the frames: None. :meth:`on_tf` is kept for TransformListener's on_update
    (the buffer keeps the history itself: it does nothing).
    """

    def __init__(self, buffer: TransformBuffer, fixed_frame: str, *, max_age_s: float = 2.0,
                 max_extrapolation_s: float = MAX_EXTRAPOLATION_S) -> None:
        self.buffer = buffer
        self.fixed_frame = fixed_frame
        self.max_age_s = float(max_age_s)
        self.max_extrapolation_s = float(max_extrapolation_s)
        self.latest_answers = 0      #: poses answered with the latest transform, not the stamp's

    @property
    def max_age_s(self) -> float:
        return self._max_age_s

    @max_age_s.setter
    def max_age_s(self, seconds: float) -> None:
        self._max_age_s = float(seconds)
        self.buffer.keep_at_least(self._max_age_s)

    def set_fixed_frame(self, fixed_frame: str) -> None:
        """Another fixed frame for the poses answered from now on."""
        self.fixed_frame = fixed_frame

    def on_tf(self, msg: Any) -> None:
        """Nothing: the buffer keeps each edge's history (kept for TransformListener callers)."""

    def newest(self, frame: str) -> float | None:
        """The newest stamp at which frame's chain to the fixed frame is known (every /tf edge of
        it has a sample), or None (no chain, or a static one)."""
        try:
            return self.buffer.latest_common_time(self.fixed_frame, frame)
        except LookupError:
            return None

    def pose_at(self, frame: str, stamp: float) -> np.ndarray | None:
        """The pose (4x4) of frame in the fixed frame at stamp [s]: interpolated from the
        buffer's history, else the latest transform (counted in latest_answers), else None
        (no chain between the frames)."""
        frame = _strip(frame)
        if not frame:
            return None
        try:
            return self.buffer.lookup_transform(self.fixed_frame, frame, stamp,
                                                max_extrapolation_s=self.max_extrapolation_s)
        except ExtrapolationError:
            pass
        except LookupError:
            return None
        try:
            pose = self.buffer.lookup_transform(self.fixed_frame, frame)
        except LookupError:
            return None
        self.latest_answers += 1
        return pose

"""A small tf buffer: the latest transform of each frame (/tf, /tf_static), composed on demand.

Works on real rclpy and on the bundled runtime alike (it imports only from vizzy_runtime.ros), and
needs no tf2_ros. It is deliberately smaller than tf2:

- it keeps the **latest** transform of each frame (no history, no interpolation, no waiting for a
  time stamp): enough for a node that transforms a request when it arrives, like the gaze
  controller. For fusing data stamped in the past with a moving head, FramePoses keeps the
  poses of the frames a node asks about at each /tf message's stamp, and interpolates;
- transforms are 4x4 homogeneous numpy matrices (float64), and lookup_transform returns one,
  not a geometry_msgs/TransformStamped.

    buffer = TransformBuffer()
    listener = TransformListener(buffer, node)          # subscribes /tf and /tf_static
    T = buffer.lookup_transform('base_link', 'ego')     # maps points in ego into base_link
    points_base = buffer.transform_points('base_link', 'ego', points)   # (N, 3)

As in tf2, lookup_transform(target_frame, source_frame) is the transform that takes coordinates
expressed in source_frame to target_frame (the pose of source_frame in target_frame), and an
unknown or disconnected frame raises LookupError with a message that names it. Like tf2, a leading
'/' in a frame id is ignored, and a frame that gets a new parent is re-parented (a tree, not a
graph).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from vizzy_vision.frames import matrices_from_transforms
from vizzy_vision.pose_history import PoseHistory

__all__ = ['FramePoses', 'TF_STATIC_TOPIC', 'TF_TOPIC', 'TransformBuffer', 'TransformListener']

# Relative, so each namespaced head keeps its own tree (the multi-robot idiom); at the root
# namespace they resolve to /tf and /tf_static, tf2_ros's names.
TF_TOPIC = 'tf'
TF_STATIC_TOPIC = 'tf_static'


def _strip(frame_id: str) -> str:
    return frame_id[1:] if frame_id.startswith('/') else frame_id


def _inverse(m: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    inv = np.eye(4)
    inv[:3, :3] = m[:3, :3].T
    inv[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return inv


class TransformBuffer:
    """The latest parent -> child transforms of a frame tree, composed on lookup. Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        # child -> (parent, 4x4 pose of child in parent)
        self._edges: dict[str, tuple[str, np.ndarray]] = {}

    # --- filling --------------------------------------------------------------------------------

    def set_transforms(self, parents: Sequence[str], children: Sequence[str],
                       matrices: np.ndarray) -> None:
        """Set the pose (N, 4, 4) of each children[i] in parents[i]."""
        matrices = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        if not len(parents) == len(children) == len(matrices):
            raise ValueError(f'{len(parents)} parents, {len(children)} children and '
                             f'{len(matrices)} matrices')
        edges = {}
        for parent, child, m in zip(parents, children, matrices, strict=True):
            parent, child = _strip(parent), _strip(child)
            if not parent or not child:
                raise ValueError(f'empty frame id in transform {parent!r} -> {child!r}')
            if parent == child:
                raise ValueError(f'transform from {parent!r} to itself')
            edges[child] = (parent, m)
        with self._lock:
            self._edges.update(edges)

    def set_transform(self, parent: str, child: str, matrix: np.ndarray) -> None:
        """Set the pose (4x4) of child in parent."""
        self.set_transforms([parent], [child], np.asarray(matrix)[None])

    def set_transform_messages(self, transforms: Iterable[Any]) -> None:
        """Add geometry_msgs/TransformStamped messages (e.g. a tf2_msgs/TFMessage's transforms).

        All of them or none: a message with a non-finite value or a zero quaternion raises
        ValueError naming it, and nothing of the batch is stored.
        """
        transforms = list(transforms)
        if not transforms:
            return
        parents = [t.header.frame_id for t in transforms]
        children = [t.child_frame_id for t in transforms]
        trans = np.array([(t.transform.translation.x, t.transform.translation.y,
                           t.transform.translation.z) for t in transforms], dtype=np.float64)
        quats = np.array([(t.transform.rotation.x, t.transform.rotation.y,
                           t.transform.rotation.z, t.transform.rotation.w) for t in transforms],
                         dtype=np.float64)
        try:
            matrices = matrices_from_transforms(trans, quats)
        except ValueError as exc:
            bad = [f'{p}->{c}' for p, c, tr, q in zip(parents, children, trans, quats, strict=True)
                   if not (np.isfinite(tr).all() and np.isfinite(q).all()
                           and np.linalg.norm(q) >= 1e-9)]
            raise ValueError(f'{exc} in transform(s) {bad}') from None
        self.set_transforms(parents, children, matrices)

    def clear(self) -> None:
        """Forget every transform."""
        with self._lock:
            self._edges.clear()

    # --- queries --------------------------------------------------------------------------------

    def all_frames(self) -> set[str]:
        """Every frame id known (parents and children)."""
        with self._lock:
            return set(self._edges) | {parent for parent, _ in self._edges.values()}

    def parent(self, frame_id: str) -> str | None:
        """The parent of frame_id, or None for a root or an unknown frame."""
        with self._lock:
            edge = self._edges.get(_strip(frame_id))
        return edge[0] if edge else None

    def can_transform(self, target_frame: str, source_frame: str) -> bool:
        """Is there a chain between the two frames?"""
        try:
            self.lookup_transform(target_frame, source_frame)
        except LookupError:
            return False
        return True

    @staticmethod
    def _pose_in_root(edges: dict[str, tuple[str, np.ndarray]],
                      frame: str) -> tuple[str, np.ndarray]:
        """The root of frame's tree and frame's pose (4x4) in it."""
        chain = [frame]
        pose = np.eye(4)
        while chain[-1] in edges:
            parent, m = edges[chain[-1]]
            if parent in chain:
                raise LookupError(f'the tf tree has a loop through {parent!r}: '
                                  f'{" -> ".join(chain + [parent])}')
            chain.append(parent)
            pose = m @ pose
        return chain[-1], pose

    def lookup_transform(self, target_frame: str, source_frame: str) -> np.ndarray:
        """4x4 transform taking coordinates in source_frame to target_frame (latest data).

        Raises LookupError naming the frame that is not in the tree, or both roots when the two
        frames are in different trees.
        """
        target, source = _strip(target_frame), _strip(source_frame)
        if not target or not source:
            raise LookupError('empty frame id: every transform needs a named frame '
                              f'(target {target_frame!r}, source {source_frame!r})')
        if target == source:
            return np.eye(4)
        with self._lock:
            edges = dict(self._edges)
        known = set(edges) | {parent for parent, _ in edges.values()}
        missing = [f for f in (source, target) if f not in known]
        if missing:
            shown = ', '.join(sorted(known)[:20]) + (', ...' if len(known) > 20 else '')
            which = ' and '.join(repr(f) for f in missing)
            what = (f'frame {which} is' if len(missing) == 1 else f'frames {which} are')
            raise LookupError(
                f'{what} not in the tf tree '
                f'(looking up {source!r} in {target!r}); known frames: {shown or "none yet"}')
        s_root, s_pose = self._pose_in_root(edges, source)
        t_root, t_pose = self._pose_in_root(edges, target)
        if s_root != t_root:
            raise LookupError(f'frames {source!r} and {target!r} are not connected: {source!r} '
                              f'is under {s_root!r}, {target!r} under {t_root!r}')
        # Both poses are in the common root: target <- root <- source.
        return _inverse(t_pose) @ s_pose

    def transform_points(self, target_frame: str, source_frame: str,
                         points: np.ndarray) -> np.ndarray:
        """(N, 3) points in source_frame -> (N, 3) in target_frame (or one (3,) point)."""
        p = np.asarray(points, dtype=np.float64)
        m = self.lookup_transform(target_frame, source_frame)
        return p @ m[:3, :3].T + m[:3, 3]


class TransformListener:
    """Fills a TransformBuffer from /tf and /tf_static on a node (either rclpy).

    Topics `tf` and `tf_static`, relative to the node's namespace (/tf and /tf_static at the root).
    /tf: reliable, volatile, keep last 100 (tf2_ros' listener QoS); /tf_static: reliable,
    transient local, keep last 100, so a late joiner still gets every static broadcaster's latched
    message. A bad message (NaN, zero quaternion, empty frame id) is logged, throttled, and skipped;
    the node keeps running. on_update(msg), if given, runs after each message went into the buffer
    (e.g. to keep a history of a frame at the message's stamp).
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
                guarded(node, 'skipped a TFMessage', self._on_tf,
                        topic=node.resolve_topic_name(tf_static_topic)),
                static_qos),
        ]

    def _on_tf(self, msg: Any) -> None:
        self.buffer.set_transform_messages(msg.transforms)
        if self._on_update is not None:
            self._on_update(msg)


class FramePoses:
    """Poses of frames in a fixed frame at the stamps of /tf messages, for data stamped earlier.

    Give :meth:`on_tf` to TransformListener's on_update. The simulator (and a robot's
    robot_state_publisher) publishes the head's transforms together at each joint reading, so
    after a message the buffer holds the chain as it was at that message's stamp: the pose of
    every frame asked about so far is recorded then (vizzy_vision.pose_history.PoseHistory), and
    :meth:`pose_at` interpolates between the records around a stamp. A frame starts being
    recorded when first asked about; a frame whose chain is static (no /tf stamps) is answered
    with the latest transform.
    """

    def __init__(self, buffer: TransformBuffer, fixed_frame: str, *, max_age_s: float = 2.0,
                 max_extrapolation_s: float = 0.05) -> None:
        self.buffer = buffer
        self.fixed_frame = fixed_frame
        self.max_age_s = float(max_age_s)
        self.max_extrapolation_s = float(max_extrapolation_s)
        self._histories: dict[str, PoseHistory] = {}
        self._lock = threading.Lock()
        self.latest_answers = 0      #: poses answered with the latest transform, not the stamp's

    def set_fixed_frame(self, fixed_frame: str) -> None:
        """Another fixed frame: the records so far are forgotten."""
        with self._lock:
            self.fixed_frame = fixed_frame
            self._histories.clear()

    def on_tf(self, msg: Any) -> None:
        """Record the pose of each frame asked about, at the stamp of a /tf message."""
        if not msg.transforms:
            return
        stamp = max(t.header.stamp.sec + 1e-9 * t.header.stamp.nanosec for t in msg.transforms)
        with self._lock:
            items = list(self._histories.items())
            fixed = self.fixed_frame
        for frame, history in items:
            try:
                pose = self.buffer.lookup_transform(fixed, frame)
            except LookupError:
                continue
            with self._lock:
                history.add(stamp, pose[:3, :3], pose[:3, 3])

    def newest(self, frame: str) -> float | None:
        """The stamp of frame's newest record, or None (not asked about yet, or none yet)."""
        with self._lock:
            history = self._histories.get(_strip(frame))
            return history.newest if history is not None and len(history) else None

    def pose_at(self, frame: str, stamp: float) -> np.ndarray | None:
        """The pose (4x4) of frame in the fixed frame at stamp [s]: interpolated between the
        records around it, else the latest transform (counted in latest_answers), else None
        (no chain between the frames)."""
        frame = _strip(frame)
        if not frame:
            return None
        with self._lock:
            history = self._histories.get(frame)
            if history is None:
                history = self._histories[frame] = PoseHistory(self.max_age_s,
                                                               self.max_extrapolation_s)
            pose = history.pose_at(stamp)
            fixed = self.fixed_frame
        if pose is not None:
            return pose
        try:
            pose = self.buffer.lookup_transform(fixed, frame)
        except LookupError:
            return None
        self.latest_answers += 1
        return pose

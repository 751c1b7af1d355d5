"""Rendered left-eye views of the cluttered tabletop scene, with every object's class and box.

vizzy_sim_bridge's `tabletop(seed)` (cans, bottles, a jar with a lid, a lying can, a pipe,
boxes, spheres and a U-shaped handle on a wooden table before a dead-leaves wall) seen by the
left eye camera at 640x480 with the head at given joints, as the `sim` node publishes it. The
ground truth of each object: its class (the scene's `kind`, one of object_views.CLASSES), the
projection of its body origin and the box of its geoms' projected bounding-box corners
(clipped), and whether its centre is visible (the rendered depth there is not much nearer than
the object: nothing occludes it).

Used to measure recognition where the node runs (experiments/foveated_recognition.py
--tabletop) and to add cluttered views to the CNN's training set (train_classifier.py); the
node does not import it. Needs mujoco and vizzy_sim_bridge.

`TabletopViews(scene=...)` renders another scene builder the same way (e.g. `visual_search`:
its cans are objects, their stands are not); `TableView.extents` holds the boxes of every
object in front of the camera that overlaps the image, centre in view or not (for choosing
fixations on no object: training.background_views).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .object_views import CAMERA, CLASSES

#: head joints of the demo's tabletop start (neck pan, neck tilt, eyes tilt, left eye, right eye)
DEFAULT_JOINTS = (0.0, 0.2, 0.15, 0.0, 0.0)


@dataclass(frozen=True)
class TableObject:
    """One object in a view: class index, name, box (x0, y0, x1, y1) px (inclusive, clipped),
    centre (u, v) px, depth [m] along the optical axis, and whether its centre is unoccluded."""

    label: int
    name: str
    box: tuple[int, int, int, int]
    centre: tuple[float, float]
    depth: float
    visible: bool

    @property
    def area(self) -> int:
        return (self.box[2] - self.box[0] + 1) * (self.box[3] - self.box[1] + 1)


@dataclass(frozen=True)
class TableView:
    seed: int
    joints: tuple[float, ...]
    rgb: np.ndarray                     #: (H, W, 3) uint8
    objects: list[TableObject]          #: objects whose centre lies in the image
    #: (x0, y0, x1, y1) px boxes of every object in front of the camera overlapping the image
    extents: list[tuple[int, int, int, int]] = field(default_factory=list)


def random_joints(rng: np.random.Generator) -> tuple[float, ...]:
    """A head pose looking over the table: neck pan +-0.4 rad, neck tilt 0.05-0.35 rad, eyes
    tilt 0-0.35 rad, version +-0.15 rad (both eyes the same)."""
    version = float(rng.uniform(-0.15, 0.15))
    return (float(rng.uniform(-0.4, 0.4)), float(rng.uniform(0.05, 0.35)),
            float(rng.uniform(0.0, 0.35)), version, version)


def object_at(objects: list[TableObject], u: float, v: float) -> TableObject | None:
    """The object "under" pixel (u, v): of the visible objects whose box holds it, the one whose
    centre is nearest; if no box holds it, the visible object with the nearest centre."""
    cand = [o for o in objects if o.visible] or objects
    if not cand:
        return None
    inside = [o for o in cand if o.box[0] <= u <= o.box[2] and o.box[1] <= v <= o.box[3]]
    pool = inside or cand
    return min(pool, key=lambda o: (o.centre[0] - u) ** 2 + (o.centre[1] - v) ** 2)


class TabletopViews:
    """Renders tabletop(seed) from the left eye; one GL context per scene seed, one per thread.

    scene: another scene builder (seed -> vizzy_sim_bridge Scene, e.g. scenes.visual_search);
    its objects whose kind is one of CLASSES are the objects, the rest is background.
    """

    def __init__(self, width: int = 640, height: int = 480,
                 scene: Callable[[int], Any] | None = None) -> None:
        from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix

        self.width, self.height = int(width), int(height)
        self._scene_builder = scene
        self.k = camera_matrix(self.width, self.height, EYE_HFOV_DEG)
        self._seed: int | None = None
        self._renderer: Any = None
        self._points: list[tuple[int, str, np.ndarray]] | None = None

    def _load(self, seed: int) -> None:
        import mujoco

        from vizzy_sim_bridge.core.model import CameraSpec, HeadSimulation
        from vizzy_sim_bridge.core.render import CameraRenderer
        from vizzy_sim_bridge.core.scenes import tabletop
        from vizzy_vision.camera import EYE_HFOV_DEG

        scene = (self._scene_builder or tabletop)(seed)
        sim = HeadSimulation(scene, eye=CameraSpec(self.width, self.height, EYE_HFOV_DEG))
        if self._renderer is not None:
            self._renderer.close()
        m = sim.model
        self._renderer = CameraRenderer(m, self.width, self.height)
        self._sim, self._data, self._seed = sim, mujoco.MjData(m), seed
        self._cam = self._renderer.camera_id(CAMERA)
        self._bodies: list[tuple[int, str, np.ndarray]] = []
        for o in scene.objects:
            if o.kind not in CLASSES:
                continue
            b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, o.name)
            if b >= 0:
                self._bodies.append((CLASSES.index(o.kind), o.name,
                                     np.nonzero(m.geom_bodyid == b)[0]))
        self._body_ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n)
                          for _, n, _ in self._bodies]
        self._points = None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._seed = None

    def __enter__(self) -> TabletopViews:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _project(self, points: np.ndarray, pos: np.ndarray, rot: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        local = (points - pos) @ rot                        # MuJoCo camera: looks along -z
        x, y, z = local[:, 0], -local[:, 1], -local[:, 2]
        fx, cx, cy = self.k[0, 0], self.k[0, 2], self.k[1, 2]
        z_safe = np.maximum(z, 1e-3)
        return np.column_stack([fx * x / z_safe + cx, fx * y / z_safe + cy]), z

    def object_points(self, seed: int) -> list[tuple[int, str, np.ndarray]]:
        """(class index, body name, body origin in the world frame [m]) of every object of
        scene seed (the scene's initial state, as view renders it): where a gaze controller
        told of the object would fixate it. RuntimeError as view."""
        import mujoco

        if self._seed != seed:
            self._load(seed)
        if self._points is None:
            sim = self._sim
            d = mujoco.MjData(sim.model)            # leaves the last view's state alone
            d.qpos[:] = sim.data.qpos
            mujoco.mj_forward(sim.model, d)
            self._points = [(label, name, d.xpos[body].copy()) for (label, name, _), body
                            in zip(self._bodies, self._body_ids, strict=True)]
        return list(self._points)

    def object_under(self, u: float, v: float) -> str | None:
        """Name of the object whose geom the ray through pixel (u, v) of the last view hits
        first (what the eye sees there); None if the ray hits no object (or nothing)."""
        import mujoco

        if self._seed is None:
            raise RuntimeError('no view rendered yet')
        m, d = self._sim.model, self._data
        fx, cx, cy = self.k[0, 0], self.k[0, 2], self.k[1, 2]
        rot = d.cam_xmat[self._cam].reshape(3, 3)
        ray = rot @ np.array([(u - cx) / fx, -(v - cy) / fx, -1.0])   # camera looks along -z
        geom = np.full(1, -1, np.int32)
        mujoco.mj_ray(m, d, d.cam_xpos[self._cam], ray / np.linalg.norm(ray), None, 1,
                      int(m.cam_bodyid[self._cam]), geom)
        if geom[0] < 0:
            return None
        body = int(m.geom_bodyid[geom[0]])
        return next((name for (_, name, _), b in zip(self._bodies, self._body_ids, strict=True)
                     if b == body), None)

    def view(self, seed: int, joints: tuple[float, ...] = DEFAULT_JOINTS) -> TableView:
        """tabletop(seed) from the left eye with the head at joints (JOINT_NAMES order, rad).
        RuntimeError if the scene builder cannot place the seed's objects."""
        import mujoco

        from vizzy_sim_bridge.core.scenes import geom_box_corners

        if self._seed != seed:
            self._load(seed)
        sim, d = self._sim, self._data
        d.qpos[:] = sim.data.qpos
        d.qpos[sim.qpos_adr] = np.asarray(joints, float)
        mujoco.mj_forward(sim.model, d)
        rgb, depth = self._renderer.render(d, self._cam, depth=True)
        pos = d.cam_xpos[self._cam].copy()
        rot = d.cam_xmat[self._cam].reshape(3, 3).copy()
        w, h = self.width, self.height
        objects, extents = [], []
        for (label, name, geoms), body in zip(self._bodies, self._body_ids, strict=True):
            corners = geom_box_corners(sim.model, d, geoms)
            cuv, cz = self._project(corners, pos, rot)
            cuv = cuv[cz > 0.05]
            if not len(cuv):
                continue                                    # wholly behind the camera
            x0, y0 = np.floor(cuv.min(axis=0)).astype(int)
            x1, y1 = np.ceil(cuv.max(axis=0)).astype(int)
            box = (max(int(x0), 0), max(int(y0), 0), min(int(x1), w - 1), min(int(y1), h - 1))
            if box[0] <= box[2] and box[1] <= box[3]:
                extents.append(box)
            (uv,), (z,) = self._project(d.xpos[body][None], pos, rot)
            if z <= 0.05 or not (0 <= uv[0] < w and 0 <= uv[1] < h):
                continue
            half = 0.5 * float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))
            seen = float(depth[int(uv[1]), int(uv[0])])
            objects.append(TableObject(label, name, box, (float(uv[0]), float(uv[1])), float(z),
                                       bool(seen > z - half - 0.02)))
        return TableView(seed, tuple(float(j) for j in joints), rgb.copy(), objects, extents)


__all__ = ['DEFAULT_JOINTS', 'TableObject', 'TableView', 'TabletopViews', 'object_at',
           'random_joints']

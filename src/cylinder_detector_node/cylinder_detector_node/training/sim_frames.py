"""Rendered RGB-D tabletop frames from the simulator, with per-object ground truth.

Used by the classifier's training script, the Table 4.2 experiment, the benchmark and the tests
(not by the node): vizzy_sim_bridge's `tabletop(seed)` scene (cans, bottles, a jar, a lying can
and pipe among boxes, spheres and a U-shaped handle), rendered by its RGB-D camera exactly as the
`sim` node publishes it (640x480, Xtion-like depth noise), as an organized cloud in the camera's
optical frame plus the colour image, and the objects' ground truth moved into that frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: head joints of the bags' tabletop recording (neck pan, neck tilt, eyes tilt, left, right eye)
DEFAULT_JOINTS = (0.0, 0.2, 0.15, 0.0, 0.0)


@dataclass(frozen=True)
class SimObject:
    name: str
    shape: str                #: 'cylinder', 'box' or 'sphere' (the handle is a 'box')
    centre: Array             #: camera optical frame [m]
    axis: Array | None        #: cylinders: unit axis in the camera frame
    radius: float | None
    height: float | None
    rotation: Array           #: object frame -> camera frame (boxes)
    size: Array               #: full extents (boxes: x, y, z in their frame; spheres: 2r)

    @property
    def is_cylinder(self) -> bool:
        return self.shape == 'cylinder'

    def surface_distance(self, pts: Array) -> Array:
        """Distance of each (N, 3) point to the object's surface (0 inside)."""
        v = np.asarray(pts, float).reshape(-1, 3) - self.centre
        if self.is_cylinder and self.axis is not None:
            assert self.radius is not None and self.height is not None   # set for cylinders
            t = np.clip(v @ self.axis, -0.5 * self.height, 0.5 * self.height)
            return np.maximum(np.linalg.norm(v - t[:, None] * self.axis, axis=1) - self.radius, 0.0)
        if self.shape == 'sphere':
            return np.maximum(np.linalg.norm(v, axis=1) - 0.5 * self.size[0], 0.0)
        local = v @ self.rotation                       # camera -> object frame
        return np.linalg.norm(np.maximum(np.abs(local) - 0.5 * self.size, 0.0), axis=1)


@dataclass(frozen=True)
class SimFrame:
    seed: int
    joints: tuple[float, ...]
    image: NDArray[np.uint8]                       #: (H, W, 3) RGB
    cloud: Array                                   #: (H, W, 3) camera optical frame, NaN invalid
    intrinsics: tuple[float, float, float, float]  #: fx, fy, cx, cy
    objects: list[SimObject]                       #: everything but the table

    def surface_distances(self, pts: Array) -> Array:
        """(N, n_objects) distance of each point to each object's surface."""
        return np.stack([o.surface_distance(pts) for o in self.objects], axis=1)


class SimRenderer:
    """Renders tabletop frames: one GL context, reused across seeds (one per thread)."""

    def __init__(self, width: int = 640, height: int = 480) -> None:
        from vizzy_sim_bridge.core.model import RGBD_CAMERA
        from vizzy_vision.camera import camera_matrix
        self.width, self.height = width, height
        k = camera_matrix(width, height, RGBD_CAMERA.hfov_deg)
        self.k = k
        self.intrinsics = (float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]))
        self._renderer: Any = None
        self._model_key: Any = None
        self._scene: Any = None
        self._sim: Any = None
        self._data: Any = None

    def frame(self, seed: int, joints: tuple[float, ...] = DEFAULT_JOINTS,
              noise_seed: int | None = None, depth_noise: float | None = None) -> SimFrame:
        """tabletop(seed) seen by the RGB-D camera with the head at `joints` (JOINT_NAMES order,
        radians); depth noise seeded by (seed, noise_seed), coefficient depth_noise (default the
        Xtion's; 0 = none). RuntimeError if the scene builder cannot place the seed's objects."""
        import mujoco

        from vizzy_sim_bridge.core.model import HeadSimulation
        from vizzy_sim_bridge.core.render import CameraRenderer
        from vizzy_sim_bridge.core.rgbd import XTION_SIGMA_COEFFICIENT, DepthProjector, noisy_depth
        from vizzy_sim_bridge.core.scenes import tabletop
        from vizzy_vision.frames import rotation_matrix
        from vizzy_vision.kinematics import JOINT_NAMES, RGBD_FRAME, frames_in_base

        if self._model_key != seed:   # one model (and GL context with its textures) per scene
            scene = tabletop(seed)
            sim = HeadSimulation(scene)
            if self._renderer is not None:
                self._renderer.close()
            self._renderer = CameraRenderer(sim.model, self.width, self.height)
            self._scene, self._sim, self._model_key = scene, sim, seed
            self._data = mujoco.MjData(sim.model)
        scene, sim, data = self._scene, self._sim, self._data
        q = dict(zip(JOINT_NAMES, joints, strict=True))
        data.qpos[:] = sim.data.qpos
        data.qpos[sim.qpos_adr] = np.asarray(joints, float)
        mujoco.mj_forward(sim.model, data)
        rgb, depth = self._renderer.render(data, 'rgbd_camera', depth=True, width=self.width,
                                           height=self.height)
        rng = np.random.default_rng(
            np.random.SeedSequence([seed, 99 if noise_seed is None else noise_seed]))
        coeff = XTION_SIGMA_COEFFICIENT if depth_noise is None else depth_noise
        z = noisy_depth(depth, rng if coeff > 0 else None, coeff)
        packed = DepthProjector(self.k, self.width, self.height).cloud(z, rgb)
        cloud = np.stack([packed['x'], packed['y'], packed['z']], axis=-1).astype(np.float64)
        # ground truth: base_link -> camera optical frame (the sim's joints equal the targets at
        # t=0)
        t_cam = frames_in_base(q)[RGBD_FRAME]
        r_cb, p_cb = t_cam[:3, :3].T, -t_cam[:3, :3].T @ t_cam[:3, 3]
        objects = []
        for o in scene.objects:
            if o.name == 'table' or o.role == 'support':
                continue
            axis = None if o.axis is None else r_cb @ np.asarray(o.axis, float)
            objects.append(SimObject(o.name, o.shape,
                                     r_cb @ np.asarray(o.position, float) + p_cb, axis,
                                     o.radius, o.height, r_cb @ rotation_matrix(o.orientation),
                                     np.asarray(o.size, float)))
        return SimFrame(seed, tuple(joints), rgb.copy(), cloud, self.intrinsics, objects)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._model_key = None


def random_joints(rng: np.random.Generator) -> tuple[float, ...]:
    """A head pose that keeps the table in the RGB-D camera's view: pan +-0.35 rad, tilt 0-0.3."""
    return (float(rng.uniform(-0.35, 0.35)), float(rng.uniform(0.0, 0.3)), 0.15, 0.0, 0.0)


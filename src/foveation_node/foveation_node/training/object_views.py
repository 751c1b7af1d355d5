"""Rendered views of single objects for training and testing the recognition CNN.

One MuJoCo model (vizzy_sim_bridge's head, `build_mjcf`) holds a few shape variants of every
object class of our scenes as mocap bodies, a textured backdrop and a table top; each view
moves one variant in front of the left eye camera, at a random depth and pixel position (off
centre: anywhere but the outer border), with a random pose, colours, backdrop texture and
lighting, and renders it at the eye camera's 640x480 with `CameraRenderer`. The ground truth
is the class and the object's bounding box in the image (projected corners of its geoms'
boxes, clipped to the image).

The thesis used ImageNet photographs (one object each, mostly centred); these are our
simulator's equivalent: one object per image, but anywhere in the image, so that foveation at
the image centre can miss it (section 2.4.2, Figs. 2.8-2.9).

Needs mujoco and vizzy_sim_bridge (training, experiments, tests); the node does not import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from vizzy_vision.frames import (
    axis_angle_matrix,
    from_wxyz,
    matrix_to_quaternion,
    rotation_matrix,
    to_wxyz,
)

CLASSES: tuple[str, ...] = ('can', 'bottle', 'jar', 'box', 'sphere', 'handle', 'pipe')
CAMERA = 'left_camera'
PARK = np.array([0.0, 0.0, -50.0])      # unused variants wait below the floor, out of view
TEXTURES = 6                            # backdrop / table textures in the model


@dataclass(frozen=True)
class View:
    """One rendered view: rgb (H, W, 3) uint8, its class, and the object's box (x0, y0, x1, y1) px
    (inclusive, clipped to the image) and centre (u, v) px (projection of the body origin)."""

    rgb: np.ndarray
    label: int
    box: tuple[int, int, int, int]
    centre: tuple[float, float]


def _f(*values: float) -> str:
    return ' '.join(f'{float(v):.6g}' for v in values)


def _cyl(name: str, r: float, half: float, z: float = 0.0) -> str:
    return f'<geom name="{name}" type="cylinder" pos="0 0 {z:.6g}" size="{_f(r, half)}"/>'


def _variants() -> dict[str, list[str]]:
    """MJCF geoms (body frame, z up, origin at the centre) of every class's shape variants.

    Geom names end in _a (main colour) or _b (second colour: bands, lids, caps); the sizes are
    the ranges of vizzy_sim_bridge.core.scenes.tabletop.
    """
    out: dict[str, list[str]] = {c: [] for c in CLASSES}
    for lid in (False, True):                       # soda can: 66 x 122 mm, printed band, rim
        g = [_cyl('a', 0.033, 0.061), _cyl('b', 0.0335, 0.122 * 0.18),
             _cyl('b2', 0.029, 0.0045, 0.057)]
        if lid:
            g.append(_cyl('b3', 0.036, 0.004, 0.065))
        out['can'].append(''.join(g))
    for r, h in ((0.030, 0.14), (0.035, 0.17), (0.040, 0.20)):   # bottle: body, neck, cap, label
        out['bottle'].append(''.join([
            _cyl('a', r, h / 2), _cyl('a2', 0.013, 0.03, h / 2 + 0.03),
            _cyl('b', 0.015, 0.01, h / 2 + 0.07), _cyl('b2', r + 0.0005, h * 0.2)]))
    for r, h in ((0.040, 0.08), (0.045, 0.10), (0.050, 0.12)):   # jar with a screw lid
        out['jar'].append(_cyl('a', r, h / 2) + _cyl('b', r + 0.003, 0.0075, h / 2 + 0.0075))
    for sx, sy, sz in ((0.05, 0.08, 0.16), (0.14, 0.10, 0.05), (0.09, 0.09, 0.10)):
        out['box'].append(f'<geom name="a" type="box" size="{_f(sx / 2, sy / 2, sz / 2)}"/>')
    for r in (0.030, 0.045):
        out['sphere'].append(f'<geom name="a" type="sphere" size="{r}"/>')
    for span, post, rr in ((0.10, 0.04, 0.008), (0.14, 0.06, 0.010)):   # U-shaped handle
        hz = (post + rr) / 2
        out['handle'].append(''.join(
            f'<geom name="a{i}" type="capsule" fromto="{_f(*ends)}" size="{rr}"/>'
            for i, ends in enumerate(((-span / 2, 0, -hz + rr, -span / 2, 0, hz - rr),
                                      (span / 2, 0, -hz + rr, span / 2, 0, hz - rr),
                                      (-span / 2, 0, hz - rr, span / 2, 0, hz - rr)))))
    for r, length in ((0.018, 0.22), (0.024, 0.27), (0.030, 0.32)):   # pipe (axis z here)
        out['pipe'].append(_cyl('a', r, length / 2))
    return out


def _soften(texture: np.ndarray) -> np.ndarray:
    import cv2
    blurred = cv2.GaussianBlur(texture, (0, 0), 3.0).astype(np.float32)
    return (0.5 * blurred + 0.5 * blurred.mean(axis=(0, 1))).astype(np.uint8)


def build_scene(seed: int = 0) -> Any:
    """A vizzy_sim_bridge Scene: every variant as a mocap body, a backdrop and a table top.

    Geoms are named '<class>_<variant>_<part>'; backdrop and table textures come from the
    scenes' own procedural textures (rich dead-leaves walls, wood, facade, pavement).
    """
    from vizzy_sim_bridge.core import scenes as sc

    rng = np.random.default_rng(np.random.SeedSequence([seed, 41]))
    # the dead-leaves walls softened (blurred, half contrast): at full strength their clutter
    # at the scale of our small objects left a small CNN at chance
    soft = [_soften(sc.rich_texture(rng, 512)) for _ in range(2)]
    textures = [*soft, sc.wood_texture(rng), sc._facade(rng), sc._pavement(rng),
                sc.wood_texture(rng)[:, ::-1].transpose(1, 0, 2).copy()]
    assert len(textures) == TEXTURES
    assets, files = [], {}
    for i, img in enumerate(textures):
        files[f'bg{i}.png'] = sc.png_bytes(img)
        assets.append(f'<texture name="bg{i}_tex" type="2d" file="bg{i}.png"/>')
        assets.append(f'<material name="bg{i}" texture="bg{i}_tex" texrepeat="1 1" '
                      f'specular="0.05" shininess="0.1" reflectance="0"/>')
    body = [f'<body name="backdrop" mocap="true" pos="{_f(*PARK)}"><geom name="backdrop" '
            f'type="plane" size="4 4 0.5" material="bg0"/></body>',
            f'<body name="table" mocap="true" pos="{_f(*PARK)}"><geom name="table" type="plane" '
            f'size="2 2 0.5" material="bg2"/></body>']
    for cls, variants in _variants().items():
        for k, geoms in enumerate(variants):
            name = f'{cls}_{k}'
            geoms = geoms.replace('name="', f'name="{name}_')
            body.append(f'<body name="{name}" mocap="true" pos="{_f(*PARK)}">{geoms}</body>')
    return sc.Scene(name='foveation_objects', seed=seed, assets_xml='\n'.join(assets),
                    worldbody_xml='\n'.join(body), assets=files,
                    description='object classes for the foveation CNN')


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return rotation_matrix(from_wxyz(q))   # q drawn in MuJoCo order (w, x, y, z)


def _hsv_colour(rng: np.random.Generator, sat: tuple[float, float] = (0.0, 1.0)) -> np.ndarray:
    import colorsys
    rgb = colorsys.hsv_to_rgb(float(rng.random()), float(rng.uniform(*sat)),
                              float(rng.uniform(0.2, 1.0)))
    return np.array([*rgb, 1.0])


class ObjectViews:
    """Renders random single-object views (see the module docstring); one per thread.

    width x height: the image size (the eye camera's 640x480 by default; its horizontal field
    of view, 85.4 deg, is kept at any size).
    """

    def __init__(self, width: int = 640, height: int = 480, seed: int = 0) -> None:
        import mujoco

        from vizzy_sim_bridge.core.model import CameraSpec, compile_model
        from vizzy_sim_bridge.core.render import CameraRenderer
        from vizzy_vision.camera import EYE_HFOV_DEG, camera_matrix

        self.width, self.height = int(width), int(height)
        spec = CameraSpec(self.width, self.height, EYE_HFOV_DEG)
        self.model, _ = compile_model(build_scene(seed), eye=spec)
        self.data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, self.data)
        self.renderer = CameraRenderer(self.model, self.width, self.height)
        self.k = camera_matrix(self.width, self.height, EYE_HFOV_DEG)
        m = self.model
        cid = self.renderer.camera_id(CAMERA)
        self._cam_pos = self.data.cam_xpos[cid].copy()
        self._cam_rot = self.data.cam_xmat[cid].reshape(3, 3).copy()   # MuJoCo: looks along -z
        self._mocap: dict[str, int] = {}
        self._geoms: dict[str, np.ndarray] = {}
        self._variants: list[list[str]] = [[] for _ in CLASSES]
        for b in range(m.nbody):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
            if name and m.body_mocapid[b] >= 0:
                self._mocap[name] = int(m.body_mocapid[b])
                self._geoms[name] = np.nonzero(m.geom_bodyid == b)[0]
                cls = name.rsplit('_', 1)[0]
                if cls in CLASSES:
                    self._variants[CLASSES.index(cls)].append(name)
        self._geom_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or ''
                            for g in range(m.ngeom)]
        self._materials = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_MATERIAL, f'bg{i}')
                           for i in range(TEXTURES)]
        self._light = dict(ambient=m.vis.headlight.ambient.copy(),
                           diffuse=m.vis.headlight.diffuse.copy())
        self._shown: list[str] = []

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self) -> ObjectViews:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------------------ placement

    def _world_point(self, u: float, v: float, depth: float) -> np.ndarray:
        """The point at depth [m] along the optical axis that projects onto pixel (u, v)."""
        fx, cx, cy = self.k[0, 0], self.k[0, 2], self.k[1, 2]
        local = np.array([(u - cx) / fx, -(v - cy) / fx, -1.0]) * depth   # MuJoCo camera frame
        return self._cam_pos + self._cam_rot @ local

    def _place(self, body: str, pos: np.ndarray, rot: np.ndarray) -> None:
        i = self._mocap[body]
        self.data.mocap_pos[i] = pos
        self.data.mocap_quat[i] = to_wxyz(matrix_to_quaternion(rot))
        self._shown.append(body)

    def _project(self, points: np.ndarray) -> np.ndarray:
        local = (points - self._cam_pos) @ self._cam_rot          # camera frame, -z forward
        x, y, z = local[:, 0], -local[:, 1], -local[:, 2]
        fx, cx, cy = self.k[0, 0], self.k[0, 2], self.k[1, 2]
        return np.column_stack([fx * x / z + cx, fx * y / z + cy])

    def render(self, label: int, rng: np.random.Generator, margin: float = 0.08,
               depth: tuple[float, float] = (0.25, 0.55),
               centre: tuple[float, float] | None = None) -> View:
        """A random view of class `label` (index in CLASSES).

        The object's centre lands on a uniform pixel at least margin x the image size from the
        border (or on `centre`), depth [m] along the optical axis uniform in `depth`.
        """
        import mujoco

        from vizzy_sim_bridge.core.scenes import geom_box_corners

        m, d = self.model, self.data
        for name in self._shown:                              # park the previous view
            d.mocap_pos[self._mocap[name]] = PARK
        self._shown = []
        cls = CLASSES[label]
        body = self._variants[label][int(rng.integers(len(self._variants[label])))]
        w, h = self.width, self.height
        if centre is None:
            u = float(rng.uniform(margin * w, (1 - margin) * w - 1))
            v = float(rng.uniform(margin * h, (1 - margin) * h - 1))
        else:
            u, v = centre
        z = float(rng.uniform(*depth))
        pos = self._world_point(u, v, z)

        # pose: upright with a random yaw and a slight tilt, or lying (pipes, some cans)
        yaw = axis_angle_matrix([0, 0, 1], float(rng.uniform(0, 2 * math.pi)))
        tilt = axis_angle_matrix([1, 0, 0], float(rng.normal(0, 0.15)))
        lying = cls == 'pipe' or (cls in ('can', 'bottle') and rng.random() < 0.25)
        if cls == 'sphere':
            rot = _random_rotation(rng)
        elif lying:
            rot = yaw @ axis_angle_matrix([1, 0, 0], math.pi / 2 + float(rng.normal(0, 0.2)))
        else:
            rot = yaw @ tilt
        self._place(body, pos, rot)

        # colours: a main one and a second one for bands, lids and caps
        main, second = _hsv_colour(rng), _hsv_colour(rng)
        if cls == 'pipe' and rng.random() < 0.5:               # bare metal
            main = np.array([*(np.full(3, rng.uniform(0.4, 0.75))), 1.0])
        for g in self._geoms[body]:
            part = self._geom_names[g].rsplit('_', 1)[1]
            m.geom_rgba[g] = main if part.startswith('a') else second

        # backdrop facing the camera (tilted), 0.3-2.5 m behind the object, any texture
        back = self._world_point(float(rng.uniform(0, w)), float(rng.uniform(0, h)),
                                 z + float(rng.uniform(0.3, 2.5)))
        facing = axis_angle_matrix([1, 0, 0], float(rng.uniform(-0.5, 0.5))) @ \
            axis_angle_matrix([0, 1, 0], float(rng.uniform(-0.5, 0.5)))
        self._place('backdrop', back, self._cam_rot @ facing)
        m.geom_matid[self._geoms['backdrop'][0]] = self._materials[int(rng.integers(TEXTURES))]
        mujoco.mj_kinematics(m, d)
        corners = geom_box_corners(m, d, self._geoms[body])
        if rng.random() < 0.5:                                 # standing on a table top
            top = pos.copy()
            top[2] = corners[:, 2].min()
            self._place('table', top, np.eye(3))
            m.geom_matid[self._geoms['table'][0]] = self._materials[int(rng.integers(TEXTURES))]

        # lighting: the headlight and the sun, each dimmer or brighter
        m.vis.headlight.ambient[:] = self._light['ambient'] * rng.uniform(0.5, 1.5)
        m.vis.headlight.diffuse[:] = self._light['diffuse'] * rng.uniform(0.4, 1.6)
        m.light_diffuse[0] = rng.uniform(0.2, 0.9)
        m.light_dir[0] = [rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), -1.0]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        rgb, _ = self.renderer.render(d, CAMERA)
        uv = self._project(corners)
        x0, y0 = np.floor(uv.min(axis=0)).astype(int)
        x1, y1 = np.ceil(uv.max(axis=0)).astype(int)
        box = (max(int(x0), 0), max(int(y0), 0), min(int(x1), w - 1), min(int(y1), h - 1))
        return View(rgb.copy(), label, box, (u, v))

    def dataset(self, n: int, seed: int, **kwargs: Any) -> list[View]:
        """n views with balanced classes (class i for view j = j mod len(CLASSES))."""
        rng = np.random.default_rng(seed)
        return [self.render(j % len(CLASSES), rng, **kwargs) for j in range(n)]


__all__ = ['CAMERA', 'CLASSES', 'ObjectViews', 'View', 'build_scene']

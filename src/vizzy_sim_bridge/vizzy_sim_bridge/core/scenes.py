"""Seeded scenes for the simulated head: MJCF fragments plus ground truth.

Each builder takes a seed and returns a Scene: MJCF for <asset> and <worldbody>, the PNG
textures those reference (generated procedurally: nothing is downloaded), and the ground truth
of every object (pose, dimensions, cylinder axis) in base_link. The same seed gives a
byte-identical scene.

World layout (all scenes): MuJoCo's world frame has the floor at z = 0 and x forward; base_link
(the waist) stands at (0, 0, WAIST_HEIGHT) with the world's orientation, so the head looks along
+x at home posture. Ground truth is given in base_link.

Scenes:
* tabletop: a table in front of the robot with cylinders of different radius, height and
  orientation (soda cans, bottles, jars with lids, a can lying on its side, a lying pipe) among
  distractors (boxes, spheres, a U-shaped handle) (thesis chapter 4, Fig. 4.6).
* visual_search: soda cans on stands at arbitrary depths in front of richly textured walls;
  the nearest can (from the ego frame) is outside the initial field of view (thesis section
  3.4.2, Fig. 3.9: "a non-trivial global optimum which could only be attended if enough
  exploration was promoted").
* pedestrians: people walking in front of the head (thesis chapter 5); the walkers come from
  vizzy_sim_bridge.core.pedestrians.PedestrianCrowd.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from vizzy_vision.frames import matrix_to_quaternion, quaternion_about, quaternion_z_to, to_wxyz
from vizzy_vision.kinematics import EGO_HEIGHT, WAIST_HEIGHT

SCENE_NAMES: tuple[str, ...] = ('tabletop', 'visual_search', 'pedestrians')

BASE_IN_WORLD = np.array([0.0, 0.0, WAIST_HEIGHT])

# Soda can (330 ml): 66 mm diameter, 122 mm high.
CAN_RADIUS, CAN_HEIGHT = 0.033, 0.122
# Table: top surface 0.72 m above the floor, 0.8 m deep x 1.2 m wide, front edge 0.40 m ahead.
TABLE_TOP_Z, TABLE_CENTER_X, TABLE_DEPTH, TABLE_WIDTH, TABLE_THICKNESS = (
    0.72, 0.80, 0.80, 1.20, 0.03)


class SceneUnavailable(RuntimeError):
    """A scene that cannot be built here (e.g. a module it needs is missing)."""


@dataclass(frozen=True)
class SceneObject:
    """Ground truth of one object, in base_link.

    shape: 'cylinder', 'box' or 'sphere' (compound objects give their main part or bounding box).
    size: full extents as a visualization_msgs/Marker scale: cylinder (2r, 2r, height) along
    its axis, box (x, y, z) in its own frame, sphere (2r, 2r, 2r).
    For cylinders radius, height and axis (unit vector, base_link) are set.
    """

    id: int
    name: str
    kind: str
    shape: str
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]   # quaternion (x, y, z, w)
    size: tuple[float, float, float]
    color: tuple[float, float, float, float]
    radius: float | None = None
    height: float | None = None
    axis: tuple[float, float, float] | None = None
    lid: bool = False
    role: str = ''     # 'target' (the visual search goal), 'support' (table, stands) or ''

    @property
    def is_cylinder(self) -> bool:
        return self.shape == 'cylinder'

    def as_dict(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out['is_cylinder'] = self.is_cylinder
        return out


@dataclass
class Scene:
    """A scene: MJCF fragments, their textures, static ground truth and moving actors."""

    name: str
    seed: int
    assets_xml: str
    worldbody_xml: str
    assets: dict[str, bytes] = field(default_factory=dict)
    objects: list[SceneObject] = field(default_factory=list)
    crowd: Any = None          # a PedestrianCrowd for the pedestrians scene
    description: str = ''

    def update(self, model: Any, data: Any, t: float) -> None:
        """Pose the moving actors (pedestrians) at sim time t [s]."""
        if self.crowd is not None:
            self.crowd.update(model, data, t)

    def moving_ground_truth(self, model: Any, data: Any) -> list[dict[str, Any]]:
        """Boxes of the moving actors now, in base_link (see pedestrian_boxes); each also has
        'corners': the corners (N x 3, base_link) of its geoms' own boxes, whose projection
        bounds the actor's silhouette in an image tightly."""
        if self.crowd is None:
            return []
        boxes = pedestrian_boxes(self.crowd.ground_truth(model, data))
        owner = getattr(self.crowd, 'geom_owner', None)
        if owner is not None:
            owners = np.asarray(owner(model))
            for k, box in enumerate(boxes):
                geoms = np.nonzero(owners == k)[0]
                if len(geoms):
                    box['corners'] = geom_box_corners(model, data, geoms) - BASE_IN_WORLD
        return boxes


# ----------------------------------------------------------------------------- helpers


def _f(*values: float) -> str:
    return ' '.join(f'{float(v):.6g}' for v in values)


def _mj_quat(q: tuple[float, float, float, float]) -> str:
    """MJCF quat attribute (w x y z) of a quaternion (x, y, z, w)."""
    return _f(*to_wxyz(q))


def _rgba(c: tuple[float, ...]) -> str:
    return _f(*c)


def png_bytes(image_rgb: np.ndarray) -> bytes:
    """PNG file contents of an RGB uint8 image."""
    ok, buf = cv2.imencode('.png', cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError('PNG encoding failed')
    return buf.tobytes()


def rich_texture(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """A richly textured RGB image (dead-leaves model: random coloured shapes at every scale).

    Rich in edges and colour at all scales, the kind of texture the thesis used "to facilitate
    stereo reconstruction" (section 3.4.2). size x size x 3 uint8.
    """
    img = np.empty((size, size, 3), np.uint8)
    img[:] = rng.integers(60, 200, 3, dtype=np.uint8)
    scale = size / 3.0
    while scale >= 4.0:
        n = int(min(4000, 0.5 * (size / scale) ** 2))
        centres = rng.integers(0, size, (n, 2))
        extents = np.maximum(1, (scale * rng.uniform(0.3, 1.0, (n, 2)))).astype(int)
        colors = rng.integers(0, 256, (n, 3))
        kinds = rng.integers(0, 3, n)
        angles = rng.uniform(0, 180, n)
        for (cx, cy), (ex, ey), col, kind, ang in zip(centres, extents, colors, kinds, angles,
                                                      strict=True):
            color = tuple(int(c) for c in col)
            if kind == 0:
                cv2.rectangle(img, (int(cx - ex), int(cy - ey)), (int(cx + ex), int(cy + ey)),
                              color, -1)
            elif kind == 1:
                cv2.ellipse(img, (int(cx), int(cy)), (int(ex), int(ey)), float(ang), 0, 360,
                            color, -1)
            else:
                cv2.line(img, (int(cx - ex), int(cy - ey)), (int(cx + ex), int(cy + ey)), color,
                         max(1, int(ex) // 4))
        scale /= 2.0
    noise = rng.integers(-18, 19, img.shape)
    return np.clip(img.astype(np.int16) + noise, 0, 255).astype(np.uint8)


def wood_texture(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """A light wood-grain RGB texture (size x size x 3 uint8) for the table top."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float32) / size
    warp = np.zeros_like(x)
    for k in range(1, 5):
        phase = rng.uniform(0, 2 * np.pi)
        warp += np.sin(2 * np.pi * k * x + phase) / (2.0 * k)
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * (18.0 * y + 1.5 * warp))
    fine: np.ndarray = rng.normal(0.0, 0.06, (size, size)).astype(np.float32)
    fine = cv2.GaussianBlur(fine, (0, 0), sigmaX=3.0, sigmaY=0.6)
    t = np.clip(0.55 * grain + 0.45 + fine, 0.0, 1.0)
    light = np.array([205, 160, 110], np.float32)
    dark = np.array([150, 100, 60], np.float32)
    img = dark + (light - dark) * t[..., None]
    return img.astype(np.uint8)


def _plane_quat(normal: np.ndarray) -> tuple[float, float, float, float]:
    """Orientation of a plane facing normal, its local y as close to world up as possible."""
    z = np.asarray(normal, dtype=np.float64)
    z = z / np.linalg.norm(z)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    y = up - (up @ z) * z
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    return matrix_to_quaternion(np.column_stack([x, y, z]))


def _textured_plane(name: str, material: str, pos: np.ndarray, normal: np.ndarray,
                    half: tuple[float, float]) -> str:
    """A plane geom facing normal, centred at pos (world); half = (half width, half height)."""
    return (f'<geom name="{name}" type="plane" pos="{_f(*pos)}" '
            f'quat="{_mj_quat(_plane_quat(normal))}" '
            f'size="{_f(half[0], half[1], 0.5)}" material="{material}"/>')


def _room(b: _Builder, half_x: float, half_y: float, height: float,
          rgba: str = '0.78 0.76 0.72 1', ceiling: str = '0.9 0.9 0.88 1',
          emission: float = 0.0) -> None:
    """Plain walls and a ceiling around the robot (world frame, centred on it): cheap to render,
    and no black void wherever the head turns (there is no skybox: it costs ~6 ms per image).
    emission > 0 makes them glow evenly (a sky)."""
    b.assets.append(f'<material name="room_wall" rgba="{rgba}" emission="{emission}" '
                    f'specular="0" reflectance="0"/>')
    b.assets.append(f'<material name="room_ceiling" rgba="{ceiling}" emission="{emission}" '
                    f'specular="0" reflectance="0"/>')
    for name, pos, normal, half in (
            ('room_front', (half_x, 0.0, height / 2), (-1.0, 0.0, 0.0), (half_y, height / 2)),
            ('room_back', (-half_x, 0.0, height / 2), (1.0, 0.0, 0.0), (half_y, height / 2)),
            ('room_left', (0.0, half_y, height / 2), (0.0, -1.0, 0.0), (half_x, height / 2)),
            ('room_right', (0.0, -half_y, height / 2), (0.0, 1.0, 0.0), (half_x, height / 2))):
        b.body.append(f'<geom name="{name}" type="plane" pos="{_f(*pos)}" '
                      f'quat="{_mj_quat(_plane_quat(np.array(normal)))}" '
                      f'size="{_f(half[0], half[1], 0.5)}" material="room_wall"/>')
    b.body.append(f'<geom name="room_ceiling" type="plane" pos="{_f(0.0, 0.0, height)}" '
                  f'quat="{_mj_quat(_plane_quat(np.array([0.0, 0.0, -1.0])))}" '
                  f'size="{_f(half_x, half_y, 0.5)}" material="room_ceiling"/>')


def _world(p_base: np.ndarray | Sequence[float]) -> np.ndarray:
    return np.asarray(p_base, dtype=np.float64) + BASE_IN_WORLD


def _base(p_world: np.ndarray) -> tuple[float, float, float]:
    p = np.asarray(p_world, dtype=np.float64) - BASE_IN_WORLD
    return (float(p[0]), float(p[1]), float(p[2]))


class _Builder:
    """Collects MJCF, textures and ground truth while a scene is laid out."""

    def __init__(self) -> None:
        self.assets: list[str] = []
        self.body: list[str] = []
        self.textures: dict[str, bytes] = {}
        self.objects: list[SceneObject] = []

    def texture(self, name: str, image: np.ndarray,
                repeat: tuple[float, float] = (1.0, 1.0)) -> str:
        """Register a PNG texture and a material using it; returns the material name."""
        file = f'{name}.png'
        self.textures[file] = png_bytes(image)
        self.assets.append(f'<texture name="{name}_tex" type="2d" file="{file}"/>')
        self.assets.append(f'<material name="{name}" texture="{name}_tex" '
                           f'texrepeat="{_f(*repeat)}" '
                           f'specular="0.05" shininess="0.1" reflectance="0"/>')
        return name

    def add(self, obj_kwargs: dict[str, Any], xml: str) -> SceneObject:
        obj = SceneObject(id=len(self.objects), **obj_kwargs)
        self.objects.append(obj)
        self.body.append(xml)
        return obj

    def scene(self, name: str, seed: int, description: str, crowd: Any = None,
              extra_assets: str = '', extra_body: str = '') -> Scene:
        return Scene(name=name, seed=seed, assets_xml='\n'.join(self.assets) + extra_assets,
                     worldbody_xml='\n'.join(self.body) + extra_body, assets=dict(self.textures),
                     objects=list(self.objects), crowd=crowd, description=description)


def _cylinder_xml(name: str, pos_w: np.ndarray, axis: np.ndarray, radius: float, height: float,
                  rgba: tuple[float, ...], extra: str = '') -> str:
    """A static body holding a cylinder (axis = body z) and any extra geoms in body coordinates."""
    return (f'<body name="{name}" pos="{_f(*pos_w)}" quat="{_mj_quat(quaternion_z_to(axis))}">'
            f'<geom type="cylinder" size="{_f(radius, height / 2.0)}" rgba="{_rgba(rgba)}"/>'
            f'{extra}</body>')


def _cylinder_truth(name: str, kind: str, pos_w: np.ndarray, axis: np.ndarray, radius: float,
                    height: float, rgba: tuple[float, ...], lid: bool = False,
                    role: str = '') -> dict[str, Any]:
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return dict(name=name, kind=kind, shape='cylinder', position=_base(pos_w),
                orientation=quaternion_z_to(a), size=(2 * radius, 2 * radius, height),
                color=tuple(rgba), radius=radius, height=height,
                axis=(float(a[0]), float(a[1]), float(a[2])), lid=lid, role=role)


def _can_bands(radius: float, height: float, band: tuple[float, ...],
               rim: tuple[float, ...]) -> str:
    """A printed band and metal rims around a can (body coordinates, axis z)."""
    return (f'<geom type="cylinder" size="{_f(radius + 0.0005, height * 0.18)}" '
            f'rgba="{_rgba(band)}"/>'
            f'<geom type="cylinder" pos="0 0 {height / 2 - 0.004:.6g}" '
            f'size="{_f(radius - 0.004, 0.0045)}" '
            f'rgba="{_rgba(rim)}"/>')


# ----------------------------------------------------------------------------- tabletop

_CAN_COLORS = [((0.80, 0.05, 0.05, 1), (0.95, 0.95, 0.95, 1)),   # red, white band
               ((0.10, 0.25, 0.75, 1), (0.85, 0.85, 0.20, 1)),   # blue, yellow band
               ((0.10, 0.55, 0.20, 1), (0.95, 0.95, 0.95, 1)),   # green, white band
               ((0.75, 0.75, 0.78, 1), (0.15, 0.15, 0.15, 1))]   # silver, black band
_BOTTLE_COLORS = [(0.15, 0.45, 0.20, 1), (0.45, 0.25, 0.10, 1), (0.30, 0.55, 0.85, 1)]
_DISTRACTOR_COLORS = [(0.95, 0.55, 0.10, 1), (0.85, 0.80, 0.15, 1), (0.55, 0.20, 0.65, 1),
                      (0.20, 0.65, 0.65, 1), (0.90, 0.40, 0.55, 1), (0.35, 0.35, 0.35, 1)]


def _place(rng: np.random.Generator, placed: list[tuple[float, float, float]], footprint: float,
           x_range: tuple[float, float], y_range: tuple[float, float]) -> tuple[float, float]:
    """A random (x, y) on the table whose footprint circle clears the ones placed so far."""
    for _ in range(500):
        x = float(rng.uniform(x_range[0] + footprint, x_range[1] - footprint))
        y = float(rng.uniform(y_range[0] + footprint, y_range[1] - footprint))
        if all(math.hypot(x - px, y - py) > footprint + pr + 0.02 for px, py, pr in placed):
            placed.append((x, y, footprint))
            return x, y
    raise RuntimeError('could not place an object on the table without overlaps')


def tabletop(seed: int) -> Scene:
    """A table with cylinders (cans, bottles, jars with lids, a lying can, a pipe) and
    distractors."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    b = _Builder()
    # the floor is plain: under the table it is barely seen, and each texture costs ~2.5 ms of
    # CPU rendering per image
    b.assets.append('<material name="floor" rgba="0.5 0.5 0.47 1" specular="0.05" '
                    'reflectance="0"/>')
    wood = b.texture('table_wood', wood_texture(rng), (2.0, 2.0))
    wall = b.texture('tabletop_wall', rich_texture(rng, 512), (3.0, 1.5))
    b.body.append('<geom name="floor" type="plane" size="4 4 0.5" material="floor"/>')
    _room(b, 3.6, 3.6, 2.8)
    b.body.append(_textured_plane('back_wall', wall, np.array([3.55, 0.0, 1.4]),
                                  np.array([-1.0, 0.0, 0.0]), (3.0, 1.4)))

    # the table: a top and four legs (support), top surface textured
    top_c = _world([TABLE_CENTER_X, 0.0, 0.0])
    top_c[2] = TABLE_TOP_Z - TABLE_THICKNESS / 2.0
    leg_x, leg_y = TABLE_DEPTH / 2 - 0.05, TABLE_WIDTH / 2 - 0.05
    legs = ''.join(
        f'<geom type="box" pos="{_f(sx * leg_x, sy * leg_y, -(TABLE_TOP_Z) / 2.0)}" '
        f'size="{_f(0.025, 0.025, (TABLE_TOP_Z - TABLE_THICKNESS) / 2.0)}" '
        f'rgba="0.3 0.22 0.15 1"/>'
        for sx in (-1, 1) for sy in (-1, 1))
    table_xml = (f'<body name="table" pos="{_f(*top_c)}">'
                 f'<geom type="box" '
                 f'size="{_f(TABLE_DEPTH / 2, TABLE_WIDTH / 2, TABLE_THICKNESS / 2)}" '
                 f'rgba="0.45 0.32 0.2 1"/>'
                 f'<geom type="plane" pos="0 0 {TABLE_THICKNESS / 2 + 0.0005:.6g}" '
                 f'size="{_f(TABLE_DEPTH / 2, TABLE_WIDTH / 2, 0.1)}" material="{wood}"/>'
                 f'{legs}</body>')
    b.add(dict(name='table', kind='table', shape='box', position=_base(top_c),
               orientation=(0.0, 0.0, 0.0, 1.0),
               size=(TABLE_DEPTH, TABLE_WIDTH, TABLE_THICKNESS), color=(0.45, 0.32, 0.2, 1.0),
               role='support'), table_xml)

    placed: list[tuple[float, float, float]] = []
    xr = (TABLE_CENTER_X - TABLE_DEPTH / 2 + 0.08, TABLE_CENTER_X + TABLE_DEPTH / 2 - 0.05)
    yr = (-TABLE_WIDTH / 2 + 0.12, TABLE_WIDTH / 2 - 0.12)
    z0 = TABLE_TOP_Z

    def on_table(x: float, y: float, z_above: float) -> np.ndarray:
        p = _world([x, y, 0.0])
        p[2] = z0 + z_above
        return p

    up = np.array([0.0, 0.0, 1.0])
    # upright soda cans, some with a plastic lid
    n_cans = int(rng.integers(2, 4))
    for i in range(n_cans):
        body, band = _CAN_COLORS[int(rng.integers(len(_CAN_COLORS)))]
        lid = bool(rng.random() < 0.5) or i == 0
        x, y = _place(rng, placed, CAN_RADIUS + 0.004, xr, yr)
        p = on_table(x, y, CAN_HEIGHT / 2)
        extra = _can_bands(CAN_RADIUS, CAN_HEIGHT, band, (0.7, 0.7, 0.72, 1))
        if lid:
            extra += (f'<geom type="cylinder" pos="0 0 {CAN_HEIGHT / 2 + 0.004:.6g}" '
                      f'size="{_f(CAN_RADIUS + 0.003, 0.004)}" rgba="0.95 0.95 0.9 1"/>')
        name = f'can_{i}'
        b.add(_cylinder_truth(name, 'can', p, up, CAN_RADIUS, CAN_HEIGHT, body, lid=lid),
              _cylinder_xml(name, p, up, CAN_RADIUS, CAN_HEIGHT, body, extra))

    # bottles: body cylinder + neck + cap (the ground truth is the body)
    for i in range(int(rng.integers(1, 3))):
        r = float(rng.uniform(0.030, 0.040))
        h = float(rng.uniform(0.14, 0.20))
        color = _BOTTLE_COLORS[int(rng.integers(len(_BOTTLE_COLORS)))]
        x, y = _place(rng, placed, r + 0.004, xr, yr)
        p = on_table(x, y, h / 2)
        neck_h = 0.06
        extra = (f'<geom type="cylinder" pos="0 0 {h / 2 + neck_h / 2:.6g}" '
                 f'size="{_f(0.013, neck_h / 2)}" '
                 f'rgba="{_rgba(color)}"/>'
                 f'<geom type="cylinder" pos="0 0 {h / 2 + neck_h + 0.01:.6g}" '
                 f'size="{_f(0.015, 0.01)}" '
                 f'rgba="0.9 0.9 0.9 1"/>'
                 f'<geom type="cylinder" size="{_f(r + 0.0005, h * 0.2)}" rgba="0.95 0.9 0.75 1"/>')
        name = f'bottle_{i}'
        b.add(_cylinder_truth(name, 'bottle', p, up, r, h, color, lid=True),
              _cylinder_xml(name, p, up, r, h, color, extra))

    # a jar with a screw lid
    r = float(rng.uniform(0.040, 0.050))
    h = float(rng.uniform(0.08, 0.12))
    x, y = _place(rng, placed, r + 0.006, xr, yr)
    p = on_table(x, y, h / 2)
    extra = (f'<geom type="cylinder" pos="0 0 {h / 2 + 0.0075:.6g}" size="{_f(r + 0.003, 0.0075)}" '
             f'rgba="0.75 0.1 0.1 1"/>')
    b.add(_cylinder_truth('jar_0', 'jar', p, up, r, h, (0.85, 0.75, 0.45, 1), lid=True),
          _cylinder_xml('jar_0', p, up, r, h, (0.85, 0.75, 0.45, 1), extra))

    # a soda can lying on its side
    yaw = float(rng.uniform(0, np.pi))
    axis = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    x, y = _place(rng, placed, CAN_HEIGHT / 2 + 0.01, xr, yr)
    p = on_table(x, y, CAN_RADIUS)
    body, band = _CAN_COLORS[int(rng.integers(len(_CAN_COLORS)))]
    b.add(_cylinder_truth('can_lying', 'can', p, axis, CAN_RADIUS, CAN_HEIGHT, body),
          _cylinder_xml('can_lying', p, axis, CAN_RADIUS, CAN_HEIGHT, body,
                        _can_bands(CAN_RADIUS, CAN_HEIGHT, band, (0.7, 0.7, 0.72, 1))))

    # a lying pipe
    r = float(rng.uniform(0.018, 0.030))
    length = float(rng.uniform(0.22, 0.32))
    yaw = float(rng.uniform(0, np.pi))
    axis = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    x, y = _place(rng, placed, length / 2 + 0.01, xr, yr)
    p = on_table(x, y, r)
    b.add(_cylinder_truth('pipe_0', 'pipe', p, axis, r, length, (0.6, 0.62, 0.65, 1)),
          _cylinder_xml('pipe_0', p, axis, r, length, (0.6, 0.62, 0.65, 1)))

    # distractors: boxes
    for i in range(int(rng.integers(2, 4))):
        sx, sy = rng.uniform(0.05, 0.14, 2)
        sz = float(rng.uniform(0.04, 0.18))
        yaw = float(rng.uniform(0, np.pi))
        color = _DISTRACTOR_COLORS[int(rng.integers(len(_DISTRACTOR_COLORS)))]
        x, y = _place(rng, placed, 0.5 * math.hypot(sx, sy) + 0.005, xr, yr)
        p = on_table(x, y, sz / 2)
        q = quaternion_about('z', yaw)
        name = f'box_{i}'
        b.add(dict(name=name, kind='box', shape='box', position=_base(p), orientation=q,
                   size=(float(sx), float(sy), sz), color=color),
              f'<body name="{name}" pos="{_f(*p)}" quat="{_mj_quat(q)}"><geom type="box" '
              f'size="{_f(sx / 2, sy / 2, sz / 2)}" rgba="{_rgba(color)}"/></body>')
    # spheres
    for i in range(int(rng.integers(1, 3))):
        r = float(rng.uniform(0.025, 0.05))
        color = _DISTRACTOR_COLORS[int(rng.integers(len(_DISTRACTOR_COLORS)))]
        x, y = _place(rng, placed, r + 0.005, xr, yr)
        p = on_table(x, y, r)
        name = f'sphere_{i}'
        b.add(dict(name=name, kind='sphere', shape='sphere', position=_base(p),
                   orientation=(0.0, 0.0, 0.0, 1.0), size=(2 * r, 2 * r, 2 * r), color=color),
              f'<body name="{name}" pos="{_f(*p)}"><geom type="sphere" size="{r:.6g}" '
              f'rgba="{_rgba(color)}"/></body>')
    # a U-shaped handle standing on its two posts (locally cylindrical: a hard distractor)
    span, post_h, rr = float(rng.uniform(0.10, 0.14)), float(rng.uniform(0.04, 0.06)), 0.008
    yaw = float(rng.uniform(0, np.pi))
    x, y = _place(rng, placed, span / 2 + 0.02, xr, yr)
    p = on_table(x, y, (post_h + rr) / 2)
    q = quaternion_about('z', yaw)
    hz = (post_h + rr) / 2
    handle = (f'<body name="handle_0" pos="{_f(*p)}" quat="{_mj_quat(q)}">'
              f'<geom type="capsule" fromto="{_f(-span / 2, 0, -hz + rr, -span / 2, 0, hz - rr)}" '
              f'size="{rr}" rgba="0.15 0.15 0.15 1"/>'
              f'<geom type="capsule" fromto="{_f(span / 2, 0, -hz + rr, span / 2, 0, hz - rr)}" '
              f'size="{rr}" rgba="0.15 0.15 0.15 1"/>'
              f'<geom type="capsule" fromto="{_f(-span / 2, 0, hz - rr, span / 2, 0, hz - rr)}" '
              f'size="{rr}" rgba="0.15 0.15 0.15 1"/>'
              f'</body>')
    b.add(dict(name='handle_0', kind='handle', shape='box', position=_base(p), orientation=q,
               size=(span + 2 * rr, 2 * rr, post_h + rr), color=(0.15, 0.15, 0.15, 1.0)), handle)
    n_cyl = sum(o.is_cylinder for o in b.objects)
    return b.scene('tabletop', seed, f'table with {n_cyl} cylinders and '
                   f'{len(b.objects) - n_cyl - 1} distractors')


# ----------------------------------------------------------------------------- visual search


def _ego_world() -> np.ndarray:
    return _world([0.0, 0.0, EGO_HEIGHT])


def visual_search(seed: int, n_cans: int = 8) -> Scene:
    """Cans on stands at arbitrary depths over richly textured walls; the nearest one (from the
    ego frame) lies outside the initial field of view (thesis section 3.4.2, Fig. 3.9)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2]))
    b = _Builder()
    floor = b.texture('search_floor', rich_texture(rng, 1024), (2.0, 2.0))
    back = b.texture('search_back', rich_texture(rng, 1024), (1.0, 1.0))
    left = b.texture('search_left', rich_texture(rng, 1024), (1.0, 1.0))
    right = b.texture('search_right', rich_texture(rng, 1024), (1.0, 1.0))
    b.body.append(f'<geom name="floor" type="plane" size="3.3 3.3 0.5" material="{floor}"/>')
    _room(b, 3.3, 3.3, 3.0)
    b.body.append(_textured_plane('back_wall', back, np.array([3.25, 0.0, 1.5]),
                                  np.array([-1.0, 0.0, 0.0]), (3.3, 1.5)))
    b.body.append(_textured_plane('left_wall', left, np.array([0.0, 3.25, 1.5]),
                                  np.array([0.0, -1.0, 0.0]), (3.3, 1.5)))
    b.body.append(_textured_plane('right_wall', right, np.array([0.0, -3.25, 1.5]),
                                  np.array([0.0, 1.0, 0.0]), (3.3, 1.5)))
    ego = _ego_world()
    up = np.array([0.0, 0.0, 1.0])
    red, white = (0.80, 0.05, 0.05, 1.0), (0.95, 0.95, 0.95, 1.0)

    def can_at(i: int, dist: float, az: float, el: float, role: str) -> None:
        d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        c = ego + dist * d
        c[2] = max(c[2], 0.30)
        name = f'can_{i}'
        extra = _can_bands(CAN_RADIUS, CAN_HEIGHT, white, (0.7, 0.7, 0.72, 1))
        b.add(_cylinder_truth(name, 'can', c, up, CAN_RADIUS, CAN_HEIGHT, red, role=role),
              _cylinder_xml(name, c, up, CAN_RADIUS, CAN_HEIGHT, red, extra))
        # the stand: a thin pole from the floor to the can's bottom, on a round foot
        bottom = c[2] - CAN_HEIGHT / 2
        stand = np.array([c[0], c[1], bottom / 2])
        b.add(dict(name=f'stand_{i}', kind='stand', shape='cylinder', position=_base(stand),
                   orientation=(0.0, 0.0, 0.0, 1.0), size=(0.02, 0.02, bottom),
                   color=(0.3, 0.3, 0.3, 1.0), radius=0.01, height=float(bottom),
                   axis=(0.0, 0.0, 1.0), role='support'),
              f'<body name="stand_{i}" pos="{_f(*stand)}"><geom type="cylinder" '
              f'size="{_f(0.01, bottom / 2)}" rgba="0.3 0.3 0.3 1"/><geom type="cylinder" '
              f'pos="0 0 {-bottom / 2 + 0.005:.6g}" size="0.08 0.005" '
              f'rgba="0.25 0.25 0.25 1"/></body>')

    # the nearest can: outside both cameras' initial field of view (|azimuth| > 55 deg)
    side = 1.0 if rng.random() < 0.5 else -1.0
    near_dist = float(rng.uniform(0.50, 0.60))
    can_at(0, near_dist, side * math.radians(float(rng.uniform(58.0, 70.0))),
           math.radians(float(rng.uniform(-12.0, 5.0))), 'target')
    # the others: in view, farther away, not hiding each other
    dirs: list[tuple[float, float]] = []
    i = 1
    while i < n_cans:
        az = math.radians(float(rng.uniform(-32.0, 32.0)))
        el = math.radians(float(rng.uniform(-22.0, 12.0)))
        if any(math.hypot(az - a, el - e) < math.radians(7.0) for a, e in dirs):
            continue
        dirs.append((az, el))
        can_at(i, float(rng.uniform(near_dist + 0.25, 2.6)), az, el, '')
        i += 1
    return b.scene('visual_search', seed, f'{n_cans} cans over textured walls; nearest at '
                   f'{near_dist:.2f} m, {"left" if side > 0 else "right"}, out of view')


# ----------------------------------------------------------------------------- pedestrians


def pedestrians(seed: int, count: int = 4,
                area: tuple[tuple[float, float], tuple[float, float]] | None = None) -> Scene:
    """People walking in front of the head (thesis chapter 5), from core.pedestrians.

    area: ((x_min, x_max), (y_min, y_max)) [m] in the world frame where they walk (None: the
    crowd's default, where everyone stays in the left eye's view; a wider area makes people
    leave the view and come back, as on a real street).
    """
    try:
        from vizzy_sim_bridge.core.pedestrians import PedestrianCrowd
    except ImportError as exc:
        raise SceneUnavailable(
            "scene 'pedestrians' needs vizzy_sim_bridge.core.pedestrians.PedestrianCrowd, "
            f'which is not available here ({exc}); choose scene tabletop or visual_search') from exc
    scene_seq, crowd_seq = np.random.SeedSequence([seed, 3]).spawn(2)
    rng = np.random.default_rng(scene_seq)
    crowd = (PedestrianCrowd(np.random.default_rng(crowd_seq), int(count)) if area is None else
             PedestrianCrowd(np.random.default_rng(crowd_seq), int(count), area=area))
    b = _Builder()
    floor = b.texture('street_floor', _pavement(rng), (12.0, 12.0))
    # a calm facade, not rich_texture: busy backgrounds halve the HOG people detector's recall
    back = b.texture('street_back', _facade(rng), (3.0, 1.0))
    b.body.append(f'<geom name="floor" type="plane" size="10 10 0.5" material="{floor}"/>')
    _room(b, 10.0, 10.0, 8.0, rgba='0.5 0.62 0.8 1', ceiling='0.5 0.62 0.8 1', emission=0.3)
    b.body.append(_textured_plane('back_wall', back, np.array([9.9, 0.0, 2.5]),
                                  np.array([-1.0, 0.0, 0.0]), (9.9, 2.5)))
    return b.scene('pedestrians', seed, f'{count} pedestrians walking', crowd=crowd,
                   extra_assets='\n' + crowd.assets_xml(), extra_body='\n' + crowd.worldbody_xml())


def _facade(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """A muted building facade: plaster with a grid of slightly darker windows."""
    base = rng.integers(150, 190, 3)
    img = np.empty((size, size, 3), np.int16)
    img[:] = base
    y, x = np.mgrid[0:size, 0:size]
    cell = size // 4
    window = ((x % cell) > cell * 0.3) & ((x % cell) < cell * 0.7) & \
             ((y % cell) > cell * 0.25) & ((y % cell) < cell * 0.75)
    img[window] -= 35
    img += rng.integers(-6, 7, img.shape, dtype=np.int16)
    return np.clip(img, 0, 255).astype(np.uint8)


def _pavement(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """Grey paving stones with joints and speckle."""
    img = np.full((size, size, 3), 120, np.uint8)
    tile = size // 8
    shades = rng.integers(95, 150, (8, 8))
    for i in range(8):
        for j in range(8):
            img[i * tile:(i + 1) * tile, j * tile:(j + 1) * tile] = int(shades[i, j])
    img[::tile, :] = 70
    img[:, ::tile] = 70
    noise = rng.integers(-15, 16, img.shape)
    return np.clip(img.astype(np.int16) + noise, 0, 255).astype(np.uint8)


def geom_box_corners(model: Any, data: Any, geom_ids: Any) -> np.ndarray:
    """World corners (8 per geom) of each geom's own bounding box: sphere (r, r, r), capsule
    (r, r, h + r), cylinder (r, r, h), ellipsoid and box their sizes; others their bounding
    sphere. Vectorized over the geoms."""
    ids = np.asarray(geom_ids, dtype=int)
    size = np.asarray(model.geom_size)[ids]
    kind = np.asarray(model.geom_type)[ids]
    half = size.copy()
    sphere, capsule, ellipsoid, cylinder, box = 2, 3, 4, 5, 6
    half[kind == sphere] = size[kind == sphere][:, :1]
    cap = kind == capsule
    half[cap] = np.column_stack([size[cap, 0], size[cap, 0], size[cap, 1] + size[cap, 0]])
    cyl = kind == cylinder
    half[cyl] = np.column_stack([size[cyl, 0], size[cyl, 0], size[cyl, 1]])
    other = ~np.isin(kind, [sphere, capsule, ellipsoid, cylinder, box])
    half[other] = np.asarray(model.geom_rbound)[ids][other][:, None]
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    local = half[:, None, :] * signs[None]                                   # G x 8 x 3
    rot = np.asarray(data.geom_xmat)[ids].reshape(-1, 3, 3)
    world = np.einsum('gij,gkj->gki', rot, local) + np.asarray(data.geom_xpos)[ids][:, None, :]
    return world.reshape(-1, 3)


def pedestrian_boxes(raw: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Normalize PedestrianCrowd.ground_truth() boxes to {id, center, size, orientation} in
    base_link (center [m], size: full extents [m], orientation quaternion (x, y, z, w)).

    Accepts world-frame boxes (floor at z = 0) given as box_min/box_max (or min/max) corners of
    an axis-aligned box (what PedestrianCrowd.ground_truth gives), or center/position +
    size/dimensions/extents (+ optional yaw or quaternion/orientation (x, y, z, w)).
    """
    out = []
    for k, box in enumerate(raw):
        box = dict(box)
        inner = box.get('box') if isinstance(box.get('box'), dict) else None
        if inner:
            box.update(inner)
        lo_key = next((k for k in ('box_min', 'min') if k in box), None)
        hi_key = next((k for k in ('box_max', 'max') if k in box), None)
        if lo_key and hi_key:
            lo, hi = np.asarray(box[lo_key], float), np.asarray(box[hi_key], float)
            center, size = (lo + hi) / 2.0, hi - lo
        else:
            center = np.asarray(box.get('center', box.get('position')), float)
            size = np.asarray(box.get('size', box.get('dimensions', box.get('extents'))), float)
        q: tuple[float, ...]
        if lo_key and hi_key:
            q = (0.0, 0.0, 0.0, 1.0)
        elif 'quaternion' in box or 'orientation' in box:
            q = tuple(float(v) for v in box['quaternion' if 'quaternion' in box else 'orientation'])
        else:
            q = quaternion_about('z', float(box.get('yaw', 0.0)))
        out.append({'id': int(box.get('id', k)), 'center': _base(center),
                    'size': tuple(float(v) for v in size), 'orientation': q,
                    'label': str(box.get('label', 'person'))})
    return out


BUILDERS: dict[str, Callable[..., Scene]] = {
    'tabletop': tabletop, 'visual_search': visual_search, 'pedestrians': pedestrians}


def build_scene(name: str, seed: int, **kwargs: Any) -> Scene:
    """The scene called name (SCENE_NAMES) for this seed; ValueError for an unknown name."""
    if name not in BUILDERS:
        raise ValueError(f'unknown scene {name!r}; known: {", ".join(SCENE_NAMES)}')
    return BUILDERS[name](int(seed), **kwargs)


__all__ = ['BASE_IN_WORLD', 'CAN_HEIGHT', 'CAN_RADIUS', 'SCENE_NAMES', 'Scene', 'SceneObject',
           'SceneUnavailable', 'build_scene', 'pedestrian_boxes', 'pedestrians', 'rich_texture',
           'tabletop', 'visual_search']

"""Synthetic organized RGB-D frames (Open3D ray casting) for benchmarks and tests: a tabletop seen
from above (make_tabletop) and a room with a table, its floor and a back wall (make_room)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

Array = NDArray[np.float64]
INTRINSICS = (525.0, 525.0, 319.5, 239.5)


@dataclass(frozen=True)
class TabletopScene:
    cloud: Array                      #: (H, W, 3) camera optical frame, NaN where no hit
    cylinders: list[tuple[Array, float, float]]   #: (base centre in camera frame, radius, height)
    intrinsics: tuple[float, float, float, float]
    up: Array | None = None           #: against gravity, camera frame (make_room)
    table_height: float | None = None  #: m, the table top below the camera (make_room)
    #: make_room: centres of the floor clutter, camera frame
    clutter: list[Array] = field(default_factory=list)


def _moved(mesh: o3d.geometry.TriangleMesh, offset: tuple[float, ...]) -> o3d.geometry.TriangleMesh:
    """mesh translated by offset, in place (Open3D's stubs type translate() as Geometry3D)."""
    mesh.translate(offset)
    return mesh


def make_tabletop(rng: np.random.Generator, n_cylinders: int = 3, n_distractors: int = 8,
                  width: int = 640, height: int = 480, noise_std: float = 0.001) -> TabletopScene:
    """A 1.2 x 0.8 m table seen from 0.6 m above and 0.5 m back (camera looking down 50 degrees),
    with upright cylinders (r 3-5 cm, h 8-20 cm) and boxes/spheres as distractors, on a grid."""
    meshes: list[o3d.geometry.TriangleMesh] = []
    table = _moved(o3d.geometry.TriangleMesh.create_box(1.2, 0.8, 0.02), (-0.6, -0.4, -0.02))
    meshes.append(table)
    slots = np.array([(x, y) for x in np.linspace(-0.45, 0.45, 5)
                      for y in np.linspace(-0.25, 0.25, 3)])
    slots = slots[rng.permutation(len(slots))[: n_cylinders + n_distractors]]
    cyls = []
    for k, (x, y) in enumerate(slots):
        if k < n_cylinders:
            r, h = rng.uniform(0.03, 0.05), rng.uniform(0.08, 0.2)
            m = _moved(o3d.geometry.TriangleMesh.create_cylinder(r, h, resolution=64),
                       (x, y, h / 2))
            cyls.append((np.array([x, y, 0.0]), r, h))
        elif k % 2:
            s = rng.uniform(0.04, 0.1, 3)
            m = _moved(o3d.geometry.TriangleMesh.create_box(*s), (x - s[0] / 2, y - s[1] / 2, 0))
        else:
            r = rng.uniform(0.03, 0.05)
            m = _moved(o3d.geometry.TriangleMesh.create_sphere(r), (x, y, r))
        meshes.append(m)
    # camera: at (0, -0.5, 0.6) in the table frame, looking at the table centre
    eye = np.array([0.0, -0.55, 0.6])
    cloud, r_ct = _render(meshes, eye, np.zeros(3), width, height, noise_std, rng)
    cyl_cam = [((c - eye) @ r_ct.T, r, h) for c, r, h in cyls]
    return TabletopScene(cloud, cyl_cam, INTRINSICS)


def _render(meshes: list[o3d.geometry.TriangleMesh], eye: Array, target: Array, width: int,
            height: int, noise_std: float, rng: np.random.Generator,
            intrinsics: tuple[float, float, float, float] = INTRINSICS) -> tuple[Array, Array]:
    """(organized cloud in the camera optical frame, world -> camera rotation) of meshes seen from
    eye looking at target (world z up, no roll), with depth noise noise_std * z^2."""
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    r_ct = np.stack([right, down, fwd])          # world -> camera rotation
    ext = np.eye(4)
    ext[:3, :3] = r_ct
    ext[:3, 3] = -r_ct @ eye
    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    fx, fy, cx, cy = intrinsics
    # open3d's stubs make Tensor's dtype and device required; they default to (inferred, CPU:0)
    k_mat = o3d.core.Tensor([[fx, 0, cx], [0, fy, cy], [0, 0, 1]],  # type: ignore[call-overload]
                            dtype=o3d.core.Dtype.Float64)
    rays = scene.create_rays_pinhole(k_mat, o3d.core.Tensor(ext),  # type: ignore[call-overload]
                                     width, height)
    t = scene.cast_rays(rays)['t_hit'].numpy()
    d = rays.numpy()[..., 3:]
    hit = np.isfinite(t)
    p_table = rays.numpy()[..., :3] + d * np.where(hit, t, 0)[..., None]
    cloud = (p_table - eye) @ r_ct.T
    cloud += rng.normal(0, noise_std, cloud.shape) * (cloud[..., 2:3] / 1.0) ** 2
    cloud[~hit] = np.nan
    return cloud, r_ct


def _box(lo: tuple[float, float, float],
         hi: tuple[float, float, float]) -> o3d.geometry.TriangleMesh:
    size = np.subtract(hi, lo)
    return _moved(o3d.geometry.TriangleMesh.create_box(*size), lo)


def make_room(rng: np.random.Generator, width: int = 640, height: int = 480,
              noise_std: float = 0.001, camera_height: float = 1.25,
              wall_distance: float = 2.0) -> TabletopScene:
    """A room as a stereo head or RGB-D camera sees a table in it: a 1.2 x 0.8 m table (top 0.72 m
    above the floor, four legs) with an upright mug (r 4 cm, h 10 cm), an upright bottle (r 3.5 cm,
    h 22 cm) and a box on it; the floor around it; a back wall wall_distance (m) beyond the camera,
    the largest plane in view; and floor clutter near the wall, about 2 m from the camera (a bin,
    r 12 cm, h 35 cm, and a 30 cm box). Camera camera_height above the floor, 0.6 m back from the
    table's near edge, looking down at the table centre (28 degrees with the defaults). Radii and
    positions are jittered by rng (a few mm). The field of view is the 640 x 480 one (58 x 49
    degrees) at any width and height of the same aspect."""
    j = lambda s: float(rng.uniform(-s, s))   # noqa: E731
    top = 0.72
    meshes = [_box((-2.0, -1.0, -0.02), (2.0, wall_distance, 0.0)),                 # floor
              _box((-2.0, wall_distance, -0.02), (2.0, wall_distance + 0.02, 2.5)),  # back wall
              _box((-0.6, 0.5, top - 0.03), (0.6, 1.3, top))]                         # table top
    for x in (-0.55, 0.51):
        for y in (0.55, 1.21):
            meshes.append(_box((x, y, 0.0), (x + 0.04, y + 0.04, top - 0.03)))        # legs
    cyls = []
    for (x, y), r, h in (((-0.2 + j(0.02), 0.8 + j(0.02)), 0.04 + j(0.003), 0.10 + j(0.01)),
                         ((0.2 + j(0.02), 0.95 + j(0.02)), 0.035 + j(0.003), 0.22 + j(0.01))):
        m = _moved(o3d.geometry.TriangleMesh.create_cylinder(r, h, resolution=64),
                   (x, y, top + h / 2))
        meshes.append(m)
        cyls.append((np.array([x, y, top]), r, h))
    # a box on the table
    meshes.append(_box((-0.05, 1.05, top), (0.05, 1.15, top + 0.08)))
    bin_c = np.array([-0.9 + j(0.05), wall_distance - 0.25, 0.175])
    meshes.append(_moved(o3d.geometry.TriangleMesh.create_cylinder(0.12, 0.35, resolution=64),
                         tuple(bin_c)))
    box_c = np.array([0.9 + j(0.05), wall_distance - 0.3, 0.15])
    meshes.append(_box(tuple(box_c - 0.15), tuple(box_c + 0.15)))
    eye = np.array([0.0, -0.1, camera_height])
    s = width / 640.0                                  # the same field of view at any size
    k = (INTRINSICS[0] * s, INTRINSICS[1] * s, 0.5 * width - 0.5, 0.5 * height - 0.5)
    cloud, r_ct = _render(meshes, eye, np.array([0.0, 0.9, top]), width, height, noise_std, rng, k)
    return TabletopScene(cloud, [((c - eye) @ r_ct.T, r, h) for c, r, h in cyls], k,
                         up=r_ct @ np.array([0.0, 0.0, 1.0]), table_height=camera_height - top,
                         clutter=[(c - eye) @ r_ct.T for c in (bin_c, box_c)])

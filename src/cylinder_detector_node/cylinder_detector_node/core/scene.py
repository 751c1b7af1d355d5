"""A synthetic organized RGB-D tabletop frame (Open3D ray casting) for benchmarks and tests."""

from __future__ import annotations

from dataclasses import dataclass

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


def make_tabletop(rng: np.random.Generator, n_cylinders: int = 3, n_distractors: int = 8,
                  width: int = 640, height: int = 480, noise_std: float = 0.001) -> TabletopScene:
    """A 1.2 x 0.8 m table seen from 0.6 m above and 0.5 m back (camera looking down 50 degrees),
    with upright cylinders (r 3-5 cm, h 8-20 cm) and boxes/spheres as distractors, on a grid."""
    meshes = []
    table = o3d.geometry.TriangleMesh.create_box(1.2, 0.8, 0.02).translate((-0.6, -0.4, -0.02))
    meshes.append(table)
    slots = np.array([(x, y) for x in np.linspace(-0.45, 0.45, 5) for y in np.linspace(-0.25, 0.25, 3)])
    slots = slots[rng.permutation(len(slots))[: n_cylinders + n_distractors]]
    cyls = []
    for k, (x, y) in enumerate(slots):
        if k < n_cylinders:
            r, h = rng.uniform(0.03, 0.05), rng.uniform(0.08, 0.2)
            m = o3d.geometry.TriangleMesh.create_cylinder(r, h, resolution=64).translate((x, y, h / 2))
            cyls.append((np.array([x, y, 0.0]), r, h))
        elif k % 2:
            s = rng.uniform(0.04, 0.1, 3)
            m = o3d.geometry.TriangleMesh.create_box(*s).translate((x - s[0] / 2, y - s[1] / 2, 0))
        else:
            r = rng.uniform(0.03, 0.05)
            m = o3d.geometry.TriangleMesh.create_sphere(r).translate((x, y, r))
        meshes.append(m)
    # camera: at (0, -0.5, 0.6) in the table frame, looking at the table centre
    eye = np.array([0.0, -0.55, 0.6])
    fwd = -eye / np.linalg.norm(eye)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    r_ct = np.stack([right, down, fwd])          # table -> camera rotation
    ext = np.eye(4)
    ext[:3, :3] = r_ct
    ext[:3, 3] = -r_ct @ eye
    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    fx, fy, cx, cy = INTRINSICS
    k_mat = o3d.core.Tensor([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=o3d.core.Dtype.Float64)
    rays = scene.create_rays_pinhole(k_mat, o3d.core.Tensor(ext), width, height)
    t = scene.cast_rays(rays)['t_hit'].numpy()
    d = rays.numpy()[..., 3:]
    hit = np.isfinite(t)
    p_table = rays.numpy()[..., :3] + d * np.where(hit, t, 0)[..., None]
    cloud = (p_table - eye) @ r_ct.T
    cloud += rng.normal(0, noise_std, cloud.shape) * (cloud[..., 2:3] / 1.0) ** 2
    cloud[~hit] = np.nan
    cyl_cam = [((c - eye) @ r_ct.T, r, h) for c, r, h in cyls]
    return TabletopScene(cloud, cyl_cam, INTRINSICS)

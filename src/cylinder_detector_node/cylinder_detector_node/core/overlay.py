"""Cylinders drawn on the RGB-D camera's image (the node's ~/overlay topic).

An organized cloud carries its image: the rgb field, row by row. Its pinhole intrinsics, when no
camera_info is at hand, follow from the cloud itself (u = fx x/z + cx, v = fy y/z + cy holds for
every valid point: two small least-squares fits). Each cylinder is drawn as its outline: the two
end circles and the two silhouette lines, projected, with its radius and height; a legend names
the colours.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from vizzy_runtime.overlay import FONT, draw_legend, drawing_scale

from .fitting import Cylinder

CYLINDER_COLOUR = (255, 60, 200)     # RGB
AXIS_COLOUR = (255, 255, 0)
LEGEND = ((CYLINDER_COLOUR, 'cylinder outline (r, h)'), (AXIS_COLOUR, 'axis'))


def intrinsics_from_organized(points: np.ndarray) -> np.ndarray | None:
    """3x3 K of an organized cloud (H x W x 3, camera optical frame, NaN where invalid), or None
    with fewer than 100 valid points or a degenerate fit."""
    h, w = points.shape[:2]
    v, u = np.mgrid[0:h, 0:w]
    z = points[..., 2]
    ok = np.isfinite(points).all(axis=-1) & (z > 1e-6)
    if ok.sum() < 100:
        return None
    xz = points[..., 0][ok] / z[ok]
    yz = points[..., 1][ok] / z[ok]
    (fx, cx), *_ = np.linalg.lstsq(np.stack([xz, np.ones_like(xz)], 1), u[ok].astype(float),
                                   rcond=None)
    (fy, cy), *_ = np.linalg.lstsq(np.stack([yz, np.ones_like(yz)], 1), v[ok].astype(float),
                                   rcond=None)
    if not (np.isfinite([fx, fy, cx, cy]).all() and fx > 0 and fy > 0):
        return None
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def _basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def cylinder_outline(c: Cylinder, segments: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """3D points (camera frame) of the two end circles, each (segments, 3)."""
    axis = np.asarray(c.axis, float)
    axis /= np.linalg.norm(axis)
    e1, e2 = _basis(axis)
    t = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = c.radius * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)
    centre = np.asarray(c.centre, float)
    return centre - axis * c.height / 2 + ring, centre + axis * c.height / 2 + ring


def project(points: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N x 2) of camera-frame points (N x 3); NaN behind the camera."""
    z = points[:, 2]
    uv = (points @ k.T)[:, :2] / np.where(z > 1e-6, z, np.nan)[:, None]
    return uv


def draw_cylinders(image: np.ndarray, k: np.ndarray, cylinders: Sequence[Cylinder]) -> np.ndarray:
    """A copy of image (rgb8) with each cylinder's outline, axis and size, and a legend."""
    out = image.copy()
    s, thick = drawing_scale(out)
    for c in cylinders:
        bottom, top = cylinder_outline(c)
        for ring in (bottom, top):
            uv = project(ring, k)
            if np.isfinite(uv).all():
                cv2.polylines(out, [np.round(uv).astype(np.int32)], True, CYLINDER_COLOUR, thick)
        # silhouette: the ring points farthest apart sideways in the image
        ub, ut = project(bottom, k), project(top, k)
        if np.isfinite(ub).all() and np.isfinite(ut).all():
            side = np.argsort(ub[:, 0])
            for i in (side[0], side[-1]):
                cv2.line(out, tuple(np.round(ub[i]).astype(int)),
                         tuple(np.round(ut[i]).astype(int)),
                         CYLINDER_COLOUR, thick)
        ends = project(np.array([bottom.mean(0), top.mean(0)]), k)
        if np.isfinite(ends).all():
            a, b = (tuple(np.round(p).astype(int)) for p in ends)
            cv2.line(out, a, b, AXIS_COLOUR, max(1, thick - 1), cv2.LINE_AA)
            text = f'r {100 * c.radius:.1f} cm h {100 * c.height:.1f} cm'
            org = (int(min(a[0], b[0])), int(max(12, min(a[1], b[1]) - 6)))
            cv2.putText(out, text, org, FONT, 0.45 * s, (0, 0, 0), thick + 2, cv2.LINE_AA)
            cv2.putText(out, text, org, FONT, 0.45 * s, CYLINDER_COLOUR, 1, cv2.LINE_AA)
    draw_legend(out, LEGEND)
    return out


__all__ = ['draw_cylinders', 'cylinder_outline', 'intrinsics_from_organized', 'project']

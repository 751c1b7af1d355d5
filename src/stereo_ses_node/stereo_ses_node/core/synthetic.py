"""Synthetic stereo pairs for tests and benchmarks: a textured fronto-parallel plane.

The plane z = depth (reference frame) carries a band-limited random texture; each camera's view
is rendered exactly by intersecting its pixel rays with the plane (cv2.remap into the texture).
"""

from __future__ import annotations

import cv2
import numpy as np

from .geometry import pixel_rays


def plane_texture(size: int = 1024, seed: int = 0) -> np.ndarray:
    """A size x size uint8 texture with structure at several scales."""
    rng = np.random.default_rng(seed)
    tex = np.zeros((size, size), np.float32)
    for blur in (1.0, 3.0, 9.0):
        layer = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), blur)
        tex += layer / (layer.std() + 1e-9)
    tex = (tex - tex.min()) / (tex.max() - tex.min())
    return (255 * tex).astype(np.uint8)


def render_plane(k: np.ndarray, pose: np.ndarray, width: int, height: int, depth: float,
                 texture: np.ndarray, texel_m: float = 0.002) -> np.ndarray:
    """RGB view (height, width, 3) of the plane z = depth, texture centred on the z axis."""
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    d = pixel_rays(np.stack([u, v], axis=-1), k, pose)
    c = pose[:3, 3]
    s = (depth - c[2]) / d[..., 2]
    x = c[0] + s * d[..., 0]
    y = c[1] + s * d[..., 1]
    n = texture.shape[0]
    mx = (x / texel_m + n / 2).astype(np.float32)
    my = (y / texel_m + n / 2).astype(np.float32)
    gray = cv2.remap(texture, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return np.repeat(gray[..., None], 3, axis=2)

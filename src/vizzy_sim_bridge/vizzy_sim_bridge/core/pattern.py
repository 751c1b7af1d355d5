"""Synthetic moving stereo pattern of the placeholder simulator (vectorized numpy)."""

from __future__ import annotations

import numpy as np


class SyntheticStereoScene:
    """A textured background with a bright disk moving on a Lissajous path.

    The disk is nearer than the background, so it has a larger disparity: the right image
    shows the background shifted by background_disparity_px and the disk by disk_disparity_px.
    """

    def __init__(self, width: int, height: int, background_disparity_px: float = 4.0,
                 disk_disparity_px: float = 24.0) -> None:
        if width <= 0 or height <= 0:
            raise ValueError(f'image size must be positive, got {width}x{height}')
        self.width, self.height = width, height
        self.background_disparity_px = background_disparity_px
        self.disk_disparity_px = disk_disparity_px
        self._u = np.arange(width, dtype=np.float32)
        self._v = np.arange(height, dtype=np.float32)
        # the background's green and checker row parity depend on the row only
        self._green = (60.0 + 120.0 * self._v / height).astype(np.uint8)
        self._row_parity = (np.floor(self._v / 40.0) % 2).astype(np.uint8)
        self._radius = 0.08 * min(width, height)

    def render(self, t: float, eye: str = 'left') -> np.ndarray:
        """The image (height x width x 3, uint8 RGB) seen by 'left' or 'right' at time t [s]."""
        if eye not in ('left', 'right'):
            raise ValueError(f"eye must be 'left' or 'right', got {eye!r}")
        right = eye == 'right'
        # background texture coordinate of each column (scrolling at 20 px/s)
        u_bg = self._u + (self.background_disparity_px if right else 0.0) + 20.0 * t
        col_parity = (np.floor(u_bg / 40.0) % 2).astype(np.uint8)
        img = np.empty((self.height, self.width, 3), dtype=np.uint8)
        img[:, :, 0] = (60.0 + 120.0 * (u_bg % self.width) / self.width).astype(np.uint8)
        img[:, :, 1] = self._green[:, None]
        img[:, :, 2] = np.where(self._row_parity[:, None] ^ col_parity[None, :], 150, 50)
        # the disk, drawn inside its bounding box only
        cu = self.width * (0.5 + 0.3 * np.sin(0.7 * t))
        cu -= self.disk_disparity_px if right else 0.0
        cv = self.height * (0.5 + 0.3 * np.sin(1.1 * t + 0.5))
        r = self._radius
        u0, u1 = max(int(cu - r), 0), min(int(cu + r) + 2, self.width)
        v0, v1 = max(int(cv - r), 0), min(int(cv + r) + 2, self.height)
        if u0 < u1 and v0 < v1:
            du, dv = self._u[u0:u1] - cu, self._v[v0:v1] - cv
            disk = (du[None, :] ** 2 + dv[:, None] ** 2) <= r * r
            img[v0:v1, u0:u1][disk] = (250, 230, 40)
        return img

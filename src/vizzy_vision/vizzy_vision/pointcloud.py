"""Point-cloud colour packing: PCL's and ROS's packed rgb, a float32 whose bits are 0x00RRGGBB
(sensor_msgs/PointCloud2 field 'rgb'), as the simulator's RGB-D sensor and the stereo node
publish it and the cylinder detector reads it."""

from __future__ import annotations

import numpy as np


def pack_rgb(rgb: np.ndarray) -> np.ndarray:
    """(..., 3) uint8 colours as (...) float32 whose bits are 0x00RRGGBB."""
    rgb = np.asarray(rgb, dtype=np.uint8)
    packed = ((rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8)
              | rgb[..., 2].astype(np.uint32))
    return packed.view(np.float32)


def unpack_rgb(packed: np.ndarray) -> np.ndarray:
    """Inverse of pack_rgb: (..., 3) uint8."""
    bits = np.ascontiguousarray(packed, dtype=np.float32).view(np.uint32)
    return np.stack([(bits >> 16) & 0xFF, (bits >> 8) & 0xFF, bits & 0xFF],
                    axis=-1).astype(np.uint8)


__all__ = ['pack_rgb', 'unpack_rgb']

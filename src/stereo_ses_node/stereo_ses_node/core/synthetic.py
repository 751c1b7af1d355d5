"""Synthetic stereo pairs for tests and benchmarks.

- A textured fronto-parallel plane: the plane z = depth (reference frame) carries a band-limited
  random texture; each camera's view is rendered exactly by intersecting its pixel rays with the
  plane (cv2.remap into the texture).
- Rectified pairs of slanted planar layers with known disparity and occlusions
  (`layered_pair`, `random_layers`): textures (real photographs in the benchmark) painted on
  planes whose disparities are linear in the left image's coordinates; the nearer layer wins
  in each view (z-order), so occluded pixels are known too.
"""

from __future__ import annotations

from dataclasses import dataclass

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


@dataclass(frozen=True)
class Layer:
    """A planar surface of a rectified scene: disparity d(x, y) = a x + b y + c in left-image px
    (a slanted plane), a texture painted in left-image coordinates and where it is (support,
    a left-image mask; None: everywhere)."""

    texture: np.ndarray
    plane: tuple[float, float, float]
    support: np.ndarray | None = None


def layered_pair(layers: list[Layer], width: int, height: int, noise_sd: float = 0.0,
                 gain: float = 1.0, seed: int = 0
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(left, right, disparity, visible) of a rectified pair of planar layers with occlusions.

    Each view shows, per pixel, the layer with the largest disparity (the nearest) among those
    whose support covers it: the left view directly, the right view by solving
    x_r = x_l - d(x_l, y) for x_l per layer (exact for planes). `disparity` is the left view's
    ground truth (float32 px), `visible` marks the left pixels whose point the right camera
    also sees (Middlebury's non-occluded mask). Views are the textures' dtype and channels,
    with Gaussian noise of noise_sd grey levels each and the right view's gain.
    """
    if not layers:
        raise ValueError('layered_pair needs at least one layer')
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    n = len(layers)
    best_l = np.full((height, width), -np.inf, np.float32)
    id_l = np.full((height, width), -1, np.int32)
    best_r = np.full((height, width), -np.inf, np.float32)
    id_r = np.full((height, width), -1, np.int32)
    xl_r = np.zeros((n, height, width), np.float32)
    for i, layer in enumerate(layers):
        a, b, c = (float(v) for v in layer.plane)
        d = a * xs + b * ys + c
        cover = np.ones((height, width), bool) if layer.support is None else layer.support
        take = cover & (d > best_l)
        best_l[take], id_l[take] = d[take], i
        xl = (xs + b * ys + c) / (1.0 - a)               # left x seen at right pixel (x, y)
        xl_r[i] = xl
        if layer.support is None:
            cover_r = np.ones((height, width), bool)
        else:
            m = cv2.remap(layer.support.astype(np.uint8), xl, ys, cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            cover_r = m > 0
        dr = xl - xs
        take = cover_r & (dr > best_r)
        best_r[take], id_r[take] = dr[take], i
    rng = np.random.default_rng(seed)

    def paint(ids: np.ndarray, mx: list[np.ndarray], g: float) -> np.ndarray:
        tex0 = layers[0].texture
        out = np.zeros((height, width) + tex0.shape[2:], np.float32)
        for i, layer in enumerate(layers):
            sel = ids == i
            if not sel.any():
                continue
            t = cv2.resize(layer.texture, (width, height), interpolation=cv2.INTER_AREA) \
                if layer.texture.shape[:2] != (height, width) else layer.texture
            img = cv2.remap(t, mx[i], ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
            out[sel] = img[sel]
        seen = out * g + rng.normal(0.0, noise_sd, out.shape) if noise_sd > 0 else out * g
        return np.clip(np.rint(seen), 0, 255).astype(tex0.dtype)

    left = paint(id_l, [xs] * n, 1.0)
    right = paint(id_r, list(xl_r), gain)
    xr = np.rint(xs - best_l).astype(np.int64)
    inside = (xr >= 0) & (xr < width)
    seen = np.zeros((height, width), bool)
    rows = ys.astype(np.int64)
    seen[inside] = id_r[rows[inside], xr[inside]] == id_l[inside]
    return left, right, best_l, seen


def random_layers(textures: list[np.ndarray], width: int, height: int, seed: int = 0,
                  background: tuple[float, float] = (18.0, 32.0),
                  foreground: tuple[float, float] = (38.0, 70.0)) -> list[Layer]:
    """A slanted background plane and len(textures) - 1 slanted foreground shapes (ellipses and
    polygons) with disparities in `foreground`; the first shape covers the image centre with
    its boundary near it (the fovea sees an occlusion edge)."""
    rng = np.random.default_rng(seed)
    lo, hi = background
    layers = [Layer(textures[0], (rng.uniform(-0.5, 0.5) * (hi - lo) / width,
                                  rng.uniform(0.2, 0.5) * (hi - lo) / height, lo))]
    flo, fhi = foreground
    for k, tex in enumerate(textures[1:]):
        mask = np.zeros((height, width), np.uint8)
        if k == 0:
            r = rng.uniform(0.15, 0.25) * min(width, height)
            ang = rng.uniform(0, 2 * np.pi)
            off = r - rng.uniform(0.03, 0.08) * min(width, height)
            cx, cy = width / 2 + off * np.cos(ang), height / 2 + off * np.sin(ang)
        else:
            r = rng.uniform(0.08, 0.2) * min(width, height)
            cx, cy = rng.uniform(0.1, 0.9) * width, rng.uniform(0.1, 0.9) * height
        if rng.random() < 0.5:
            cv2.ellipse(mask, (int(cx), int(cy)), (int(r), int(r * rng.uniform(0.6, 1.0))),
                        rng.uniform(0, 180), 0, 360, 1, -1)
        else:
            corners = np.sort(rng.uniform(0, 2 * np.pi, 6))
            rad = r * rng.uniform(0.7, 1.2, 6)
            pts = np.stack([cx + rad * np.cos(corners), cy + rad * np.sin(corners)], -1)
            cv2.fillPoly(mask, [pts.astype(np.int32)], 1)
        c0 = rng.uniform(flo + 3, fhi - 3)
        a, b = rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02)
        layers.append(Layer(tex, (a, b, c0 - a * cx - b * cy), mask.astype(bool)))
    return layers

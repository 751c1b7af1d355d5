"""Offscreen rendering of the head's cameras with MuJoCo, headless on the CPU (Mesa).

The OpenGL backend is EGL if it works, else OSMesa (MUJOCO_GL=egl or osmesa forces one). Each
is probed in a short child process, because PyOpenGL binds one platform per process for good.
With neither, RendererUnavailable says which Debian packages to install: libegl1 (EGL) or
libosmesa6 (OSMesa).

Settings that keep it fast on a CPU (see model.py's <visual>): no shadow map (shadowsize 0),
no multisampling (offsamples 0), no reflections; the robot's own geoms (group 3) are hidden
from its cameras. One render pass gives both the colour and the depth image.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from typing import Any

import mujoco
import numpy as np

from .model import ROBOT_GROUP

logging.getLogger('OpenGL').setLevel(logging.WARNING)   # PyOpenGL's "no OpenGL_accelerate" note

BACKENDS: tuple[str, ...] = ('egl', 'osmesa')
DEBIAN_PACKAGES: dict[str, str] = {'egl': 'libegl1', 'osmesa': 'libosmesa6'}

_PROBE = """
import sys
backend = sys.argv[1]
if backend == 'egl':
    from mujoco.egl import GLContext
else:
    from mujoco.osmesa import GLContext
ctx = GLContext(32, 32)
ctx.make_current()
ctx.free()
print('ok')
"""


class RendererUnavailable(RuntimeError):
    """No offscreen OpenGL (neither EGL nor OSMesa works here)."""


def probe_backend(backend: str, timeout: float = 60.0) -> str | None:
    """None if backend can create an offscreen context here, else why not (in a child process)."""
    env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
    try:
        proc = subprocess.run([sys.executable, '-c', _PROBE, backend], env=env, timeout=timeout,
                              capture_output=True, text=True)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f'{type(exc).__name__}: {exc}'
    if proc.returncode == 0 and 'ok' in proc.stdout:
        return None
    lines = [ln for ln in (proc.stderr or proc.stdout).strip().splitlines() if ln.strip()]
    return lines[-1] if lines else f'exit status {proc.returncode}'


def unavailable_message(errors: dict[str, str]) -> str:
    tried = '; '.join(f'{b}: {why}' for b, why in errors.items())
    return ('no offscreen OpenGL renderer for MuJoCo. Install EGL or OSMesa, e.g. '
            f'`sudo apt-get install {DEBIAN_PACKAGES["egl"]}` (EGL, preferred) or '
            f'`sudo apt-get install {DEBIAN_PACKAGES["osmesa"]}` (OSMesa), or set MUJOCO_GL to a '
            f'working backend. Tried: {tried}')


_selected: str | None = None


def select_backend(preference: str = 'auto', probe: Any = probe_backend) -> str:
    """The OpenGL backend to render with: preference ('egl', 'osmesa') or the first of BACKENDS
    that works ('auto'; MUJOCO_GL, when it names one of them, counts as the preference).

    Raises RendererUnavailable naming the Debian packages when none works.
    """
    global _selected
    if preference == 'auto':
        env = os.environ.get('MUJOCO_GL', '').strip().lower()
        if env in BACKENDS:
            preference = env
    if preference not in ('auto',) + BACKENDS:
        raise ValueError(f'unknown render backend {preference!r}; use auto, egl or osmesa')
    if _selected is not None and preference in ('auto', _selected) and probe is probe_backend:
        return _selected
    candidates = BACKENDS if preference == 'auto' else (preference,)
    errors: dict[str, str] = {}
    for backend in candidates:
        why = probe(backend)
        if why is None:
            if probe is probe_backend:
                _selected = backend
            return backend
        errors[backend] = why
    raise RendererUnavailable(unavailable_message(errors))


def gl_context_class(backend: str) -> Any:
    """mujoco's GLContext class for backend (binds PyOpenGL to it for this process)."""
    platform = os.environ.get('PYOPENGL_PLATFORM')
    if platform and platform != backend:
        raise RendererUnavailable(
            f'PYOPENGL_PLATFORM={platform} but the renderer needs {backend}; unset it or set '
            f'MUJOCO_GL={platform}')
    os.environ.setdefault('MUJOCO_GL', backend)
    try:
        if backend == 'egl':
            from mujoco.egl import GLContext
        else:
            from mujoco.osmesa import GLContext
    except Exception as exc:  # ImportError, OSError from ctypes, PyOpenGL errors
        raise RendererUnavailable(
            unavailable_message({backend: f'{type(exc).__name__}: {exc}'})) from exc
    return GLContext


class CameraRenderer:
    """Renders the model's fixed cameras offscreen: RGB (H x W x 3 uint8) and metric depth.

    Use from one thread (the one that created it: the GL context is current there).
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int,
                 backend: str = 'auto', max_geom: int | None = None) -> None:
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(f'{width}x{height} exceeds the model offscreen buffer '
                             f'{model.vis.global_.offwidth}x{model.vis.global_.offheight}')
        self.backend = select_backend(backend)
        self.model = model
        self.width, self.height = int(width), int(height)
        self._gl = gl_context_class(self.backend)(self.width, self.height)
        self._gl.make_current()
        self._ctx = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_50)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._ctx)
        self._ctx.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        # room for every geom and site of the model (one visual geom each) and some decor:
        # 4000 by default cost ~2.5 MB for the 47 geoms of the tabletop (issue 27)
        if max_geom is None:
            max_geom = 4 * (int(model.ngeom) + int(model.nsite)) + 200
        self._scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self._scene.flags[mujoco.mjtRndFlag.mjRND_FOG] = False
        self._scene.flags[mujoco.mjtRndFlag.mjRND_HAZE] = False
        self._option = mujoco.MjvOption()
        self._option.geomgroup[ROBOT_GROUP] = 0
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._rgb = np.empty(self.height * self.width * 3, np.uint8)
        self._depth = np.empty(self.height * self.width, np.float32)
        extent = float(model.stat.extent)
        self.znear = float(model.vis.map.znear) * extent
        self.zfar = float(model.vis.map.zfar) * extent
        zf, zn = np.float32(self.zfar), np.float32(self.znear)
        c = -(zf + zn) / (zf - zn)
        d = -(np.float32(2) * zf * zn) / (zf - zn)
        self._c = float(np.float32(-0.5) * c - np.float32(0.5))   # reversed-Z (ZEROFAR) mapping,
        self._d = float(np.float32(-0.5) * d)                     # as mujoco.Renderer does
        self._closed = False

    def camera_id(self, name: str) -> int:
        cid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, name)
        if cid < 0:
            raise ValueError(f'no camera {name!r} in the model')
        return cid

    def render(self, data: mujoco.MjData, camera: int | str, depth: bool = False,
               width: int | None = None,
               height: int | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """(rgb, depth) seen by camera (id or name) in data (kinematics already computed).

        width x height (default: the renderer's size, at most that) is the image size; the
        camera's fovy is the vertical field of view. rgb: H x W x 3 uint8, a view into an
        internal buffer (copy it to keep it past the next call); row 0 is the top of the image.
        depth (only if asked): H x W float32 distance along the optical axis [m]; inf where
        nothing was hit.
        """
        if self._closed:
            raise RuntimeError('render after close')
        w, h = int(width or self.width), int(height or self.height)
        if not (0 < w <= self.width and 0 < h <= self.height):
            raise ValueError(f'{w}x{h} does not fit the renderer ({self.width}x{self.height})')
        self._gl.make_current()
        self._camera.fixedcamid = self.camera_id(camera) if isinstance(camera, str) else int(camera)
        mujoco.mjv_updateScene(self.model, data, self._option, None, self._camera,
                               mujoco.mjtCatBit.mjCAT_ALL, self._scene)
        rect = mujoco.MjrRect(0, 0, w, h)
        rgb_buf = self._rgb[:h * w * 3].reshape(h, w, 3)
        depth_buf = self._depth[:h * w].reshape(h, w)
        mujoco.mjr_render(rect, self._scene, self._ctx)
        mujoco.mjr_readPixels(rgb_buf, depth_buf if depth else None, rect, self._ctx)
        rgb = rgb_buf[::-1]
        if not depth:
            return rgb, None
        # d / (raw + c) in float64, in one buffer (the same operations, the same bits, without
        # two more 2.4 MB temporaries a frame: issue 27)
        raw = depth_buf[::-1]
        metric = raw.astype(np.float64)
        metric += self._c
        with np.errstate(divide='ignore'):
            np.divide(self._d, metric, out=metric)
        metric[raw <= 0.0] = np.inf   # reversed Z: 0 is the far plane (sky, nothing hit)
        return rgb, metric.astype(np.float32)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._gl.make_current()
            self._ctx.free()
        finally:
            self._gl.free()

    def __enter__(self) -> CameraRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:  # noqa: SIM105 (no contextlib in __del__: module globals may be gone at shutdown)
            self.close()
        except Exception:  # interpreter shutdown: OpenGL may already be gone
            pass


__all__ = ['BACKENDS', 'CameraRenderer', 'DEBIAN_PACKAGES', 'RendererUnavailable',
           'gl_context_class', 'probe_backend', 'select_backend', 'unavailable_message']

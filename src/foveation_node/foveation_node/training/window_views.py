"""Training and held-out views of a window model: the W x W square around a fixation of a
foveated left-eye render, resized to the network's S x S input (core.recognition's "window
models": the network sees only what the fovea holds, at the fovea's resolution).

Every view is `crop_window(foveate(rgb, fixation), fixation, W)` resized to S x S, where rgb is
a 640x480 left-eye render (training.tabletop_views) and the foveation has K = 5 levels and f_0
drawn from F0_RANGE (the held-out sets: the node's f_0, HELD_OUT_F0). Sources (SOURCES, one
code per view):

- `fixated`: the closed loop's case. The head fixates an object as the gaze controller does
  when the object map sends the object's centre (its body origin, in base_link): both optical
  axes through the point (`vizzy_gaze.core.gaze.solve_fixation`), the point jittered by
  POINT_JITTER_M per axis; the object is then at the principal point, and FIXATED_PER_OBJECT
  views are taken at the principal point +- FIXATION_JITTER_PX (one f_0 each). Objects whose
  centre is occluded are skipped. Held out: the point not jittered, one view at the principal
  point (`fixated_exact`).
- `anywhere`: objects seen in random head poses (tabletop_views.random_joints over the table,
  background_views.away_joints anywhere), fixated at their centre +- FIXATION_JITTER_PX.
- background: fixations on no object, at least window_margin(f_0) (f_0 / 2, at least
  MIN_MARGIN_PX) from every object's box (TableView.extents): here the network sees only the
  window, so an object farther than that from the window's centre may lie in it, off-centre,
  and must not count. `background_near` (within W / 2 of that margin: the window holds part of
  an object off-centre) in the fixated and over-table poses, `background_table` (anywhere in
  the image) in the over-table poses, `background_away` (poses anywhere within the joint
  limits: walls, floor, ceiling), `background_wall` (the head tilted up at the wall behind the
  table, as the demo ends: wall_joints).
- visual_search scenes (textured walls, cans on stands): `search_fixated` (each can fixated
  as above), `search_can` (cans seen in poses anywhere) and `search_background` (background
  fixations in those poses and near the fixated cans).

Labels: the object the eye sees at the fixation (the ray through it: TabletopViews.object_under),
else the object fixated (off a thin object, in a handle's gap); background: len(CLASSES).
Scenes are rendered in chunks of CHUNK scenes (`render_chunk`), each from its own random
streams (seeded by the scene seed), so a set is the same however its chunks are cached or
spread over processes. Needs mujoco, vizzy_sim_bridge and vizzy_gaze (training only).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from foveation_node.core.recognition import crop_window

from .background_views import away_joints, background_fixations
from .object_views import CLASSES
from .tabletop_views import TableObject, TabletopViews, TableView, random_joints

WINDOW = 160                    # px of the 640x480 image around the fixation
INPUT = 96                      # px, the network's input side
PRINCIPAL_POINT = (319.5, 239.5)
F0_RANGE = (60.0, 160.0)
HELD_OUT_F0 = 100               # the node's default f_0
FIXATION_JITTER_PX = 12.0       # sigma of the fixation's offset from the point fixated
POINT_JITTER_M = 0.006          # sigma per axis of the fixated point (about 1 cm in all)
FIXATED_PER_OBJECT = 3          # views per fixated object (training)
MIN_MARGIN_PX = 30.0
OVER_TABLE_POSES = 3            # per tabletop scene (random_joints)
AWAY_POSES = 2                  # per tabletop scene (away_joints)
WALL_POSES = 1                  # per tabletop scene (wall_joints)
BACKGROUND_PER_POSE = 2
SEARCH_POSES = 4                # per visual_search scene (away_joints)
SEARCH_FIXATED_PER_CAN = 2
CHUNK = 25                      # scenes per cached chunk

SOURCES = ('fixated', 'fixated_exact', 'anywhere', 'background_near', 'background_table',
           'background_away', 'background_wall', 'search_fixated', 'search_can',
           'search_background')
BACKGROUND = len(CLASSES)


def window_margin(f0: float) -> float:
    """Least distance [px] from a background fixation to every object's box: f0 / 2, at least
    MIN_MARGIN_PX (object views lie within about 2 FIXATION_JITTER_PX of an object's centre)."""
    return max(float(f0) / 2.0, MIN_MARGIN_PX)


def wall_joints(rng: np.random.Generator) -> tuple[float, ...]:
    """The head tilted up at the wall behind the table (the demo's last pose, e.g. neck tilt
    -0.15, eyes tilt -0.1): neck pan +-0.4, neck tilt -0.35..-0.05, eyes tilt -0.35..0 rad,
    version +-0.15 rad."""
    version = float(rng.uniform(-0.15, 0.15))
    return (float(rng.uniform(-0.4, 0.4)), float(rng.uniform(-0.35, -0.05)),
            float(rng.uniform(-0.35, 0.0)), version, version)


def fixation_joints(point_world: np.ndarray) -> tuple[float, ...] | None:
    """Head joints fixating a world point (both optical axes through it), as the gaze
    controller would for that point in base_link; None when it is out of reach."""
    from vizzy_gaze.core.gaze import GazeError, solve_fixation
    from vizzy_vision.kinematics import WAIST_HEIGHT

    point = np.asarray(point_world, float) - np.array([0.0, 0.0, WAIST_HEIGHT])   # base_link
    try:
        return tuple(float(j) for j in solve_fixation(point).joints)
    except GazeError:
        return None


@dataclass
class WindowSet:
    """(n, S, S, 3) uint8 views, (n,) int64 labels and (n,) int8 source codes (SOURCES)."""

    images: np.ndarray
    labels: np.ndarray
    sources: np.ndarray

    @classmethod
    def empty(cls, size: int) -> WindowSet:
        return cls(np.zeros((0, size, size, 3), np.uint8), np.zeros(0, np.int64),
                   np.zeros(0, np.int8))

    @classmethod
    def concat(cls, sets: list[WindowSet], size: int) -> WindowSet:
        sets = [s for s in sets if len(s.labels)]
        if not sets:
            return cls.empty(size)
        return cls(np.concatenate([s.images for s in sets]),
                   np.concatenate([s.labels for s in sets]),
                   np.concatenate([s.sources for s in sets]))

    def save(self, path: Path) -> None:
        tmp = path.with_name(path.name + '.part.npz')
        np.savez(tmp, images=self.images, labels=self.labels, sources=self.sources)
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> WindowSet:
        data = np.load(path)
        return cls(data['images'], data['labels'], data['sources'])


class _Windows:
    """Collects the windows of foveated renders; one Foveator per whole-pixel f_0."""

    def __init__(self, window: int, size: int) -> None:
        from foveation_node.core.foveation import Foveator

        self._make = Foveator
        self._foveators: dict[tuple[int, int, int], Foveator] = {}
        self.window, self.size = int(window), int(size)
        self.images: list[np.ndarray] = []
        self.labels: list[int] = []
        self.sources: list[int] = []

    def add(self, rgb: np.ndarray, u: float, v: float, f0: int, label: int, source: str) -> None:
        h, w = rgb.shape[:2]
        key = (w, h, f0)
        if key not in self._foveators:
            self._foveators[key] = self._make(w, h, 5, float(f0))
        fov = self._foveators[key].foveate(rgb, (u, v))
        crop = crop_window(fov, (u, v), self.window)
        self.images.append(cv2.resize(crop, (self.size, self.size),
                                      interpolation=cv2.INTER_AREA))
        self.labels.append(int(label))
        self.sources.append(SOURCES.index(source))

    def result(self) -> WindowSet:
        if not self.labels:
            return WindowSet.empty(self.size)
        return WindowSet(np.stack(self.images), np.asarray(self.labels, np.int64),
                         np.asarray(self.sources, np.int8))


def _jittered(rng: np.random.Generator, u: float, v: float, w: int, h: int
              ) -> tuple[float, float]:
    return (float(np.clip(u + rng.normal(0, FIXATION_JITTER_PX), 0, w - 1)),
            float(np.clip(v + rng.normal(0, FIXATION_JITTER_PX), 0, h - 1)))


def _background(out: _Windows, view: TableView, rng: np.random.Generator, n: int, source: str,
                held_out: bool, near: bool = False) -> None:
    """Up to n background windows of view (near: an object part in the window, off-centre)."""
    f0 = HELD_OUT_F0 if held_out else int(rng.uniform(*F0_RANGE))
    margin = window_margin(f0)
    h, w = view.rgb.shape[:2]
    within = margin + out.window / 2.0 if near else np.inf
    for u, v in background_fixations(view.extents, w, h, rng, n, margin, within):
        out.add(view.rgb, u, v, f0, BACKGROUND, source)


def _label_at(tv: TabletopViews, view: TableView, u: float, v: float, target: TableObject
              ) -> int:
    """The class of the object the eye sees at (u, v) (TabletopViews.object_under); target's
    where the ray through (u, v) meets no object (off a thin object, through a handle's gap)."""
    name = tv.object_under(u, v)
    if name is None or name == target.name:
        return target.label
    return next(label for label, n, _ in tv.object_points(view.seed) if n == name)


def _seen(tv: TabletopViews, o: TableObject) -> bool:
    """o's centre is in the image and not hidden by another object (the ray through it meets o,
    or no object: a handle's centre lies in its gap)."""
    return tv.object_under(*o.centre) in (o.name, None)


def _objects_seen(out: _Windows, tv: TabletopViews, view: TableView, rng: np.random.Generator,
                  source: str, held_out: bool) -> None:
    """One window per unoccluded object of view, at its centre +- FIXATION_JITTER_PX."""
    h, w = view.rgb.shape[:2]
    for o in view.objects:
        if not (o.visible and _seen(tv, o)):
            continue
        u, v = _jittered(rng, *o.centre, w, h)
        f0 = HELD_OUT_F0 if held_out else int(rng.uniform(*F0_RANGE))
        out.add(view.rgb, u, v, f0, _label_at(tv, view, u, v, o), source)


def _fixated(out: _Windows, tv: TabletopViews, seed: int, rng: np.random.Generator,
             per_object: int, source: str, background_source: str, held_out: bool) -> None:
    """The head fixating each object of scene seed in turn (module docstring)."""
    for _, name, point in tv.object_points(seed):
        if not held_out:
            point = point + rng.normal(0.0, POINT_JITTER_M, 3)
        joints = fixation_joints(point)
        if joints is None:
            continue
        view = tv.view(seed, joints)
        target = next((o for o in view.objects if o.name == name), None)
        if target is None or tv.object_under(*PRINCIPAL_POINT) not in (name, None):
            continue                                    # hidden where the head looks
        h, w = view.rgb.shape[:2]
        for _ in range(1 if held_out else per_object):
            u, v = PRINCIPAL_POINT if held_out else _jittered(rng, *PRINCIPAL_POINT, w, h)
            f0 = HELD_OUT_F0 if held_out else int(rng.uniform(*F0_RANGE))
            out.add(view.rgb, u, v, f0, _label_at(tv, view, u, v, target), source)
        _background(out, view, rng, 1, background_source, held_out, near=True)


def render_tabletop_scene(out: _Windows, tv: TabletopViews, seed: int, held_out: bool) -> None:
    """Every window of tabletop scene seed (module docstring); held_out: the node's f_0 and the
    fixated objects at the principal point exactly."""
    rng = np.random.default_rng([seed, 31])
    try:
        tv.object_points(seed)
    except RuntimeError:                                # the builder could not place objects
        return
    _fixated(out, tv, seed, rng, FIXATED_PER_OBJECT,
             'fixated_exact' if held_out else 'fixated', 'background_near', held_out)
    for _ in range(OVER_TABLE_POSES):
        view = tv.view(seed, random_joints(rng))
        _objects_seen(out, tv, view, rng, 'anywhere', held_out)
        _background(out, view, rng, 1, 'background_table', held_out)
        _background(out, view, rng, 1, 'background_near', held_out, near=True)
    for joints, source in ([(away_joints(rng), 'background_away') for _ in range(AWAY_POSES)]
                           + [(wall_joints(rng), 'background_wall') for _ in range(WALL_POSES)]):
        view = tv.view(seed, joints)
        _objects_seen(out, tv, view, rng, 'anywhere', held_out)
        _background(out, view, rng, BACKGROUND_PER_POSE, source, held_out)


def render_search_scene(out: _Windows, tv: TabletopViews, seed: int, held_out: bool) -> None:
    """Every window of visual_search scene seed: its cans fixated and seen in poses anywhere,
    background in those poses and near the fixated cans."""
    rng = np.random.default_rng([seed, 32])
    _fixated(out, tv, seed, rng, SEARCH_FIXATED_PER_CAN, 'search_fixated',
             'search_background', held_out)
    for _ in range(SEARCH_POSES):
        view = tv.view(seed, away_joints(rng))
        _objects_seen(out, tv, view, rng, 'search_can', held_out)
        _background(out, view, rng, BACKGROUND_PER_POSE, 'search_background', held_out)


def render_chunk(scene: str, seed0: int, scenes: int, held_out: bool, window: int = WINDOW,
                 size: int = INPUT, progress: Callable[[int], Any] | None = None) -> WindowSet:
    """The windows of scenes seed0 .. seed0 + scenes - 1 of scene ('tabletop' or
    'visual_search'); progress(seed) after each scene."""
    from vizzy_sim_bridge.core.scenes import visual_search

    out = _Windows(window, size)
    render = render_tabletop_scene if scene == 'tabletop' else render_search_scene
    with TabletopViews(scene=visual_search if scene == 'visual_search' else None) as tv:
        for seed in range(seed0, seed0 + scenes):
            render(out, tv, seed, held_out)
            if progress is not None:
                progress(seed)
    return out.result()


def chunk_path(cache_dir: Path, scene: str, seed0: int, scenes: int, held_out: bool,
               window: int, size: int) -> Path:
    kind = 'val' if held_out else 'train'
    return cache_dir / f'{scene}_{kind}_{seed0}_{scenes}_w{window}_s{size}.npz'


def render_set(scene: str, seed0: int, scenes: int, held_out: bool, window: int, size: int,
               cache_dir: Path | None = None, shard: tuple[int, int] = (0, 1),
               desc: str = '') -> WindowSet:
    """The windows of scenes seed0 .. seed0 + scenes - 1 in chunks of CHUNK scenes, each loaded
    from cache_dir if there, else rendered (and saved). shard (i, n): render only the chunks
    whose index is i mod n (the others are loaded if cached, else left out): n processes can
    render one set together."""
    from tqdm import tqdm

    sets = []
    if cache_dir is not None:
        cache_dir.mkdir(parents=True, exist_ok=True)
    starts = list(range(seed0, seed0 + scenes, CHUNK))
    with tqdm(total=scenes, desc=desc or f'{scene} {"held-out" if held_out else "train"}',
              unit='scene') as bar:
        for i, start in enumerate(starts):
            n = min(CHUNK, seed0 + scenes - start)
            path = (chunk_path(cache_dir, scene, start, n, held_out, window, size)
                    if cache_dir is not None else None)
            if path is not None and path.exists():
                sets.append(WindowSet.load(path))
                bar.update(n)
            elif i % shard[1] == shard[0]:
                part = render_chunk(scene, start, n, held_out, window, size,
                                    progress=lambda _: bar.update(1))
                if path is not None:
                    part.save(path)
                sets.append(part)
            else:
                bar.update(n)
    return WindowSet.concat(sets, size)


__all__ = ['BACKGROUND', 'CHUNK', 'F0_RANGE', 'FIXATION_JITTER_PX', 'HELD_OUT_F0', 'INPUT',
           'PRINCIPAL_POINT', 'SOURCES', 'WINDOW', 'WindowSet', 'chunk_path', 'fixation_joints',
           'render_chunk', 'render_set', 'wall_joints', 'window_margin']

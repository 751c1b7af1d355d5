"""Procedural walking people for the pedestrian scene (thesis chapter 5), as MJCF fragments.

Each person is a mocap root body (moved kinematically along its own path) carrying an
articulated body built from primitives: pelvis, torso (yaw joint), head with hair, arms
(shoulder and elbow hinges) and legs (hip, knee and ankle hinges). Nothing is simulated:
:meth:`PedestrianCrowd.update` poses every walker as a pure function of the simulation time
``t`` (mocap pose and limb ``qpos``), so a recording is repeatable frame by frame.

Frames follow REP 103 (x forward from the robot base, y left, z up, ground at z = 0).

Gait model (per leg, phase 0 = heel strike of that leg, legs half a cycle apart):
  hip flexion    5 deg + A_hip cos(2 pi phase), A_hip from the stride length (about 16-19 deg)
  knee flexion   4 deg + a loading bump (14 deg at 13 %) + the swing flexion (58 deg at 72 %)
  foot pitch     toe up 15 deg at heel strike, flat in mid stance, toe down 35 deg at toe-off
  shoulder       opposite to the hip of the same side (0.75 A_hip), elbow flexes as the arm
                 swings forward, the torso counter-rotates by 4 deg
The pelvis height is set so the lowest heel or toe touches the ground, which gives the
vertical bob (about 4 cm peak to peak) of a real gait; the pelvis also sways 2 cm sideways.
Stride length 0.83 H sqrt(v / 1.3 m/s) (about 1.45 m at 1.3 m/s for H = 1.75 m, i.e. 108
steps/min; 90-105 steps/min at 1.0-1.2 m/s), rounded so a whole number of strides fits in the
period. Segment lengths are Drillis-Contini fractions of the height H.

Paths: each person walks a closed polygon of 3-5 random waypoints with rounded corners
(straight lines and turns) inside ``area``. Every walker's motion repeats with a common period
(``period``, 20 s; a walker goes round its loop once or twice per period, ``max_laps``), so the
constructor can check separations over one whole period and keep people apart at all times:
walkers are placed one by one, each the most separated of many random loops and start points,
then the closest ones are re-drawn (``min_distance`` holds the smallest distance reached,
typically 0.7-0.85 m for 4-6 people in the default 4.5 m x 5 m area).

Appearance: shirt (plain knit, plaid or striped procedural texture, long or short sleeves),
trousers (speckled cloth), skin, hair (short or long) and shoe colours from realistic palettes
with jitter; heights 1.6-1.9 m, builds 0.92-1.12. OpenCV's default HOG people detector finds
about 84 % of the unoccluded walkers >= 128 px tall in 640x480 frames from 1.1 m up before a
plain wall (experiments/pedestrian_hog_check.py).

Only numpy is needed to build the XML and to evaluate poses; ``mujoco`` is imported lazily by
:meth:`PedestrianCrowd.update` (for ``mj_kinematics``). All geoms have contype = conaffinity = 0
and the limb bodies gravcomp = 1, so physics steps leave the poses as update() set them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

Area = tuple[tuple[float, float], tuple[float, float]]
RGB = tuple[float, float, float]

# clothing, skin and hair palettes (linear-ish sRGB in 0..1); colours get a small jitter
SHIRT_COLOURS: tuple[RGB, ...] = (
    (0.92, 0.92, 0.90), (0.75, 0.75, 0.76), (0.12, 0.15, 0.30), (0.08, 0.08, 0.09),
    (0.62, 0.10, 0.10), (0.12, 0.32, 0.18), (0.45, 0.62, 0.82), (0.85, 0.72, 0.30),
    (0.40, 0.10, 0.16), (0.80, 0.70, 0.55), (0.85, 0.42, 0.12), (0.30, 0.30, 0.32),
    (0.20, 0.35, 0.55), (0.55, 0.45, 0.70),
)
TROUSER_COLOURS: tuple[RGB, ...] = (
    (0.10, 0.14, 0.28), (0.07, 0.07, 0.08), (0.70, 0.62, 0.45), (0.32, 0.32, 0.34),
    (0.30, 0.20, 0.12), (0.40, 0.50, 0.66), (0.18, 0.22, 0.18), (0.55, 0.55, 0.52),
)
SKIN_COLOURS: tuple[RGB, ...] = (
    (0.96, 0.80, 0.69), (0.90, 0.70, 0.57), (0.78, 0.57, 0.42), (0.60, 0.42, 0.29),
    (0.40, 0.27, 0.18), (0.93, 0.76, 0.63),
)
HAIR_COLOURS: tuple[RGB, ...] = (
    (0.05, 0.04, 0.03), (0.18, 0.11, 0.06), (0.35, 0.22, 0.12), (0.78, 0.64, 0.38),
    (0.55, 0.54, 0.52), (0.45, 0.20, 0.08),
)
SHOE_COLOURS: tuple[RGB, ...] = (
    (0.06, 0.06, 0.06), (0.90, 0.90, 0.88), (0.30, 0.18, 0.10), (0.25, 0.25, 0.28),
)

_REF_HEIGHT = 1.75  # [m] the body dimensions below are for this height and scale with it


def _gauss(phase: np.ndarray | float, mu: float, sigma: float) -> np.ndarray:
    """A periodic (period 1) Gaussian bump of unit height centred at mu."""
    d = (np.asarray(phase, dtype=float) - mu + 0.5) % 1.0 - 0.5
    return np.exp(-0.5 * (d / sigma) ** 2)


def gait_angles(phase: np.ndarray | float, hip_amplitude_deg: float = 22.0
                ) -> dict[str, np.ndarray]:
    """Sagittal joint angles [rad] of one leg and of the arm of the same side at gait phase.

    Returns hip, knee (flexion positive), foot_pitch (global, toe up positive), ankle
    (dorsiflexion positive, relative to the shank), shoulder (flexion forward positive) and
    elbow (flexion positive). The shoulder swings opposite to the hip of the same side.
    """
    ph = np.asarray(phase, dtype=float) % 1.0
    c = np.cos(2.0 * np.pi * ph)
    hip = 5.0 + hip_amplitude_deg * c
    knee = 4.0 + 14.0 * _gauss(ph, 0.13, 0.06) + 58.0 * _gauss(ph, 0.72, 0.10)
    foot = (15.0 * _gauss(ph, 0.0, 0.05) + 6.0 * _gauss(ph, 0.9, 0.06)
            - 35.0 * _gauss(ph, 0.58, 0.07))
    shoulder = 3.0 - 0.75 * hip_amplitude_deg * c
    elbow = 15.0 + 15.0 * (1.0 - c) / 2.0
    shank = hip - knee  # shank pitch from the vertical, forward positive
    ankle = foot - shank
    rad = np.radians
    return {'hip': rad(hip), 'knee': rad(knee), 'ankle': rad(ankle), 'foot_pitch': rad(foot),
            'shoulder': rad(shoulder), 'elbow': rad(elbow), 'shank': rad(shank)}


@dataclass(frozen=True)
class _Body:
    """Segment dimensions [m] of one person."""

    height: float
    build: float  # width factor (shoulders, hips, limbs)

    @property
    def s(self) -> float:
        return self.height / _REF_HEIGHT

    @property
    def thigh(self) -> float:
        return 0.245 * self.height

    @property
    def shank(self) -> float:
        return 0.246 * self.height

    @property
    def ankle_height(self) -> float:
        return 0.07 * self.s

    @property
    def hip_height(self) -> float:
        return self.thigh + self.shank + self.ankle_height

    @property
    def upper_arm(self) -> float:
        return 0.186 * self.height

    @property
    def forearm(self) -> float:
        return 0.146 * self.height

    @property
    def heel(self) -> tuple[float, float]:
        """(x, z) of the heel's lower corner in the foot frame (at the ankle)."""
        return (-0.08 * self.s, -0.07 * self.s)

    @property
    def toe(self) -> tuple[float, float]:
        return (0.17 * self.s, -0.07 * self.s)


@dataclass
class Pedestrian:
    """One walker: body, appearance, path and gait parameters."""

    index: int
    body: _Body
    speed: float                     # [m/s]
    stride: float                    # [m] per gait cycle (two steps)
    hip_amplitude_deg: float
    phase0: float                    # gait phase at t = 0
    s0: float                        # arc length at t = 0 [m]
    path_s: np.ndarray = field(repr=False)       # (n,) arc length samples [m]
    path_xy: np.ndarray = field(repr=False)      # (n, 2)
    path_heading: np.ndarray = field(repr=False)  # (n,) unwrapped heading [rad]
    length: float = 0.0               # loop length [m]
    shirt: RGB = (0.5, 0.5, 0.5)
    shirt_pattern: str = 'plain'
    trousers: RGB = (0.2, 0.2, 0.2)
    skin: RGB = (0.8, 0.6, 0.5)
    hair: RGB = (0.1, 0.1, 0.1)
    shoes: RGB = (0.1, 0.1, 0.1)
    long_hair: bool = False
    long_sleeves: bool = True

    def arc(self, t: np.ndarray | float) -> np.ndarray:
        return (self.s0 + self.speed * np.asarray(t, dtype=float)) % self.length

    def pose2d(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Ground position (..., 2) and heading (...) [rad] at time t (no gait sway)."""
        s = self.arc(t)
        xy = np.stack([np.interp(s, self.path_s, self.path_xy[:, 0]),
                       np.interp(s, self.path_s, self.path_xy[:, 1])], axis=-1)
        heading = np.interp(s, self.path_s, self.path_heading)
        return xy, heading

    def gait_phase(self, t: float) -> float:
        return (self.phase0 + self.speed * t / self.stride) % 1.0


def _rounded_loop(points: np.ndarray, corner: float, ds: float = 0.02
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A closed path through the polygon `points` with corners rounded by quadratic Beziers.

    Straight segments are joined by a Bezier from `corner` m before each vertex to `corner` m
    after it (less on short edges); the curve stays in the polygon's convex hull. Returns arc
    length samples every ds, the points and the unwrapped heading.
    """
    n = len(points)
    pieces = []
    for i in range(n):
        p_prev, p, p_next = points[i - 1], points[i], points[(i + 1) % n]
        u_in, u_out = p - p_prev, p_next - p
        l_in, l_out = float(np.linalg.norm(u_in)), float(np.linalg.norm(u_out))
        c = min(corner, 0.45 * l_in, 0.45 * l_out)
        a, b = p - u_in / l_in * c, p + u_out / l_out * c
        w = np.linspace(0.0, 1.0, 40)[:, None]
        pieces.append((1 - w) ** 2 * a + 2 * (1 - w) * w * p + w ** 2 * b)
        q_next = points[(i + 2) % n]
        u_next = q_next - p_next
        c_next = min(corner, 0.45 * l_out, 0.45 * float(np.linalg.norm(u_next)))
        a_next = p_next - u_out / l_out * c_next
        pieces.append(b + np.linspace(0.0, 1.0, 40)[1:-1, None] * (a_next - b))
    dense = np.concatenate(pieces + [pieces[0][:1]])
    seg = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    length = float(cum[-1])
    s = np.linspace(0.0, length, max(int(length / ds), 8) + 1)
    xy = np.stack([np.interp(s, cum, dense[:, 0]), np.interp(s, cum, dense[:, 1])], axis=-1)
    d = np.diff(np.concatenate([xy, xy[1:2]]), axis=0)  # forward difference, wraps around
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return s, xy, heading


def _fmt(*v: float) -> str:
    return ' '.join(f'{x:.6g}' for x in v)


def _quat_axis_deg(axis: tuple[float, float, float], angle_deg: float) -> str:
    """MJCF quat (w x y z) of a rotation about a unit axis (quats work whatever the
    compiler's angle unit is)."""
    h = math.radians(angle_deg) / 2
    return _fmt(math.cos(h), *(math.sin(h) * a for a in axis))


class PedestrianCrowd:
    """Several people walking on their own looping paths, for the pedestrian scene.

    Args:
        rng: source of every random choice (paths, bodies, clothes); the same seed gives the
            same crowd.
        count: number of people.
        area: ((x_min, x_max), (y_min, y_max)) [m] in the world frame where people walk
            (their ground position stays inside it, `margin` from its edges).
        speed_range: walking speeds [m/s].
        height_range: body heights [m].
        period: [s] every walker's motion repeats with this period.
        min_separation: [m] the smallest distance between two walkers' ground positions that
            the constructor aims for (checked over a whole period; if no layout is found in
            `max_tries` the most separated one is kept; then the walker closest to another is
            re-drawn, up to `refine_rounds` times per walker).
        margin: [m] between a path and the area's edge.
        max_laps: at most this many laps of its loop per period (fewer: longer loops).
        prefix: name prefix of every body, joint, geom, texture and material.
    """

    def __init__(self, rng: np.random.Generator, count: int, *,
                 area: Area = ((1.5, 6.0), (-2.5, 2.5)),
                 speed_range: tuple[float, float] = (1.0, 1.5),
                 height_range: tuple[float, float] = (1.6, 1.9),
                 period: float = 20.0,
                 min_separation: float = 0.7,
                 margin: float = 0.3,
                 max_tries: int = 200,
                 refine_rounds: int = 4,
                 max_laps: int = 2,
                 prefix: str = 'ped') -> None:
        if count < 0:
            raise ValueError(f'count must be >= 0, got {count}')
        (x0, x1), (y0, y1) = area
        if x1 - x0 < 2 * margin + 0.5 or y1 - y0 < 2 * margin + 0.5:
            raise ValueError(f'area {area} is too small to walk in (margin {margin} m)')
        if not 0 < speed_range[0] <= speed_range[1]:
            raise ValueError(f'bad speed range {speed_range}')
        self.area: Area = ((float(x0), float(x1)), (float(y0), float(y1)))
        self.margin = margin
        self.period = float(period)
        self.prefix = prefix
        self.speed_range = speed_range
        self.height_range = height_range
        self.max_laps = max_laps
        self.min_separation = min_separation
        self.people: list[Pedestrian] = []
        self._last_t = 0.0
        self._index_cache: tuple[Any, dict[str, Any]] | None = None
        self._times = np.arange(0.0, self.period, 0.1)
        self._max_tries = max_tries
        tracks: list[np.ndarray] = []
        for i in range(count):  # greedy: each new walker as far as possible from the others
            person, track, _ = self._best_person(rng, i, tracks)
            self.people.append(person)
            tracks.append(track)
        for _ in range(refine_rounds * count):  # then re-draw the walker closest to another
            if count < 2:
                break
            seps = [self._separation(tracks[k], tracks[:k] + tracks[k + 1:]) for k in range(count)]
            k = int(np.argmin(seps))
            if seps[k] >= min_separation:
                break
            person, track, sep = self._best_person(rng, k, tracks[:k] + tracks[k + 1:])
            if sep > seps[k]:
                self.people[k], tracks[k] = person, track
        self.min_distance = min((self._separation(tracks[k], tracks[k + 1:])
                                 for k in range(count - 1)), default=math.inf)

    # ---------------------------------------------------------------- layout
    @staticmethod
    def _separation(track: np.ndarray, others: Sequence[np.ndarray]) -> Any:
        """Smallest distance over time between a track (..., T, 2) and the others (T, 2):
        a float for one track, an array for a batch (inf when there are no others)."""
        if not others:
            return math.inf
        d = np.linalg.norm(track[..., None, :, :] - np.stack(others), axis=-1)
        return d.min(axis=(-2, -1))

    def _best_person(self, rng: np.random.Generator, index: int, tracks: list[np.ndarray]
                     ) -> tuple[Pedestrian, np.ndarray, float]:
        """The most separated of up to max_tries random walkers (16 start points per loop)."""
        best: tuple[Pedestrian, np.ndarray, float] | None = None
        for attempt in range(2 * self._max_tries):
            if best is not None and attempt >= self._max_tries:
                break
            # if no loop allows max_laps laps per period, any number of laps will do
            person = self._sample_person(rng, index,
                                         self.max_laps if attempt < self._max_tries else 50)
            if person is None:
                continue
            starts = (person.s0 + np.arange(16)[:, None] * person.length / 16) % person.length
            arc = (starts + person.speed * self._times) % person.length
            cand = np.stack([np.interp(arc, person.path_s, person.path_xy[:, 0]),
                             np.interp(arc, person.path_s, person.path_xy[:, 1])], axis=-1)
            seps = np.atleast_1d(self._separation(cand, tracks))
            j = int(np.argmax(seps))
            if best is None or seps[j] > best[2]:
                best = (replace(person, s0=float(starts[j, 0])), cand[j], float(seps[j]))
            if best[2] >= self.min_separation:
                break
        if best is None:
            raise RuntimeError(f'could not lay out a walking loop in area {self.area}')
        return best

    def _sample_person(self, rng: np.random.Generator, index: int, max_laps: int
                       ) -> Pedestrian | None:
        (x0, x1), (y0, y1) = self.area
        m = self.margin
        n = int(rng.integers(3, 6))
        pts = np.stack([rng.uniform(x0 + m, x1 - m, n), rng.uniform(y0 + m, y1 - m, n)], axis=1)
        centre = pts.mean(axis=0)
        order = np.argsort(np.arctan2(pts[:, 1] - centre[1], pts[:, 0] - centre[0]))
        pts = pts[order]
        if rng.random() < 0.5:
            pts = pts[::-1]
        edges = np.roll(pts, -1, axis=0) - pts
        lengths = np.linalg.norm(edges, axis=1)
        if lengths.min() < min(1.0, 0.4 * min(x1 - x0, y1 - y0) - 0.8 * m):
            return None
        u = edges / lengths[:, None]
        turn = np.degrees(np.arccos(np.clip(np.sum(u * np.roll(u, 1, axis=0), axis=1), -1, 1)))
        if turn.max() > 140.0:
            return None
        s, xy, heading = _rounded_loop(pts, corner=0.7)
        length = float(s[-1])
        vmin, vmax = self.speed_range
        ks = [k for k in range(1, max_laps + 1) if vmin <= k * length / self.period <= vmax]
        if not ks:
            return None
        speed = ks[int(rng.integers(len(ks)))] * length / self.period
        height = float(rng.uniform(*self.height_range))
        body = _Body(height=height, build=float(rng.uniform(0.92, 1.12)))
        stride = 0.83 * height * math.sqrt(speed / 1.3)
        leg = body.thigh + body.shank
        hip_amp = float(np.clip(0.75 * math.degrees(math.asin(min(0.9, stride / 4.0 / leg))),
                                12.0, 22.0))
        # the gait repeats with the common period too: a whole number of strides per period
        cycles = max(1, round(speed * self.period / stride))
        stride = speed * self.period / cycles

        def pick(palette: Sequence[RGB], jitter: float = 0.04) -> RGB:
            c = np.asarray(palette[int(rng.integers(len(palette)))])
            c = np.clip(c * rng.uniform(1 - jitter * 2, 1 + jitter * 2) + rng.normal(0, jitter, 3),
                        0.02, 0.98)
            return (float(c[0]), float(c[1]), float(c[2]))

        return Pedestrian(
            index=index, body=body, speed=speed, stride=stride, hip_amplitude_deg=hip_amp,
            phase0=float(rng.random()), s0=float(rng.uniform(0, length)),
            path_s=s, path_xy=xy, path_heading=heading, length=length,
            shirt=pick(SHIRT_COLOURS),
            shirt_pattern=str(rng.choice(['plain', 'checker', 'stripes'])),
            trousers=pick(TROUSER_COLOURS), skin=pick(SKIN_COLOURS, 0.02),
            hair=pick(HAIR_COLOURS, 0.02), shoes=pick(SHOE_COLOURS, 0.02),
            long_hair=bool(rng.random() < 0.3), long_sleeves=bool(rng.random() < 0.6))

    # ---------------------------------------------------------------- MJCF
    def _name(self, i: int, part: str) -> str:
        return f'{self.prefix}{i}_{part}'

    def assets_xml(self) -> str:
        """<texture> and <material> elements (to go inside <asset>)."""
        out = []
        for p in self.people:
            i = p.index
            shade = tuple(0.72 * c for c in p.shirt)
            repeat = '1 1'
            if p.shirt_pattern == 'checker':    # small plaid
                tex = (f'builtin="checker" rgb1="{_fmt(*p.shirt)}" rgb2="{_fmt(*shade)}" '
                       f'mark="random" random="0.04" markrgb="{_fmt(*shade)}"')
                repeat = '5 5'
            elif p.shirt_pattern == 'stripes':  # horizontal bands (a repeated gradient)
                tex = (f'builtin="gradient" rgb1="{_fmt(*p.shirt)}" rgb2="{_fmt(*shade)}" '
                       f'mark="random" random="0.04" markrgb="{_fmt(*shade)}"')
                repeat = '1 6'
            else:                                # plain knit: speckle noise
                tex = (f'builtin="flat" rgb1="{_fmt(*p.shirt)}" rgb2="{_fmt(*p.shirt)}" '
                       f'mark="random" random="0.08" markrgb="{_fmt(*shade)}"')
                repeat = '3 3'
            out.append(f'<texture name="{self._name(i, "shirt")}" type="2d" width="64" '
                       f'height="64" {tex}/>')
            dark = tuple(0.75 * c for c in p.trousers)
            out.append(f'<texture name="{self._name(i, "trousers")}" type="2d" builtin="flat" '
                       f'width="64" height="64" rgb1="{_fmt(*p.trousers)}" '
                       f'rgb2="{_fmt(*p.trousers)}" '
                       f'mark="random" random="0.15" markrgb="{_fmt(*dark)}"/>')
            streak = tuple(min(1.0, 1.4 * c + 0.05) for c in p.hair)
            out.append(f'<texture name="{self._name(i, "hair")}" type="2d" builtin="flat" '
                       f'width="32" height="32" rgb1="{_fmt(*p.hair)}" rgb2="{_fmt(*p.hair)}" '
                       f'mark="random" random="0.15" markrgb="{_fmt(*streak)}"/>')
            for part, rep in (('shirt', repeat), ('trousers', '4 4'), ('hair', '4 4')):
                out.append(f'<material name="{self._name(i, part)}" '
                           f'texture="{self._name(i, part)}" '
                           f'texrepeat="{rep}" specular="0.05" shininess="0.05"/>')
            out.append(f'<material name="{self._name(i, "skin")}" rgba="{_fmt(*p.skin)} 1" '
                       f'specular="0.15" shininess="0.2"/>')
            out.append(f'<material name="{self._name(i, "shoes")}" rgba="{_fmt(*p.shoes)} 1" '
                       f'specular="0.3" shininess="0.4"/>')
        return '\n'.join(out)

    def worldbody_xml(self) -> str:
        """The people's bodies (to go inside <worldbody>): mocap roots with articulated limbs."""
        return '\n'.join(self._person_xml(p) for p in self.people)

    def _person_xml(self, p: Pedestrian) -> str:
        i, b = p.index, p.body
        s, w = b.s, b.s * b.build  # length scale, width scale

        def n(part: str) -> str:
            return self._name(i, part)

        def geom(part: str, gtype: str, size: Sequence[float], material: str, place: str) -> str:
            # place: pos="..." or fromto="..."; no contacts (the walkers are kinematic)
            return (f'<geom name="{n(part)}" type="{gtype}" size="{_fmt(*size)}" {place} '
                    f'material="{n(material)}" contype="0" conaffinity="0" group="0"/>')

        def joint(part: str, axis: str) -> str:
            return (f'<joint name="{n(part)}" type="hinge" axis="{axis}" damping="5" '
                    f'armature="0.01" limited="false"/>')

        def body(part: str, pos: Sequence[float], quat: str = '') -> str:
            q = f' quat="{quat}"' if quat else ''
            return f'<body name="{n(part)}" pos="{_fmt(*pos)}"{q} gravcomp="1">'

        xy, heading = p.pose2d(0.0)
        sleeve = 'shirt' if p.long_sleeves else 'skin'
        z_sh, y_sh = 0.288 * b.height, 0.185 * w  # shoulder joints above the hip joints
        z_head = 0.405 * b.height                  # head centre above the hip joints
        z_yoke = z_sh - 0.015 * s                  # the shoulders' capsule, just below the joints
        lines = [
            f'<body name="{n("root")}" mocap="true" pos="{_fmt(xy[0], xy[1], 0)}" '
            f'quat="{_fmt(math.cos(heading / 2), 0, 0, math.sin(heading / 2))}">',
            ' ' + body('pelvis', (0, 0, b.hip_height)),
            '  ' + geom('pelvis', 'ellipsoid', (0.105 * w, 0.165 * w, 0.11 * s), 'trousers',
                        f'pos="0 0 {0.03 * s:.4f}"'),
            '  ' + body('torso', (0, 0, 0), _quat_axis_deg((0, 1, 0), 3.0)),  # leans forward
            '   ' + joint('torso_yaw', '0 0 1'),
            '   ' + geom('abdomen', 'ellipsoid', (0.105 * w, 0.16 * w, 0.16 * s), 'shirt',
                         f'pos="0 0 {0.17 * s:.4f}"'),
            '   ' + geom('chest', 'ellipsoid', (0.12 * w, 0.175 * w, 0.19 * s), 'shirt',
                         f'pos="{_fmt(0.01 * s, 0, 0.35 * s)}"'),
            '   ' + geom('shoulders', 'capsule', (0.065 * w,), 'shirt',
                         f'fromto="{_fmt(0, -0.15 * w, z_yoke, 0, 0.15 * w, z_yoke)}"'),
            '   ' + geom('neck', 'capsule', (0.052 * s,), 'skin',
                         f'fromto="{_fmt(0, 0, z_sh - 0.03 * s, 0.005, 0, z_head - 0.07 * s)}"'),
            '   ' + body('head', (0.01 * s, 0, z_head)),
            '    ' + geom('head', 'ellipsoid', (0.097 * s, 0.078 * s, 0.115 * s), 'skin',
                          'pos="0 0 0"'),
            '    ' + geom('hair', 'ellipsoid', (0.1 * s, 0.083 * s, 0.085 * s), 'hair',
                          f'pos="{_fmt(-0.014 * s, 0, 0.04 * s)}"'),
            '    ' + geom('nose', 'ellipsoid', (0.02 * s, 0.014 * s, 0.025 * s), 'skin',
                          f'pos="{_fmt(0.09 * s, 0, -0.01 * s)}"'),
        ]
        if p.long_hair:
            lines.append('    ' + geom('long_hair', 'ellipsoid', (0.06 * s, 0.09 * s, 0.14 * s),
                                       'hair', f'pos="{_fmt(-0.06 * s, 0, -0.06 * s)}"'))
        lines.append('   </body>')
        for side, sign in (('l', 1.0), ('r', -1.0)):
            lines += [  # arms hang 7 deg out from the body
                '   ' + body(side + '_upper_arm', (0, sign * y_sh, z_sh),
                             _quat_axis_deg((1, 0, 0), sign * 7.0)),
                '    ' + joint(side + '_shoulder', '0 -1 0'),
                '    ' + geom(side + '_upper_arm', 'capsule', (0.05 * w,), 'shirt',
                              f'fromto="{_fmt(0, 0, -0.02 * s, 0, 0, -b.upper_arm)}"'),
                '    ' + body(side + '_forearm', (0, 0, -b.upper_arm)),
                '     ' + joint(side + '_elbow', '0 -1 0'),
                '     ' + geom(side + '_forearm', 'capsule', (0.041 * w,), sleeve,
                               f'fromto="{_fmt(0, 0, 0, 0, 0, -b.forearm)}"'),
                '     ' + geom(side + '_hand', 'ellipsoid', (0.028 * s, 0.042 * s, 0.08 * s),
                               'skin', f'pos="{_fmt(0.005, 0, -b.forearm - 0.07 * s)}"'),
                '    </body>',
                '   </body>',
            ]
        lines.append('  </body>')  # torso
        for side, sign in (('l', 1.0), ('r', -1.0)):
            lines += [
                '  ' + body(side + '_thigh', (0, sign * 0.092 * w, 0)),
                '   ' + joint(side + '_hip', '0 -1 0'),
                '   ' + geom(side + '_thigh', 'capsule', (0.078 * w,), 'trousers',
                             f'fromto="{_fmt(0, 0, -0.02 * s, 0, 0, -b.thigh)}"'),
                '   ' + body(side + '_shank', (0, 0, -b.thigh)),
                '    ' + joint(side + '_knee', '0 1 0'),
                '    ' + geom(side + '_shank', 'capsule', (0.058 * w,), 'trousers',
                              f'fromto="{_fmt(0, 0, 0, 0, 0, -b.shank + 0.02 * s)}"'),
                '    ' + body(side + '_foot', (0, 0, -b.shank)),
                '     ' + joint(side + '_ankle', '0 -1 0'),
                '     ' + geom(side + '_foot', 'box', (0.125 * s, 0.046 * w, 0.035 * s), 'shoes',
                               f'pos="{_fmt(0.045 * s, 0, -0.035 * s)}"'),
                '    </body>',
                '   </body>',
                '  </body>',
            ]
        lines += [' </body>', '</body>']
        return '\n'.join(lines)

    # ---------------------------------------------------------------- animation
    JOINTS = ('torso_yaw', 'l_hip', 'l_knee', 'l_ankle', 'r_hip', 'r_knee', 'r_ankle',
              'l_shoulder', 'l_elbow', 'r_shoulder', 'r_elbow')

    def joint_positions(self, t: float) -> np.ndarray:
        """(count, len(JOINTS)) joint angles [rad] at time t."""
        out = np.zeros((len(self.people), len(self.JOINTS)))
        for k, p in enumerate(self.people):
            out[k] = self._pose(p, t)[2]
        return out

    def _pose(self, p: Pedestrian, t: float) -> tuple[np.ndarray, float, np.ndarray]:
        """Root position (3,), heading and the joint angles (JOINTS order) of p at time t."""
        xy, heading = p.pose2d(t)
        phase_l = p.gait_phase(t)
        gl = gait_angles(phase_l, p.hip_amplitude_deg)
        gr = gait_angles(phase_l + 0.5, p.hip_amplitude_deg)
        b = p.body
        drops = []
        for g in (gl, gr):
            hip, shank, foot = float(g['hip']), float(g['shank']), float(g['foot_pitch'])
            ankle_drop = b.thigh * math.cos(hip) + b.shank * math.cos(shank)
            # lowest heel/toe corner below the ankle for the foot's pitch (toe up positive)
            below = max(-(x * math.sin(foot) + z * math.cos(foot)) for x, z in (b.heel, b.toe))
            drops.append(ankle_drop + below)
        bob = max(drops) - b.hip_height  # <= 0 (the legs are never longer than when straight)
        sway = 0.02 * b.s * math.sin(2 * math.pi * phase_l)
        c, s = math.cos(heading), math.sin(heading)
        root = np.array([xy[0] - s * sway, xy[1] + c * sway, bob])
        torso_yaw = math.radians(4.0) * math.cos(2 * math.pi * phase_l)
        q = np.array([torso_yaw, gl['hip'], gl['knee'], gl['ankle'], gr['hip'], gr['knee'],
                      gr['ankle'], gl['shoulder'], gl['elbow'], gr['shoulder'], gr['elbow']],
                     dtype=float)
        return root, float(heading), q

    def _indices(self, model: Any) -> dict[str, Any]:
        if self._index_cache is not None and self._index_cache[0] is model:
            return self._index_cache[1]
        mocap, qadr, dadr, geoms, geom_owner = [], [], [], [], np.full(model.ngeom, -1, dtype=int)
        for p in self.people:
            root = model.body(self._name(p.index, 'root')).id
            mocap.append(int(model.body_mocapid[root]))
            joints = [model.joint(self._name(p.index, jn)) for jn in self.JOINTS]
            qadr.append([int(jt.qposadr[0]) for jt in joints])
            dadr.append([int(jt.dofadr[0]) for jt in joints])
            bodies = np.flatnonzero(np.asarray(model.body_rootid) == root)
            ids = np.flatnonzero(np.isin(np.asarray(model.geom_bodyid), bodies))
            geoms.append(ids)
            geom_owner[ids] = p.index
        nj = len(self.JOINTS)
        idx = {'mocap': np.array(mocap, dtype=int),
               'qpos': np.array(qadr, dtype=int).reshape(-1, nj),
               'dof': np.array(dadr, dtype=int).reshape(-1, nj),
               'geoms': geoms, 'geom_owner': geom_owner}
        self._index_cache = (model, idx)
        return idx

    def geom_owner(self, model: Any) -> np.ndarray:
        """(ngeom,) index of the person each geom belongs to, -1 for geoms of no person."""
        return self._indices(model)['geom_owner']

    def update(self, model: Any, data: Any, t: float, *, kinematics: bool = True) -> None:
        """Pose every walker at simulation time t [s] (mocap pose and limb qpos; qvel zeroed).

        A pure function of t: calling it with the same t always gives the same pose. With
        `kinematics` (default) it then runs mujoco.mj_kinematics, mj_comPos and mj_camlight so
        body, geom, camera and light poses in `data` are current for rendering and for
        :meth:`ground_truth` (a later mj_forward/mj_step recomputes the same poses).
        """
        if not self.people:
            return
        idx = self._indices(model)
        for k, p in enumerate(self.people):
            root, heading, q = self._pose(p, t)
            data.mocap_pos[idx['mocap'][k]] = root
            data.mocap_quat[idx['mocap'][k]] = (math.cos(heading / 2), 0.0, 0.0,
                                                math.sin(heading / 2))
            data.qpos[idx['qpos'][k]] = q
            data.qvel[idx['dof'][k]] = 0.0
        self._last_t = float(t)
        if kinematics:
            import mujoco
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_camlight(model, data)

    def ground_truth(self, model: Any, data: Any) -> list[dict[str, Any]]:
        """Per person: id, name, world axis-aligned box (box_min, box_max) of all its geoms,
        ground position (x, y, 0) on its path, heading [rad], velocity (vx, vy, 0) [m/s],
        height [m], at the time of the last :meth:`update` (boxes from the poses in `data`).
        """
        idx = self._indices(model) if self.people else None
        out = []
        for k, p in enumerate(self.people):
            assert idx is not None
            lo, hi = geom_aabb(model, data, idx['geoms'][k])
            xy, heading = p.pose2d(self._last_t)
            out.append({
                'id': p.index, 'name': self._name(p.index, 'root'),
                'box_min': [float(v) for v in lo], 'box_max': [float(v) for v in hi],
                'position': [float(xy[0]), float(xy[1]), 0.0],
                'heading': float(math.remainder(float(heading), 2 * math.pi)),
                'velocity': [p.speed * math.cos(heading), p.speed * math.sin(heading), 0.0],
                'height': p.body.height,
            })
        return out

    def positions(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Ground positions (count, 2) and headings (count,) at time t (no mujoco needed)."""
        if not self.people:
            return np.zeros((0, 2)), np.zeros(0)
        poses = [p.pose2d(t) for p in self.people]
        return np.array([xy for xy, _ in poses]), np.array([h for _, h in poses])


def geom_aabb(model: Any, data: Any, geom_ids: Sequence[int] | np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """World axis-aligned bounding box (min, max) of the given geoms (exact for spheres,
    capsules, ellipsoids, boxes and cylinders; bounding sphere otherwise)."""
    ids = np.asarray(geom_ids, dtype=int)
    pos = np.asarray(data.geom_xpos)[ids]
    rot = np.asarray(data.geom_xmat)[ids].reshape(-1, 3, 3)
    size = np.asarray(model.geom_size)[ids]
    gtype = np.asarray(model.geom_type)[ids]
    ext = np.empty_like(pos)
    for k, (typ, r, sz) in enumerate(zip(gtype, rot, size, strict=True)):
        if typ == 2:    # sphere
            e = np.full(3, sz[0])
        elif typ == 3:  # capsule
            e = np.abs(r[:, 2]) * sz[1] + sz[0]
        elif typ == 4:  # ellipsoid
            e = np.sqrt((r ** 2) @ (sz ** 2))
        elif typ == 5:  # cylinder
            e = np.abs(r[:, 2]) * sz[1] + sz[0] * np.sqrt(np.clip(1 - r[:, 2] ** 2, 0, 1))
        elif typ == 6:  # box
            e = np.abs(r) @ sz
        else:
            e = np.full(3, float(np.asarray(model.geom_rbound)[ids[k]]))
        ext[k] = e
    return (pos - ext).min(axis=0), (pos + ext).max(axis=0)


def preview_scene_xml(crowd: PedestrianCrowd, *, width: int = 640, height: int = 480,
                      hfov_deg: float = 85.4, camera_height: float = 1.1,
                      backdrop_x: float = 9.0) -> str:
    """A stand-alone MJCF scene for tests and experiments (the real scenes are built elsewhere).

    A mid-grey textured floor, a textured backdrop wall and side walls, two lights, the crowd,
    and a camera named 'eye' at (0, 0, camera_height) looking along +x with the given
    horizontal field of view at width x height.
    """
    fovy = 2 * math.degrees(math.atan(math.tan(math.radians(hfov_deg) / 2) * height / width))
    return f"""<mujoco model="pedestrian_preview">
  <visual>
    <quality shadowsize="0" offsamples="0"/>
    <global offwidth="{width}" offheight="{height}"/>
    <headlight ambient="0.35 0.35 0.35" diffuse="0.35 0.35 0.35" specular="0 0 0"/>
  </visual>
  <asset>
    <texture name="floor" type="2d" builtin="checker" width="256" height="256"
             rgb1="0.50 0.50 0.50" rgb2="0.44 0.44 0.45" mark="random" random="0.08"
             markrgb="0.38 0.38 0.38"/>
    <material name="floor" texture="floor" texrepeat="40 40" specular="0.05"/>
    <texture name="wall" type="2d" builtin="checker" width="256" height="256"
             rgb1="0.78 0.76 0.70" rgb2="0.72 0.70 0.64" mark="edge" markrgb="0.62 0.60 0.55"/>
    <material name="wall" texture="wall" texrepeat="10 4" specular="0.05"/>
    {crowd.assets_xml()}
  </asset>
  <worldbody>
    <light name="sun" directional="true" pos="0 0 5" dir="0.3 0.2 -1" diffuse="0.55 0.55 0.55"
           specular="0.1 0.1 0.1"/>
    <geom name="floor" type="plane" size="20 20 0.1" material="floor" contype="0" conaffinity="0"/>
    <geom name="backdrop" type="box" pos="{backdrop_x} 0 4" size="0.05 10 4" material="wall"
          contype="0" conaffinity="0"/>
    <geom name="left_wall" type="box" pos="4 7 4" size="6 0.05 4" material="wall"
          contype="0" conaffinity="0"/>
    <geom name="right_wall" type="box" pos="4 -7 4" size="6 0.05 4" material="wall"
          contype="0" conaffinity="0"/>
    <camera name="eye" pos="0 0 {camera_height}" xyaxes="0 -1 0 0 0 1" fovy="{fovy:.4f}"/>
    {crowd.worldbody_xml()}
  </worldbody>
</mujoco>"""

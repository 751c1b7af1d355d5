"""Resource-constrained multiple object tracker: the pipeline of Fig. 5.1.

Each frame: predict every target's belief (Eq. 5.3); plan which search regions to attend
(MCTS, sections 5.3.3-5.3.5) or take the full frame; run the detector only there; associate
detections to targets (Hungarian on Mahalanobis distance, gated); update the matched beliefs
(Eq. 5.2) with the observation model's noise at the detected scale (Eqs. 5.8-5.15); manage
the track set.

Track births: the first frame is a full-frame detection and every detection starts a track
(section 5.4's bootstrap). The thesis created no tracks after that; as its future work
suggests, ``new_tracks`` can also start them from unmatched detections:

- ``'budget'`` (default, the deployed configuration): S_max binds every frame. The tracks'
  regions may read at most ``(1 - birth_share) S_max`` of the image per frame (union of the
  crops, :func:`.regions.read_area`); what a frame leaves of its ``S_max`` is saved, and a
  full-frame detection (where new people are found) is made when the savings pay for a whole
  image and at least ``full_frame_period`` frames have passed since the last one. So after
  the bootstrap frame the pixels read never exceed ``S_max`` times the frames so far, and a
  frame that is not a full frame never reads more than ``S_max`` of the image.
- ``'none'``: the thesis protocol (bootstrap only);
- ``'periodic'``: a full-frame detection every ``full_frame_period`` frames (not charged);
- ``'sweep'``: each frame also scans one vertical strip of the image (``sweep_fraction`` of
  its width, plus one window width of overlap), cycling over the image; its area counts in
  the detector time.

Tracks born after the bootstrap are tentative until detected ``confirm_hits`` times and
dropped after ``tentative_misses`` + 1 consecutive misses (the thesis-style rule drops them on
the first; one more look saves the people HOG misses once, about 30 % of looks). A track is
deleted when it has been missed more than ``max_misses`` consecutive times in frames where its
region was processed, when its centre leaves the image, or when its position uncertainty
exceeds ``max_std_frac`` of its window size (it can no longer be found).

Occlusion (``occluded_share``, an extension: the thesis's observation model has no
occlusion): a track whose predicted box is covered by at least that share by the box of a
nearer track (a larger scale: a person closer to the camera) is not expected to be detected.
The planner does not spend a region on it, a processed frame does not count it as missed, and
it keeps being predicted (and reported) until it comes out from behind the other person.
Without it, people who cross behind others are looked for where they cannot be seen, deleted
after ``max_misses`` misses and wait for the next full frame to be found again.

Ego-motion: when the camera rotated since the previous frame, ``step(image, homography=H)``
(``H = K R K^-1``, :mod:`.egomotion`) first moves every belief into the current camera, then
predicts; without it a head movement makes every target jump out of its search region.

Bad input (not uint8, empty, wrong shape, a frame size that differs from the first frame)
raises :class:`FrameError` before anything changes; all per-frame work is done on copies and
committed at the end, so an exception from the detector also leaves the tracker as it was.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .association import associate, gate_threshold
from .detector import Detections, Detector, box_intersection, box_iou, check_image
from .egomotion import warp_beliefs
from .kalman import STATE_DIM, MotionModel, predict, update
from .observation import ObservationModel
from .planner import MctsPlanner, Plan, PlannerConfig
from .regions import READ_MODES, full_frame_region, read_area

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


NEW_TRACKS = ('budget', 'none', 'periodic', 'sweep')


class FrameError(ValueError):
    """A frame the tracker cannot use; the tracker's state is unchanged."""


@dataclass(frozen=True)
class TrackerConfig:
    """Tracker settings (the planner's are in :class:`PlannerConfig`).

    mode: 'planner' (attend the planned regions) or 'full' (detector on every full frame:
        the baseline).
    new_tracks, full_frame_period, sweep_fraction, birth_share: track births (module
        docstring).
    confirm_hits: detections a track born after the bootstrap needs before it is reported.
    tentative_misses: consecutive misses a tentative track survives (0: dropped on its first;
        a miss while occluded does not count).
    max_misses: most consecutive misses (in processed frames) a track survives.
    birth_score: a track is born only from a detection scoring at least this (the detector's
        score; -inf: any); weaker detections still update tracks.
    keep_lost: a confirmed track deleted inside the image (misses, or lost) is remembered and
        predicted for this many frames; a detection no live track takes that falls in its gate
        brings it back under its id instead of starting a new track (0: forget at once).
    report_misses: a confirmed track is reported while it has at most this many consecutive
        misses (None: always, while it lives); a hidden track keeps predicting and is
        reported again once re-detected, under the same id.
    max_std_frac: delete when the centre std exceeds this fraction of the window size.
    gate_probability: chi-square gate of the association.
    init_velocity_std, init_scale_velocity_std: velocity std of a new track at scale 1
        (pixels/frame, scale/frame), times its scale.
    quantization: 'worst' (thesis) or 'uniform' (authors' code), see :class:`ObservationModel`.
    extra_detector_std: detector noise beyond quantization, fraction of the window [u, v, s].
    new_track_iou: an unmatched detection overlapping a track's window by more than this
        does not start a new track.
    occluded_share: a track whose object box is covered by at least this share by a nearer
        track's is occluded (module docstring); None: no occlusion reasoning (thesis).
    """

    mode: Literal['planner', 'full'] = 'planner'
    new_tracks: Literal['budget', 'none', 'periodic', 'sweep'] = 'budget'
    full_frame_period: int = 30
    sweep_fraction: float = 0.05
    birth_share: float = 0.15
    confirm_hits: int = 2
    tentative_misses: int = 0
    max_misses: int = 5
    report_misses: int | None = None
    keep_lost: int = 0
    birth_score: float = -np.inf
    max_std_frac: float = 1.5
    gate_probability: float = 0.99
    init_velocity_std: float = 4.0
    init_scale_velocity_std: float = 0.02
    quantization: str = 'worst'
    extra_detector_std: tuple[float, float, float] = (0.05, 0.05, 0.05)
    new_track_iou: float = 0.3
    occluded_share: float | None = None
    motion: MotionModel = field(default_factory=MotionModel)
    planner: PlannerConfig = field(default_factory=PlannerConfig)

    def __post_init__(self) -> None:
        problems = []
        if self.mode not in ('planner', 'full'):
            problems.append(f"mode must be 'planner' or 'full', got {self.mode!r}")
        if self.new_tracks not in NEW_TRACKS:
            problems.append(f'new_tracks must be one of {NEW_TRACKS}, got {self.new_tracks!r}')
        if not 0.0 <= self.birth_share < 1.0:
            problems.append(f'birth_share must be in [0, 1), got {self.birth_share}')
        if self.full_frame_period < 1:
            problems.append(f'full_frame_period must be >= 1, got {self.full_frame_period}')
        if not 0.0 < self.sweep_fraction <= 1.0:
            problems.append(f'sweep_fraction must be in (0, 1], got {self.sweep_fraction}')
        if self.confirm_hits < 1 or self.max_misses < 1:
            problems.append('confirm_hits and max_misses must be >= 1')
        if self.tentative_misses < 0:
            problems.append(f'tentative_misses must be >= 0, got {self.tentative_misses}')
        if self.max_std_frac <= 0:
            problems.append(f'max_std_frac must be > 0, got {self.max_std_frac}')
        if self.occluded_share is not None and not 0.0 < self.occluded_share <= 1.0:
            problems.append(f'occluded_share must be in (0, 1] or None, got '
                            f'{self.occluded_share}')
        if problems:
            raise ValueError('TrackerConfig: ' + '; '.join(problems))


#: The deployed configuration (the node's defaults; ``evaluate``'s default protocol): track
#: births paid from the S_max budget, the constraint counting the pixels the detector reads
#: (at the resolution it reads them), births only from confident detections (birth_score is
#: on HOG's SVM margin: another detector plug-in needs its own), a track reported through one
#: missed frame, a person's size that changes slowly (scale acceleration and a new track's
#: scale velocity 5x and 4x below the thesis-protocol values: at S_max 0.1 the size uncertainty
#: of a person not looked at made the search regions too large to afford; tuned on the
#: simulated street's seeds 0-1, docs/mot_planner.md), occlusion reasoning (people behind
#: others are not looked for and not missed), a new track that survives one miss before it
#: is confirmed, and two detector settings (:class:`.detector.HogDetector`): HOG's SVM threshold
#: lowered to -0.5 inside the tracks' regions (``region_hit_threshold``), and regions read at
#: 1.15 times their smallest scale and enlarged back (``read_upsample``: 1.3x fewer pixels per
#: region), with a birth share of 0.35 so that what the cheaper regions save goes to full
#: frames (births and re-finds) rather than to more regions; and a planning horizon of one
#: frame (``horizon``, the planner's depth T): at S_max 0.1 about one region fits a frame, and
#: the look with the largest expected information gain now tracked better than the thesis's
#: three-frame lookahead (MOTA +0.01 to +0.02 on the simulated streets over 5-8 MCTS seeds,
#: 300 MCTS runs at T = 3 no better; docs/mot_planner.md, "Planning horizon").
DEPLOYED: dict[str, Any] = {
    'new_tracks': 'budget', 'area': 'scaled', 'full_frame_period': 5, 'birth_share': 0.35,
    'report_misses': 1, 'birth_score': 0.8, 'keep_lost': 10, 'scale_accel_std': 0.002,
    'init_scale_velocity_std': 0.005, 'occluded_share': 0.7, 'tentative_misses': 1,
    'region_hit_threshold': -0.5, 'read_upsample': 1.15, 'horizon': 1}
#: The thesis protocol (section 5.4): tracks only from the first frame, the centre-box area.
THESIS: dict[str, Any] = {
    'new_tracks': 'none', 'area': 'centres', 'full_frame_period': 30, 'birth_share': 0.15,
    'report_misses': None, 'birth_score': -np.inf, 'keep_lost': 0,
    'scale_accel_std': MotionModel().scale_accel_std, 'init_scale_velocity_std': 0.02,
    'occluded_share': None, 'tentative_misses': 0, 'region_hit_threshold': 0.0,
    'read_upsample': 1.0, 'horizon': PlannerConfig().depth}
PROTOCOLS = {'deployed': DEPLOYED, 'thesis': THESIS}


#: Protocol terms that are no TrackerConfig field: the planner's area and horizon, the motion
#: model's scale term and the detector's settings in regions.
NOT_TRACKER_TERMS = ('area', 'horizon', 'scale_accel_std', 'region_hit_threshold',
                     'read_upsample')


def protocol_config(protocol: str, planner: PlannerConfig | None = None, *,
                    area: str | None = None, horizon: int | None = None,
                    **overrides: object) -> TrackerConfig:
    """The tracker of ``protocol`` ('deployed' or 'thesis', :data:`PROTOCOLS`) around a planner
    configuration, whose area and depth are set to ``area`` and ``horizon`` (None: the
    protocol's); ``overrides`` replace any TrackerConfig field. The detector's terms
    (``region_hit_threshold``, ``read_upsample``) are the caller's."""
    terms = PROTOCOLS[protocol]
    kwargs: dict[str, object] = {k: v for k, v in terms.items() if k not in NOT_TRACKER_TERMS}
    kwargs['motion'] = MotionModel(scale_accel_std=float(terms['scale_accel_std']))
    kwargs.update(overrides)
    return TrackerConfig(planner=replace(planner or PlannerConfig(),
                                         area=str(terms['area'] if area is None else area),
                                         depth=int(terms['horizon'] if horizon is None
                                                   else horizon)),
                         **kwargs)  # type: ignore[arg-type]


def deployed_config(planner: PlannerConfig | None = None, **overrides: Any) -> TrackerConfig:
    """The deployed configuration (:data:`DEPLOYED`) around a planner configuration, whose
    area and depth are set to DEPLOYED's (or ``area=``, ``horizon=``); ``overrides`` replace
    any TrackerConfig field."""
    return protocol_config('deployed', planner, **overrides)


@dataclass
class Tracks:
    """The track set as arrays (K rows): ids, beliefs (x (K, 6), P (K, 6, 6)), counters."""

    ids: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))
    x: FloatArray = field(default_factory=lambda: np.zeros((0, STATE_DIM)))
    P: FloatArray = field(default_factory=lambda: np.zeros((0, STATE_DIM, STATE_DIM)))
    hits: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))
    misses: IntArray = field(default_factory=lambda: np.zeros(0, np.int64))
    confirmed: BoolArray = field(default_factory=lambda: np.zeros(0, bool))

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    def select(self, mask: BoolArray | IntArray) -> Tracks:
        return Tracks(self.ids[mask], self.x[mask], self.P[mask], self.hits[mask],
                      self.misses[mask], self.confirmed[mask])

    def concat(self, other: Tracks) -> Tracks:
        return Tracks(*(np.concatenate([a, b]) for a, b in
                        zip((self.ids, self.x, self.P, self.hits, self.misses, self.confirmed),
                            (other.ids, other.x, other.P, other.hits, other.misses,
                             other.confirmed), strict=True)))


@dataclass
class FrameResult:
    """What one frame produced.

    ids, boxes (n, 4) x, y, w, h object boxes, states (n, 6), covariances (n, 6, 6): the
    confirmed tracks; hits (n,): how many times each was detected. regions (m, 6): the
    processed regions (one full-image row for a full-frame detection). attended_ids: tracks
    whose region was processed. detections: the detector's window boxes. detector_s, plan_s,
    total_s: wall times; detector_cpu_s: the detector's CPU time (all its threads).
    processed_fraction: the share of the image the detector read (union of its crops,
    :func:`.regions.read_area`; 1 for a full frame). savings: the budget saved towards the
    next full frame, in image areas ('budget' births). covered_fraction: the share of the
    image the crops cover (= processed_fraction unless the area counts 'scaled' pixels).
    """

    frame: int
    ids: IntArray
    boxes: FloatArray
    states: FloatArray
    covariances: FloatArray
    hits: IntArray
    regions: FloatArray
    attended_ids: IntArray
    detections: Detections
    full_frame: bool
    detector_s: float = 0.0
    plan_s: float = 0.0
    total_s: float = 0.0
    plan_iterations: int = 0
    processed_fraction: float = 0.0
    created: int = 0
    deleted: int = 0
    detector_cpu_s: float = 0.0
    savings: float = 0.0
    covered_fraction: float = 0.0


class MotTracker:
    """Tracker of Fig. 5.1 around a :class:`Detector`."""

    def __init__(self, detector: Detector, cfg: TrackerConfig | None = None) -> None:
        if not isinstance(detector, Detector):
            raise TypeError('detector must have geometry, box_shrink and detect(image, regions)')
        self.cfg = cfg or TrackerConfig()
        self.detector = detector
        self.observation = ObservationModel(detector.geometry, self.cfg.extra_detector_std,
                                            self.cfg.quantization)
        self.planner = MctsPlanner(self.cfg.planner, self.cfg.motion, self.observation)
        self.gate = gate_threshold(self.cfg.gate_probability)
        self.reset()

    def reset(self) -> None:
        """Forget every track and the frame size; the next frame bootstraps."""
        self.tracks = Tracks()
        self.frame_index = 0
        self.image_size: tuple[int, int] | None = None
        self._next_id = 1
        self.savings = 0.0            # pixels saved towards the next full frame ('budget')
        self._last_full = 0           # frame index of the last full-frame detection
        self.lost = Tracks()          # recently deleted tracks, still predicted (keep_lost)
        self._lost_age = np.zeros(0, np.int64)
        self.planner.reset()

    # --- helpers --------------------------------------------------------------------------

    def window_boxes(self, x: FloatArray) -> FloatArray:
        """Detector-window boxes (K, 4) x, y, w, h of states or measurements x (K, >= 3)."""
        g = self.detector.geometry
        w, h = x[:, 2] * g.window_w, x[:, 2] * g.window_h
        return np.stack([x[:, 0] - w / 2, x[:, 1] - h / 2, w, h], axis=1)

    def object_boxes(self, x: FloatArray) -> FloatArray:
        """Object boxes (K, 4) of states x: window boxes through the detector's box shrink."""
        return self.detector.box_shrink.apply(self.window_boxes(x))

    def _measurements(self, det: Detections) -> tuple[FloatArray, FloatArray, FloatArray]:
        """z (M, 3) = [centre u, centre v, scale] of valid detections, R (M, 3, 3), scores."""
        boxes = np.asarray(det.boxes, dtype=float).reshape(-1, 4)
        scores = np.asarray(det.scores, dtype=float).reshape(-1)
        if scores.shape[0] != boxes.shape[0]:
            raise ValueError(f'detector returned {boxes.shape[0]} boxes but '
                             f'{scores.shape[0]} scores')
        ok = np.isfinite(boxes).all(axis=1) & (boxes[:, 2] > 0) & (boxes[:, 3] > 0)
        boxes, scores = boxes[ok], scores[ok]
        z = np.stack([boxes[:, 0] + boxes[:, 2] / 2, boxes[:, 1] + boxes[:, 3] / 2,
                      boxes[:, 3] / self.detector.geometry.window_h], axis=1)
        return z, self.observation.covariance(z[:, 2]), scores

    def _new_tracks(self, z: FloatArray, confirmed: bool) -> Tracks:
        n = z.shape[0]
        s = z[:, 2]
        P = np.zeros((n, STATE_DIM, STATE_DIM))
        P[:, :3, :3] = self.observation.covariance(s)
        i = np.arange(3, 6)
        vel = np.stack([self.cfg.init_velocity_std * s, self.cfg.init_velocity_std * s,
                        self.cfg.init_scale_velocity_std * s], axis=1)
        P[:, i, i] = vel ** 2
        x = np.concatenate([z, np.zeros((n, 3))], axis=1)
        ids = np.arange(self._next_id, self._next_id + n, dtype=np.int64)
        return Tracks(ids, x, P, np.ones(n, np.int64), np.zeros(n, np.int64),
                      np.full(n, confirmed))

    def _check(self, image: object) -> tuple[NDArray[np.uint8], tuple[int, int]]:
        try:
            image = check_image(image)
        except ValueError as exc:
            raise FrameError(f'frame {self.frame_index}: {exc}') from None
        size = (int(image.shape[1]), int(image.shape[0]))
        if self.image_size is not None and size != self.image_size:
            raise FrameError(
                f'frame {self.frame_index}: frame size changed from {self.image_size[0]}x'
                f'{self.image_size[1]} to {size[0]}x{size[1]}; call reset() to start over at '
                'the new size')
        return image, size

    def _sweep_region(self, size: tuple[int, int]) -> FloatArray:
        width, height = size
        n = int(np.ceil(1.0 / self.cfg.sweep_fraction))
        i = self.frame_index % n
        overlap = self.detector.geometry.window_w
        x0 = max(i * width / n - overlap, 0.0)
        x1 = min((i + 1) * width / n + overlap, float(width))
        return np.array([[x0, 0.0, x1, float(height), self.detector.geometry.min_scale, np.inf]])

    # --- the frame loop -------------------------------------------------------------------

    def _warped(self, homography: FloatArray | None) -> Tracks:
        """The tracks moved into the current camera (ego-motion), or as they are."""
        tracks = self.tracks
        if homography is None or not len(tracks):
            return tracks
        h = np.asarray(homography, dtype=float)
        if h.shape != (3, 3) or not np.isfinite(h).all() or abs(h[2, 2]) < 1e-12:
            raise ValueError(f'homography must be a finite 3x3 matrix with H[2, 2] != 0, '
                             f'got {h!r}')
        x, P = warp_beliefs(tracks.x, tracks.P, h / h[2, 2])
        return replace(tracks, x=x, P=P)

    def coast(self, homography: FloatArray | None = None) -> FrameResult:
        """Advance one frame without an image (e.g. a corrupt frame): predict only (after
        moving the beliefs by the camera's rotation, as in :meth:`step`)."""
        t0 = time.perf_counter()
        tracks = self._warped(homography)
        if len(tracks):
            x, P = predict(tracks.x, tracks.P, self.cfg.motion)
            tracks = replace(tracks, x=x, P=P)
        lost, lost_age = self._aged_lost(homography)
        tracks, deleted, newly_lost = self._prune(tracks)
        self.tracks = tracks
        self.lost, self._lost_age = self._remember(lost, lost_age, newly_lost)
        return self._result(Detections.empty(), np.zeros((0, 6)), np.zeros(0, np.int64), False,
                            0.0, 0.0, t0, 0, 0, deleted, 0.0)

    def step(self, image: NDArray[np.uint8],
             homography: FloatArray | None = None) -> FrameResult:
        """Process one frame; returns the confirmed tracks and what was attended.

        homography: the pixel motion (3, 3) of the camera's rotation since the previous frame
        (:func:`.egomotion.rotation_homography`); beliefs are moved by it before prediction.
        """
        t0 = time.perf_counter()
        image, size = self._check(image)
        cfg = self.cfg
        width, height = size
        bootstrap = self.image_size is None
        image_area = float(width * height)
        credit = cfg.planner.s_max * image_area          # this frame's share ('budget')
        budgeted = cfg.new_tracks == 'budget' and cfg.mode == 'planner'
        due = self.frame_index - self._last_full >= cfg.full_frame_period
        full = (bootstrap or cfg.mode == 'full'
                or (cfg.new_tracks == 'periodic' and self.frame_index % cfg.full_frame_period == 0)
                or (budgeted and due and self.savings + credit >= image_area))
        tracks = self._warped(homography)
        if len(tracks):
            x, P = predict(tracks.x, tracks.P, cfg.motion)
            tracks = replace(tracks, x=x, P=P)
        plan_s, iterations = 0.0, 0
        occluded = self.occluded(tracks.x)
        if full:
            regions = full_frame_region(size, self.detector.geometry)
            attended = np.ones(len(tracks), bool)
            det_regions = None
        else:
            track_budget = (1.0 - cfg.birth_share) * credit
            visible = np.flatnonzero(~occluded)            # the planner's targets
            plan = self.planner.plan(tracks.x[visible], tracks.P[visible], size,
                                     track_budget if budgeted and cfg.planner.area in READ_MODES
                                     else None)
            plan_s, iterations = plan.plan_s, plan.iterations
            chosen = plan.action.copy()
            if budgeted:                                   # S_max binds the pixels read
                chosen = self._within(plan, chosen, track_budget, size)
            regions = plan.regions[chosen]
            attended = np.zeros(len(tracks), bool)
            attended[visible[chosen]] = True
            if cfg.new_tracks == 'sweep':
                regions = np.concatenate([regions, self._sweep_region(size)])
            det_regions = regions
        t_det, c_det = time.perf_counter(), time.process_time()
        det = (self.detector.detect(image, det_regions) if det_regions is None or len(det_regions)
               else Detections.empty())
        detector_s = time.perf_counter() - t_det
        detector_cpu_s = time.process_time() - c_det
        z, R, scores = self._measurements(det)
        lost, lost_age = self._aged_lost(homography)

        assoc = associate(tracks.x, tracks.P, z, R, self.gate)
        m_t, m_d = assoc.matches[:, 0], assoc.matches[:, 1]
        x, P = tracks.x.copy(), tracks.P.copy()
        if m_t.size:
            x[m_t], P[m_t] = update(x[m_t], P[m_t], z[m_d], R[m_d])
        hits, misses = tracks.hits.copy(), tracks.misses.copy()
        matched = np.zeros(len(tracks), bool)
        matched[m_t] = True
        hits[matched] += 1
        misses[matched] = 0
        missed = attended & ~matched
        misses[missed & ~occluded] += 1                   # not seen behind someone: no miss
        confirmed = tracks.confirmed | (hits >= cfg.confirm_hits)
        tracks = Tracks(tracks.ids, x, P, hits, misses, confirmed)
        # Tentative tracks die after tentative_misses + 1 consecutive misses.
        n_before = len(tracks)
        dropped = missed & ~tracks.confirmed & (tracks.misses > cfg.tentative_misses)
        tracks = tracks.select(~dropped | bootstrap)
        deleted = n_before - len(tracks)

        # Detections no live track took may bring back a recently lost one (keep_lost).
        unmatched = assoc.unmatched_detections
        sure = unmatched[scores[unmatched] >= cfg.birth_score]     # as sure as a birth
        if len(lost) and sure.size:
            back = associate(lost.x, lost.P, z[sure], R[sure], self.gate).matches
            if back.size:
                li, di = back[:, 0], sure[back[:, 1]]
                xb, Pb = update(lost.x[li], lost.P[li], z[di], R[di])
                tracks = tracks.concat(Tracks(lost.ids[li], xb, Pb, lost.hits[li] + 1,
                                              np.zeros(li.size, np.int64),
                                              np.ones(li.size, bool)))
                stay = np.ones(len(lost), bool)
                stay[li] = False
                lost, lost_age = lost.select(stay), lost_age[stay]
                unmatched = np.setdiff1d(unmatched, di)
        created = 0
        if bootstrap or cfg.new_tracks != 'none':
            z_new = z[unmatched]
            z_new = z_new[scores[unmatched] >= cfg.birth_score]
            if len(tracks) and z_new.shape[0]:
                iou = box_iou(self.window_boxes(z_new), self.window_boxes(tracks.x))
                z_new = z_new[~(iou > cfg.new_track_iou).any(axis=1)]
            if z_new.shape[0]:
                born = self._new_tracks(z_new, confirmed=bootstrap)
                self._next_id += z_new.shape[0]
                tracks = tracks.concat(born)
                created = z_new.shape[0]
        self.image_size = size
        tracks, pruned, newly_lost = self._prune(tracks)
        attended_ids = self.tracks.ids[attended] if len(self.tracks) else np.zeros(0, np.int64)
        self.tracks = tracks
        self.lost, self._lost_age = self._remember(lost, lost_age, newly_lost)
        read = image_area if full else read_area(regions, size, self._read_mode, self._upsample)
        if budgeted and not bootstrap:
            self.savings = min(self.savings + credit - read, image_area)
        if full:
            self._last_full = self.frame_index
        result = self._result(det, regions, attended_ids, full, detector_s, plan_s, t0,
                              iterations, created, deleted + pruned, read / image_area)
        result.detector_cpu_s = detector_cpu_s
        result.savings = self.savings / image_area
        result.covered_fraction = 1.0 if full else read_area(regions, size) / image_area
        return result

    @property
    def _upsample(self) -> float:
        return float(self.detector.geometry.upsample)

    @property
    def _read_mode(self) -> str:
        """How the pixels read are counted: as the constraint counts them ('pixels' or
        'scaled'); 'pixels' for the thesis's 'centres'."""
        area = self.cfg.planner.area
        return area if area in READ_MODES else 'pixels'

    def _within(self, plan: Plan, attended: BoolArray, budget: float,
                size: tuple[int, int]) -> BoolArray:
        """The attended regions, dropping regions until the union of what the detector reads
        fits the budget (a no-op when the planner counted pixels: its areas add up to at least
        their union); the largest goes first."""
        keep = np.flatnonzero(attended)
        keep = keep[np.argsort(plan.areas[keep], kind='stable')]
        while keep.size and read_area(plan.regions[keep], size, self._read_mode,
                                      self._upsample) > budget:
            keep = keep[:-1]
        out = np.zeros_like(attended)
        out[keep] = True
        return out

    def occluded(self, x: FloatArray) -> BoolArray:
        """(K,) whether each of the states x (K, >= 3) is occluded: its object box covered by
        at least ``occluded_share`` by the box of one track with a larger scale (nearer);
        all False without ``occluded_share``."""
        share = self.cfg.occluded_share
        K = x.shape[0]
        if share is None or K < 2:
            return np.zeros(K, bool)
        b = self.object_boxes(x)
        cover = box_intersection(b, b) / np.maximum(b[:, 2] * b[:, 3], 1e-12)[:, None]
        nearer = x[None, :, 2] > x[:, None, 2]                              # j nearer than k
        return np.asarray((np.where(nearer, cover, 0.0) >= share).any(axis=1), dtype=bool)

    def _aged_lost(self, homography: FloatArray | None) -> tuple[Tracks, IntArray]:
        """The lost tracks one frame on (moved by the camera's rotation, predicted, aged)."""
        lost = self.lost
        if not len(lost):
            return lost, self._lost_age
        if homography is not None:
            h = np.asarray(homography, dtype=float)
            x, P = warp_beliefs(lost.x, lost.P, h / h[2, 2])
            lost = replace(lost, x=x, P=P)
        x, P = predict(lost.x, lost.P, self.cfg.motion)
        return replace(lost, x=x, P=P), self._lost_age + 1

    def _remember(self, lost: Tracks, age: IntArray, newly: Tracks) -> tuple[Tracks, IntArray]:
        """The lost tracks to keep: the newly lost added, those older than keep_lost gone."""
        if self.cfg.keep_lost <= 0:
            return Tracks(), np.zeros(0, np.int64)
        lost = lost.concat(newly)
        age = np.concatenate([age, np.zeros(len(newly), np.int64)])
        keep = age <= self.cfg.keep_lost
        return lost.select(keep), age[keep]

    def _prune(self, tracks: Tracks) -> tuple[Tracks, int, Tracks]:
        """Delete tracks after too many misses, out of the image, or lost (module docstring);
        returns the tracks kept, how many were deleted and the confirmed ones deleted inside
        the image (the lost tracks :meth:`_remember` may keep)."""
        if not len(tracks) or self.image_size is None:
            return tracks, 0, Tracks()
        width, height = self.image_size
        g = self.detector.geometry
        x, P = tracks.x, tracks.P
        inside = (x[:, 0] >= 0) & (x[:, 0] < width) & (x[:, 1] >= 0) & (x[:, 1] < height)
        s = np.maximum(x[:, 2], 1e-6)
        sharp = ((np.sqrt(P[:, 0, 0]) <= self.cfg.max_std_frac * s * g.window_w)
                 & (np.sqrt(P[:, 1, 1]) <= self.cfg.max_std_frac * s * g.window_h))
        keep = inside & sharp & (tracks.misses <= self.cfg.max_misses) & (x[:, 2] > 0)
        lost = ~keep & inside & (x[:, 2] > 0) & tracks.confirmed
        return tracks.select(keep), int((~keep).sum()), tracks.select(lost)

    def _result(self, det: Detections, regions: FloatArray, attended_ids: IntArray, full: bool,
                detector_s: float, plan_s: float, t0: float, iterations: int, created: int,
                deleted: int, processed: float) -> FrameResult:
        shown = self.tracks.confirmed
        if self.cfg.report_misses is not None:
            shown = shown & (self.tracks.misses <= self.cfg.report_misses)
        t = self.tracks.select(shown)
        result = FrameResult(
            frame=self.frame_index, ids=t.ids.copy(), boxes=self.object_boxes(t.x),
            states=t.x.copy(), covariances=t.P.copy(), hits=t.hits.copy(), regions=regions,
            attended_ids=attended_ids, detections=det, full_frame=full, detector_s=detector_s,
            plan_s=plan_s, total_s=time.perf_counter() - t0, plan_iterations=iterations,
            processed_fraction=processed, created=created, deleted=deleted)
        self.frame_index += 1
        return result

"""The tracker: identities on synthetic motion, bootstrap, births and deaths, bad input."""

import numpy as np
import pytest

from mot_planner_node.core.detector import (
    HOG_SHRINK,
    BoxShrink,
    Detections,
    HogDetector,
    box_iou,
    nms,
)
from mot_planner_node.core.metrics import MotEvaluator, summarize
from mot_planner_node.core.observation import DetectorGeometry
from mot_planner_node.core.planner import PlannerConfig
from mot_planner_node.core.simulated import (
    SimulatedDetector,
    SyntheticScene,
    track_synthetic,
    visibility,
)
from mot_planner_node.core.tracker import FrameError, MotTracker, TrackerConfig

SIZE = (640, 480)
BLANK = np.zeros((480, 640, 3), np.uint8)


def lanes(n_frames: int = 80) -> list[np.ndarray]:
    """Four people walking in separate lanes (no occlusion), object boxes per frame."""
    heights = np.array([100.0, 115.0, 130.0, 145.0])
    x0 = np.array([40.0, 560.0, 120.0, 480.0])
    vx = np.array([2.0, -1.5, 1.0, -2.5])
    feet = np.array([150.0, 260.0, 360.0, 460.0]) - 20
    out = []
    for t in range(n_frames):
        cx = x0 + vx * t
        w = 0.41 * heights
        out.append(np.stack([cx - w / 2, feet - heights, w, heights], axis=1))
    return out


def planner_cfg(**kw) -> TrackerConfig:
    p = dict(k_max=2, s_max=0.1, budget_ms=None, max_iterations=80, seed=0)
    return TrackerConfig(mode='planner', new_tracks='none',
                         planner=PlannerConfig(**{**p, **kw}))


@pytest.mark.parametrize('mode', ['planner', 'full'])
def test_identities_kept_on_moving_boxes(mode: str) -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, seed=1)
    cfg = planner_cfg() if mode == 'planner' else TrackerConfig(mode='full', new_tracks='none')
    tracker = MotTracker(det, cfg)
    ev = MotEvaluator()
    ids = np.arange(1, 5)
    for t, boxes in enumerate(lanes()):
        det.p_detect = 1.0 if t == 0 else 0.9     # everyone found at the bootstrap, then misses
        det.set_truth(boxes)
        r = tracker.step(BLANK)
        if mode == 'planner' and t > 0:
            assert len(r.regions) <= 2
            assert not r.full_frame
        ev.update(t + 1, ids, boxes, r.ids, r.boxes)
    m = summarize({'s': ev})['s']
    assert m['num_switches'] == 0
    assert m['num_false_positives'] == 0
    assert m['idf1'] > 0.95 and m['mota'] > 0.95
    assert m['motp'] > 70.0


def test_bootstrap_makes_one_track_per_detection_and_regions_follow() -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, jitter=0.0)
    tracker = MotTracker(det, planner_cfg(k_max=4, s_max=1.0))
    frames = lanes(3)
    det.set_truth(frames[0])
    r0 = tracker.step(BLANK)
    assert r0.full_frame and r0.frame == 0 and r0.created == 4
    assert r0.ids.tolist() == [1, 2, 3, 4]
    assert (box_iou(r0.boxes, frames[0]).max(axis=1) > 0.6).all()
    det.set_truth(frames[1])
    r1 = tracker.step(BLANK)
    assert not r1.full_frame and r1.plan_s > 0
    assert sorted(r1.attended_ids.tolist()) == [1, 2, 3, 4]
    # Each attended region holds its person's window.
    win = HOG_SHRINK.invert(frames[1])
    cx, cy = win[:, 0] + win[:, 2] / 2, win[:, 1] + win[:, 3] / 2
    inside = ((r1.regions[:, None, 0] <= cx) & (cx <= r1.regions[:, None, 2])
              & (r1.regions[:, None, 1] <= cy) & (cy <= r1.regions[:, None, 3]))
    assert inside.any(axis=0).all()


def test_tracks_die_after_misses_and_births_come_from_full_frames() -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, jitter=0.0)
    cfg = TrackerConfig(mode='full', new_tracks='none', max_misses=3)
    tracker = MotTracker(det, cfg)
    frames = lanes(10)
    det.set_truth(frames[0])
    tracker.step(BLANK)
    det.set_truth(frames[1][:2])                 # two people vanish
    deleted = [tracker.step(BLANK).deleted for _ in range(5)]
    assert sum(deleted) == 2 and len(tracker.tracks) == 2
    # Periodic full frames start (tentative, then confirmed) tracks for newcomers.
    det2 = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, jitter=0.0)
    t2 = MotTracker(det2, TrackerConfig(mode='planner', new_tracks='periodic',
                                        full_frame_period=2, confirm_hits=2,
                                        planner=PlannerConfig(budget_ms=None, max_iterations=20,
                                                              seed=0)))
    det2.set_truth(frames[0][:1])
    assert t2.step(BLANK).ids.tolist() == [1]
    det2.set_truth(frames[1][:1])
    t2.step(BLANK)
    det2.set_truth(frames[2][:2])                # frame 2: full frame, newcomer
    r = t2.step(BLANK)
    assert r.full_frame and r.created == 1 and r.ids.tolist() == [1]   # tentative: not shown
    det2.set_truth(frames[3][:2])
    r = t2.step(BLANK)
    assert r.ids.tolist() == [1, 2]


@pytest.mark.parametrize('allowed', [0, 1, 2])
def test_a_new_track_survives_tentative_misses_then_is_dropped(allowed: int) -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, jitter=0.0)
    frames = lanes(12)

    def newcomer_missed(misses: int) -> MotTracker:
        t = MotTracker(det, TrackerConfig(mode='full', new_tracks='periodic', confirm_hits=2,
                                          tentative_misses=allowed))
        det.set_truth(frames[0][:1])
        t.step(BLANK)                                    # bootstrap: one person
        det.set_truth(frames[1][:2])
        assert t.step(BLANK).created == 1                # a newcomer: tentative
        for k in range(misses):                          # HOG misses the newcomer
            det.set_truth(frames[2 + k][:1])
            t.step(BLANK)
        return t

    # Up to `allowed` misses it lives on, and the next detection confirms it (shown).
    t = newcomer_missed(allowed)
    assert len(t.tracks) == 2
    det.set_truth(frames[2 + allowed][:2])
    assert len(t.step(BLANK).ids) == 2
    # One more miss drops it.
    assert len(newcomer_missed(allowed + 1).tracks) == 1


def test_sweep_adds_a_strip() -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0)
    t = MotTracker(det, TrackerConfig(new_tracks='sweep', sweep_fraction=0.25,
                                      planner=PlannerConfig(budget_ms=None, max_iterations=10)))
    det.set_truth(lanes(1)[0])
    t.step(BLANK)
    r = t.step(BLANK)
    strip = r.regions[-1]
    assert strip[1] == 0 and strip[3] == 480 and strip[2] - strip[0] <= 640 / 4 + 2 * 64


def test_bad_frames_leave_the_tracker_as_it_was() -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0)
    tracker = MotTracker(det, planner_cfg())
    det.set_truth(lanes(1)[0])
    tracker.step(BLANK)
    before = (tracker.tracks.x.copy(), tracker.tracks.P.copy(), tracker.frame_index)
    bad = [np.zeros((0, 640, 3), np.uint8), np.zeros((480, 640, 3), np.float32),
           np.zeros((480, 640, 4), np.uint8), 'not an image', None,
           np.zeros((240, 320, 3), np.uint8)]
    messages = []
    for image in bad:
        with pytest.raises(FrameError) as exc:
            tracker.step(image)
        messages.append(str(exc.value))
    assert 'empty' in messages[0] and 'uint8' in messages[1] and 'HxW' in messages[2]
    assert 'numpy array' in messages[3]
    assert 'frame size changed from 640x480 to 320x240' in messages[5]
    np.testing.assert_array_equal(tracker.tracks.x, before[0])
    np.testing.assert_array_equal(tracker.tracks.P, before[1])
    assert tracker.frame_index == before[2]
    # Still works on good frames; reset() accepts a new size.
    assert len(tracker.step(BLANK).ids) == 4
    tracker.reset()
    det.set_truth(np.zeros((0, 4)))
    r = tracker.step(np.zeros((240, 320), np.uint8))
    assert r.frame == 0 and len(r.ids) == 0


class Broken:
    """A detector that fails, then returns garbage."""

    geometry = DetectorGeometry()
    box_shrink = BoxShrink()

    def __init__(self) -> None:
        self.mode = 'ok'

    def detect(self, image, regions=None) -> Detections:
        if self.mode == 'raise':
            raise RuntimeError('detector crashed')
        if self.mode == 'nan':
            return Detections(np.array([[np.nan, 0, 10, 10], [0, 0, -5, 10]]), np.ones(2))
        return Detections(np.array([[100.0, 100.0, 64.0, 128.0]]), np.ones(1))


def test_detector_failures_keep_the_state_consistent() -> None:
    det = Broken()
    tracker = MotTracker(det, TrackerConfig(mode='full', new_tracks='none', max_misses=10))
    tracker.step(BLANK)
    x = tracker.tracks.x.copy()
    det.mode = 'raise'
    with pytest.raises(RuntimeError):
        tracker.step(BLANK)
    np.testing.assert_array_equal(tracker.tracks.x, x)
    assert tracker.frame_index == 1
    det.mode = 'nan'                     # invalid boxes are dropped: a plain miss
    r = tracker.step(BLANK)
    assert r.ids.tolist() == [1] and tracker.tracks.misses.tolist() == [1]
    c = tracker.coast()                  # e.g. a frame that could not be decoded
    assert c.frame == 2 and c.ids.tolist() == [1] and not c.full_frame
    assert tracker.tracks.P[0, 0, 0] > 0


def test_no_detections_at_all() -> None:
    det = SimulatedDetector(p_detect=0.0, false_positives_per_frame=0.0)
    tracker = MotTracker(det, planner_cfg())
    for boxes in lanes(5):
        det.set_truth(boxes)
        r = tracker.step(BLANK)
        assert len(r.ids) == 0 and len(r.detections.boxes) == 0


def test_tracker_refuses_non_detectors_and_bad_config() -> None:
    with pytest.raises(TypeError, match='detect'):
        MotTracker(object())
    with pytest.raises(ValueError, match='mode'):
        TrackerConfig(mode='sometimes')
    with pytest.raises(ValueError, match='new_tracks'):
        TrackerConfig(new_tracks='always')


def test_synthetic_scene_and_run() -> None:
    scene = SyntheticScene(n_people=5, seed=2)
    frames = scene.frames(30)
    for f in frames:
        assert f.boxes.shape == (5, 4)
        win = HOG_SHRINK.invert(f.boxes)
        assert (win[:, 1] + win[:, 3] <= 480 + 1e-6).all()      # windows fit the image
        assert (f.boxes[:, 3] >= 99.9).all()
    vis = visibility(np.array([[0, 0, 10, 10], [0, 0, 10, 20.0]]))
    np.testing.assert_allclose(vis, [0.0, 1.0])
    run = track_synthetic(TrackerConfig(planner=PlannerConfig(budget_ms=None, max_iterations=20,
                                                              seed=0)), n_frames=20, seed=2)
    assert len(run.regions) == 20 and run.metrics['num_frames'] == 20


def test_box_shrink_and_nms() -> None:
    boxes = np.array([[10.0, 20.0, 64.0, 128.0]])
    obj = HOG_SHRINK.apply(boxes)
    assert obj[0, 3] == pytest.approx(128 * HOG_SHRINK.height)
    assert obj[0, 0] + obj[0, 2] / 2 == pytest.approx(42.0)
    np.testing.assert_allclose(HOG_SHRINK.invert(obj), boxes)
    b = np.array([[0, 0, 10, 10], [1, 1, 10, 10], [50, 50, 10, 10.0]])
    assert nms(b, np.array([0.5, 0.9, 0.1])).tolist() == [1, 2]


def test_hog_regions_map_back_to_the_image(monkeypatch) -> None:
    hog = HogDetector(hit_threshold=0.2, region_hit_threshold=-0.5)
    seen = []
    thresholds = []

    def fake_run(crop, padding=None, hit_threshold=None, scale=None):
        seen.append(crop.shape)
        thresholds.append(hit_threshold)
        return Detections(np.array([[10.0, 20.0, 64.0, 128.0]]), np.array([1.5]))

    monkeypatch.setattr(hog, '_run', fake_run)
    image = np.zeros((480, 640, 3), np.uint8)
    d = hog.detect(image, np.array([[100.0, 50.0, 300.0, 450.0, 2.0, 3.0]]))
    # The 200x400 crop is scanned at half size (s_lo = 2); boxes come back scaled and shifted.
    assert seen == [(200, 100, 3)]
    np.testing.assert_allclose(d.boxes, [[120.0, 90.0, 128.0, 256.0]])
    # Regions use their own SVM threshold; a full frame uses the detector's (None: its own).
    hog.detect(image)
    assert thresholds == [-0.5, None]
    assert HogDetector(hit_threshold=0.3).region_hit_threshold == 0.3      # default: the same
    # An upsampling detector reads the crop coarser, then scans it at the region's scale.
    up = HogDetector(upsample=1.5)
    crops = []
    monkeypatch.setattr(up, '_run', lambda crop, padding=None, hit_threshold=None, scale=None: (
        crops.append(crop.shape), Detections.empty())[1])
    up.detect(image, np.array([[100.0, 50.0, 300.0, 450.0, 2.0, 3.0],
                               [100.0, 50.0, 300.0, 450.0, 1.0, 3.0]]))
    assert crops == [(200, 100, 3), (400, 200, 3)]
    assert up.geometry.upsample == 1.5
    # Regions outside the image are skipped.
    seen.clear()
    d = hog.detect(image, np.array([[700.0, 0.0, 800.0, 100.0, 1.0, 1.0]]))
    assert seen == [] and d.boxes.shape == (0, 4)


def test_full_frames_are_scanned_at_their_own_scale_step() -> None:
    # issue 27: the births' full-frame scans are most of the detector's time; a coarser step
    # there (14 pyramid levels of a 640x480 frame at 1.1 instead of 27 at 1.05) halves it,
    # while the regions keep the step the observation model is built from
    steps = []

    class Recording:
        def __init__(self, hog):
            self.hog, self.winSize = hog, hog.winSize

        def detectMultiScale(self, image, **kw):
            steps.append(kw['scale'])
            return self.hog.detectMultiScale(image, **kw)

    image = np.full((480, 640, 3), 128, np.uint8)
    regions = np.array([[100.0, 50.0, 300.0, 450.0, 1.0, 3.0]])
    for full_frame_scale, expected in ((None, [1.05, 1.05]), (1.1, [1.1, 1.05])):
        hog = HogDetector(full_frame_scale=full_frame_scale)
        hog.hog = Recording(hog.hog)
        steps.clear()
        hog.detect(image)
        hog.detect(image, regions)
        assert steps == expected
        assert hog.geometry.scale_step == 1.05
    with pytest.raises(ValueError, match='full_frame_scale'):
        HogDetector(full_frame_scale=1.0)


def test_hog_runs_on_plain_images() -> None:
    hog = HogDetector()
    d = hog.detect(np.full((200, 160, 3), 128, np.uint8))
    assert d.boxes.shape[1] == 4 and d.scores.shape[0] == d.boxes.shape[0]
    tiny = hog.detect(np.zeros((50, 40), np.uint8))
    assert tiny.boxes.shape == (0, 4)
    with pytest.raises(ValueError, match='empty'):
        hog.detect(np.zeros((0, 10, 3), np.uint8))


def crossing(n_frames: int = 70) -> list[np.ndarray]:
    """A near person standing still and a far one walking behind them, left to right."""
    near = np.array([320.0 - 0.41 * 200 / 2, 420.0 - 200, 0.41 * 200, 200.0])
    out = []
    for t in range(n_frames):
        cx = 180.0 + 4.0 * t
        out.append(np.array([near, [cx - 0.41 * 120 / 2, 330.0 - 120, 0.41 * 120, 120.0]]))
    return out


@pytest.mark.parametrize('share', [None, 0.3])
def test_a_person_behind_another_is_not_looked_for_and_keeps_its_id(share) -> None:
    det = SimulatedDetector(p_detect=1.0, false_positives_per_frame=0.0, jitter=0.0)
    cfg = TrackerConfig(mode='planner', new_tracks='none', max_misses=2, occluded_share=share,
                        planner=PlannerConfig(k_max=2, s_max=1.0, budget_ms=None,
                                              max_iterations=40, seed=0))
    tracker = MotTracker(det, cfg)
    frames = crossing()
    hidden = [t for t, b in enumerate(frames) if visibility(b)[1] < det.min_visible]
    assert 8 <= len(hidden) <= 30                          # the far one is hidden for a while
    behind_attended, ids_after = [], []
    for t, boxes in enumerate(frames):
        det.set_truth(boxes)
        r = tracker.step(BLANK)
        if t in hidden[2:]:
            behind_attended.append(2 in r.attended_ids.tolist())
        if t > hidden[-1] + 5:
            ids_after.append(sorted(r.ids.tolist()))
    if share is None:       # the thesis's model: looked for where it cannot be seen, deleted
        assert any(behind_attended[:3]) and ids_after[-1] == [1]
    else:                   # not looked for, not missed, found again as itself
        assert not any(behind_attended)
        assert all(ids == [1, 2] for ids in ids_after)
        assert tracker.occluded(tracker.tracks.x).tolist() == [False, False]


def test_occlusion_is_judged_by_the_nearer_box() -> None:
    tracker = MotTracker(SimulatedDetector(), TrackerConfig(occluded_share=0.5))
    win = HOG_SHRINK.invert(np.array([[300, 150, 82, 200],      # near (scale 200/97)
                                      [310, 200, 49, 120],      # far, inside the near box
                                      [500, 200, 49, 120]]))    # far, in the open
    g = tracker.detector.geometry
    x = np.zeros((3, 6))
    x[:, 0], x[:, 1] = win[:, 0] + win[:, 2] / 2, win[:, 1] + win[:, 3] / 2
    x[:, 2] = win[:, 3] / g.window_h
    assert tracker.occluded(x).tolist() == [False, True, False]
    assert not MotTracker(SimulatedDetector(), TrackerConfig()).occluded(x).any()
    with pytest.raises(ValueError, match='occluded_share'):
        TrackerConfig(occluded_share=0.0)
    with pytest.raises(ValueError, match='tentative_misses'):
        TrackerConfig(tentative_misses=-1)


def test_protocols_set_the_planning_horizon() -> None:
    """The deployed tracker plans one frame ahead, the thesis protocol T = 3 frames; an
    explicit horizon (the node's parameter) wins over the protocol's, whatever the planner
    configuration it is given says."""
    from mot_planner_node.core.tracker import DEPLOYED, THESIS, deployed_config, protocol_config
    given = PlannerConfig(depth=5, budget_ms=None, max_iterations=10)
    assert deployed_config(given).planner.depth == DEPLOYED['horizon'] == 1
    assert protocol_config('thesis', given).planner.depth == THESIS['horizon'] == 3
    cfg = deployed_config(given, horizon=2, occluded_share=0.5)
    assert (cfg.planner.depth, cfg.occluded_share, cfg.planner.max_iterations) == (2, 0.5, 10)
    with pytest.raises(ValueError, match='depth'):
        deployed_config(given, horizon=0)

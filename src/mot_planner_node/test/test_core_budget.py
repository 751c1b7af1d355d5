"""S_max as a hard bound on the pixels the detector reads, births paid from it, and plans that
repeat for a fixed seed and iteration budget."""

import numpy as np
import pytest

from mot_planner_node.core.kalman import MotionModel
from mot_planner_node.core.observation import DetectorGeometry, ObservationModel
from mot_planner_node.core.planner import MctsPlanner, PlannerConfig
from mot_planner_node.core.regions import pixel_rects, read_area, read_areas, read_scale
from mot_planner_node.core.simulated import SimulatedDetector, SyntheticScene
from mot_planner_node.core.tracker import MotTracker, TrackerConfig

SIZE = (640, 480)
G = DetectorGeometry()


def region(x0, y0, x1, y1, s_lo=1.0):
    return [x0, y0, x1, y1, s_lo, s_lo * 1.2]


def test_read_area_counts_overlaps_once_on_the_crops_read() -> None:
    # Two 100 x 100 squares overlapping in a 50 x 50 corner: 2 * 10000 - 2500.
    r = np.array([region(0, 0, 100, 100), region(50, 50, 150, 150)])
    assert read_area(r, SIZE) == 17500
    # The same square twice counts once; a third one apart adds its own area.
    assert read_area(np.array([region(0, 0, 100, 100)] * 2), SIZE) == 10000
    assert read_area(np.array([region(0, 0, 100, 100), region(200, 0, 210, 10)]), SIZE) == 10100
    # Fractional bounds are rounded outwards (the detector crops whole pixels), then clipped.
    r = np.array([region(10.2, 20.7, 30.1, 40.0), region(-50, 470.5, 20, 500)])
    np.testing.assert_array_equal(pixel_rects(r, SIZE), [[10, 20, 31, 40], [0, 470, 20, 480]])
    assert read_area(r, SIZE) == 21 * 20 + 20 * 10
    assert read_area(np.zeros((0, 6)), SIZE) == 0.0
    # 'scaled': a crop shrunk by s_lo = 2 costs a quarter; where it overlaps a crop read at
    # full resolution, the finer read counts.
    r = np.array([region(0, 0, 100, 100, 2.0), region(50, 0, 150, 100, 1.0)])
    np.testing.assert_allclose(read_areas(r, 'scaled', SIZE), [2500, 10000])
    assert read_area(r, SIZE, 'scaled') == pytest.approx(50 * 100 / 4 + 100 * 100)
    with pytest.raises(ValueError, match='read mode'):
        read_area(r, SIZE, 'centres')


def belief(u, v, s, std):
    x = np.array([[u, v, s, 0.0, 0.0, 0.0]])
    P = np.diag([std ** 2, std ** 2, 0.01, 1.0, 1.0, 1e-4])[None]
    return x, P


def test_a_region_too_big_for_the_budget_is_narrowed_to_fit() -> None:
    planner = MctsPlanner(PlannerConfig(area='pixels', budget_ms=None, max_iterations=10),
                          MotionModel(), ObservationModel(G))
    x, P = belief(320, 240, 1.2, 80.0)                 # window 77 x 154 px, centre std 80 px
    budget = 0.1 * 640 * 480
    wide = planner.regions(x, P, SIZE)
    assert read_areas(wide, 'pixels', SIZE)[0] > budget
    regions, areas, k = planner.fit_regions(x, P, SIZE, budget)
    assert 0.0 < k[0] < 1.0 and areas[0] <= budget
    assert areas[0] > 0.9 * budget                      # as wide as fits, not narrower
    r = regions[0]                                       # still contains the predicted window
    assert r[0] <= 320 - 1.2 * 32 and r[2] >= 320 + 1.2 * 32
    assert r[1] <= 240 - 1.2 * 64 and r[3] >= 240 + 1.2 * 64
    plan = planner.plan(x, P, SIZE, budget)
    assert plan.action[0] and plan.areas[0] <= budget
    # A person whose bare window is bigger than the budget cannot be attended.
    x, P = belief(320, 240, 3.0, 5.0)                   # window 192 x 384 px
    assert planner.fit_regions(x, P, SIZE, budget)[1][0] > budget
    assert not planner.plan(x, P, SIZE, budget).action.any()


def run_budgeted(s_max: float, n_frames: int = 60, seed: int = 3, area: str = 'pixels',
                 **cfg):
    scene = SyntheticScene(n_people=6, image_size=SIZE, seed=seed, min_height=90.0,
                           max_height=130.0)
    frames = scene.frames(n_frames)
    detector = SimulatedDetector(seed=seed)
    planner = PlannerConfig(k_max=3, s_max=s_max, area=area, budget_ms=None,
                            max_iterations=30, seed=0)
    tracker = MotTracker(detector, TrackerConfig(new_tracks='budget', planner=planner,
                                                 birth_share=0.3, **cfg))
    blank = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
    out = []
    for frame in frames:
        detector.set_truth(frame.boxes)
        out.append(tracker.step(blank))
    return out


@pytest.mark.parametrize('area', ['pixels', 'scaled'])
@pytest.mark.parametrize('s_max', [0.05, 0.1, 0.3])
def test_s_max_binds_the_pixels_read(s_max: float, area: str) -> None:
    results = run_budgeted(s_max, area=area)
    read = np.array([r.processed_fraction for r in results])
    full = np.array([r.full_frame for r in results])
    assert full[0] and read[0] == 1.0                    # the bootstrap
    # Every other frame that is no full frame reads at most (1 - birth_share) S_max ...
    assert read[~full].max() <= 0.7 * s_max + 1e-9
    # ... and the full frames after the bootstrap are paid from what the others left: from
    # frame 2 on, the pixels read never exceed S_max times the frames so far.
    assert np.all(np.cumsum(read[1:]) <= s_max * np.arange(1, len(read)) + 1e-9)
    assert full[1:].sum() >= 1                            # births happen within the budget
    for r in results:                                    # what was read is what is reported
        if not r.full_frame:
            assert r.processed_fraction == pytest.approx(
                read_area(r.regions, SIZE, area) / (640 * 480))
            assert r.covered_fraction == pytest.approx(read_area(r.regions, SIZE) / (640 * 480))
            assert r.covered_fraction >= r.processed_fraction - 1e-12


def test_more_budget_reads_more_and_births_more_often() -> None:
    low, high = run_budgeted(0.05, full_frame_period=5), run_budgeted(0.3, full_frame_period=5)
    mean = lambda rs: np.mean([r.processed_fraction for r in rs[1:]])   # noqa: E731
    assert mean(low) <= 0.05 + 1e-9 and mean(high) <= 0.3 + 1e-9
    assert mean(high) > 2 * mean(low)
    # More full frames (births) with the larger budget.
    assert sum(r.full_frame for r in high) > sum(r.full_frame for r in low)


def test_same_seed_and_iterations_give_the_same_run() -> None:
    a, b = run_budgeted(0.1, n_frames=30), run_budgeted(0.1, n_frames=30)
    for ra, rb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ra.ids, rb.ids)
        np.testing.assert_array_equal(ra.boxes, rb.boxes)
        np.testing.assert_array_equal(ra.regions, rb.regions)
        assert ra.plan_iterations == rb.plan_iterations


def test_tracker_config_refuses_bad_birth_settings() -> None:
    with pytest.raises(ValueError, match='birth_share'):
        TrackerConfig(birth_share=1.0)
    with pytest.raises(ValueError, match='new_tracks'):
        TrackerConfig(new_tracks='sometimes')


class Blinking:
    """Finds one person walking right at 2 px/frame, except on frames 5-9 (hidden), anywhere
    it is asked to look."""

    geometry = DetectorGeometry()
    box_shrink = SimulatedDetector().box_shrink

    def __init__(self) -> None:
        self.frame = 0

    def detect(self, image, regions=None):
        from mot_planner_node.core.detector import Detections
        self.frame += 1
        if 6 <= self.frame <= 10:
            return Detections.empty()
        return Detections(np.array([[100.0 + 2.0 * (self.frame - 1), 150.0, 80.0, 160.0]]),
                          np.array([2.0]))


@pytest.mark.parametrize('keep_lost,same_id', [(0, False), (10, True)])
def test_a_lost_track_comes_back_under_its_id(keep_lost: int, same_id: bool) -> None:
    cfg = TrackerConfig(mode='full', max_misses=2, keep_lost=keep_lost, report_misses=0,
                        confirm_hits=1)
    tracker = MotTracker(Blinking(), cfg)
    blank = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
    ids, alive = [], []
    for _ in range(14):
        ids.append(tracker.step(blank).ids.tolist())
        alive.append(len(tracker.tracks))
    assert ids[0] == [1] and ids[4] == [1]
    assert ids[6] == [] and alive[6] == 1         # missed: kept, not reported (report_misses 0)
    assert alive[8] == 0                          # deleted after 3 misses
    if same_id:                                   # back at once, as the track it was
        assert ids[10:] == [[1]] * 4
    else:                                         # a new track, reported once confirmed
        assert ids[10:] == [[], [2], [2], [2]]


def test_an_upsampling_detector_reads_fewer_pixels_per_region() -> None:
    # Read at upsample x the region's smallest scale: the scaled area shrinks by upsample^2.
    r = np.array([region(0, 0, 100, 200, s_lo=2.0), region(200, 0, 300, 100, s_lo=0.5)])
    np.testing.assert_allclose(read_scale(r, 1.5), [3.0, 1.0])   # never finer than the image
    np.testing.assert_allclose(read_areas(r, 'scaled', SIZE, 1.5),
                               read_areas(r, 'scaled', SIZE) * [(2 / 3) ** 2, 1.0])
    assert read_area(r, SIZE, 'scaled', 1.5) == pytest.approx(100 * 200 / 9 + 100 * 100)
    assert read_area(r, SIZE, 'pixels', 1.5) == read_area(r, SIZE, 'pixels')

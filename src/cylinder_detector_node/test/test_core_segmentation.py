"""Tabletop segmentation (section 4.3.1) and the whole pipeline on ray-cast frames: which plane is
the table (facing up, below the sensor, the highest with objects on it), then its objects."""

from __future__ import annotations

import numpy as np
import pytest

from cylinder_detector_node.core.pipeline import detect_cylinders
from cylinder_detector_node.core.scene import make_room, make_tabletop
from cylinder_detector_node.core.segmentation import SegmentParams, project_box, segment_tabletop

DOWN = 0.5   # m: the synthetic tables below lie this far below the camera (optical frame, y down)


def horizontal(rng: np.random.Generator, n: int, y: float, x: tuple[float, float],
               z: tuple[float, float]) -> np.ndarray:
    """n points on the horizontal rectangle y = const (camera optical frame: y is down)."""
    return np.column_stack([rng.uniform(*x, n), np.full(n, y), rng.uniform(*z, n)])


def upright(rng: np.random.Generator, n: int, base: tuple[float, float, float], r: float,
            h: float) -> np.ndarray:
    """n points on the side of an upright cylinder standing at base (its axis along -y)."""
    a, t = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, h, n)
    return np.column_stack([base[0] + r * np.cos(a), base[1] - t, base[2] + r * np.sin(a)])


def test_tabletop_objects_are_segmented_and_cylinders_found() -> None:
    scene = make_tabletop(np.random.default_rng(0))   # camera looking down 47 degrees
    assert scene.cloud.shape == (480, 640, 3)
    seg = segment_tabletop(scene.cloud, intrinsics=scene.intrinsics)
    assert seg.plane is not None
    # 11 objects; a few may touch or hide behind another
    assert 9 <= len(seg.clusters) <= 11
    for cl in seg.clusters:
        u0, v0, u1, v1 = cl.patch
        assert 0 <= u0 < u1 <= 640 and 0 <= v0 < v1 <= 480
    det = detect_cylinders(scene.cloud, intrinsics=scene.intrinsics)
    up = det.plane[:3]
    for base, r, h in scene.cylinders:
        centre = base + 0.5 * h * up
        best = min(det.cylinders, key=lambda c: np.linalg.norm(np.array(c.centre) - centre))
        assert np.linalg.norm(np.array(best.centre) - centre) < 0.02
        assert abs(best.radius - r) < 0.3 * r
        assert abs(np.array(best.axis) @ up) > np.cos(np.radians(10))
        assert best.confidence > 0.6


def test_table_in_a_room_wins_over_the_back_wall_and_the_floor() -> None:
    """The back wall is the largest plane in view and the floor carries clutter 2 m away: the
    table (below the camera, facing up, the highest plane with objects) must still win."""
    scene = make_room(np.random.default_rng(0), width=320, height=240)
    assert scene.cloud.shape == (240, 320, 3)
    anything = segment_tabletop(scene.cloud, SegmentParams(up=None))
    largest = max(anything.planes, key=lambda p: p['points'])
    assert abs(np.array(largest['normal']) @ scene.up) < 0.1           # the wall: the old trap
    for params in (SegmentParams(), SegmentParams(up=tuple(scene.up), up_tolerance_deg=10)):
        seg = segment_tabletop(scene.cloud, params)
        assert seg.plane is not None
        assert seg.plane[:3] @ scene.up > np.cos(np.radians(2))
        assert seg.plane[3] == pytest.approx(scene.table_height, abs=0.01)
        assert len(seg.clusters) == 3                                     # mug, bottle, box
        centres = np.array([c.points.mean(axis=0) for c in seg.clusters])
        assert np.linalg.norm(centres, axis=1).max() < 1.6                # nothing by the wall
        verdicts = {p['verdict'] for p in seg.planes}
        assert 'table' in verdicts and 'lower than the table' in verdicts   # the floor
        assert any('above the sensor' in v or 'from up' in v for v in verdicts)   # the wall
    det = detect_cylinders(scene.cloud)
    assert len(det.cylinders) >= 2
    for base, r, h in scene.cylinders:
        centre = base + 0.5 * h * scene.up
        c = min(det.cylinders, key=lambda c: np.linalg.norm(np.array(c.centre) - centre))
        assert np.linalg.norm(np.array(c.centre) - centre) < 0.06
        assert abs(c.radius - r) < 0.3 * r           # 320 x 240: a few hundred points each
        assert np.degrees(np.arccos(min(1.0, np.array(c.axis) @ scene.up))) < 6.0
    assert set(det.stage_cpu_ms) == {'downsample', 'plane', 'clusters', 'classification',
                                     'fitting', 'total'}
    assert det.stage_cpu_ms['total'] >= det.stage_cpu_ms['fitting'] > 0.0


def test_the_highest_plane_with_objects_wins_over_a_larger_floor() -> None:
    rng = np.random.default_rng(4)
    floor = horizontal(rng, 60000, 1.2, (-2.0, 2.0), (1.0, 3.5))        # 10 m^2, 1.2 m below
    table = horizontal(rng, 8000, DOWN, (-0.4, 0.4), (0.8, 1.3))         # 0.4 m^2, 0.5 m below
    on_floor = upright(rng, 3000, (1.2, 1.2, 2.5), 0.1, 0.3)             # a bin on the floor
    on_table = upright(rng, 1500, (0.1, DOWN, 1.0), 0.04, 0.1)           # a mug on the table
    seg = segment_tabletop(np.vstack([floor, table, on_floor, on_table]))
    assert seg.plane is not None and seg.plane[3] == pytest.approx(DOWN, abs=0.01)
    assert len(seg.clusters) == 1
    assert np.linalg.norm(seg.clusters[0].points.mean(axis=0)[[0, 2]] - [0.1, 1.0]) < 0.05
    # the empty table is passed over: the floor with its bin is the support then
    seg = segment_tabletop(np.vstack([floor, table, on_floor]))
    assert seg.plane[3] == pytest.approx(1.2, abs=0.01) and len(seg.clusters) == 1


def test_books_on_the_table_are_an_object_not_the_table() -> None:
    rng = np.random.default_rng(5)
    table = horizontal(rng, 30000, DOWN, (-0.6, 0.6), (0.6, 1.6))
    # 5 cm high, 0.3 x 0.25 m
    books = horizontal(rng, 4000, DOWN - 0.05, (-0.15, 0.15), (1.0, 1.25))
    side = np.column_stack([rng.uniform(-0.15, 0.15, 600), rng.uniform(DOWN - 0.05, DOWN, 600),
                            np.full(600, 1.0)])                               # its front side
    cup_on_books = upright(rng, 1500, (0.0, DOWN - 0.05, 1.1), 0.04, 0.1)
    mug = upright(rng, 1500, (0.4, DOWN, 0.8), 0.04, 0.1)
    seg = segment_tabletop(np.vstack([table, books, side, cup_on_books, mug]))
    assert seg.plane[3] == pytest.approx(DOWN, abs=0.005)
    assert any('lies on' in p.get('verdict', '') for p in seg.planes)
    centres = sorted(tuple(np.round(c.points.mean(axis=0)[[0, 2]], 1)) for c in seg.clusters)
    # books with cup, mug
    assert len(centres) == 2 and centres[1][0] == pytest.approx(0.4, abs=0.05)


def test_walls_and_ceilings_are_no_table() -> None:
    rng = np.random.default_rng(6)
    # facing the camera
    wall = np.column_stack([rng.uniform(-1, 1, (30000, 2)), np.full(30000, 1.5)])
    # something before it
    box = rng.uniform([-0.1, -0.1, 1.3], [0.1, 0.1, 1.45], (2000, 3))
    seg = segment_tabletop(np.vstack([wall, box]))
    assert seg.plane is None and seg.clusters == []
    assert 'no table plane' in seg.messages[0] and 'up' in seg.messages[0]
    ceiling = horizontal(rng, 20000, -0.8, (-1, 1), (0.5, 2.0))                  # above the camera
    assert segment_tabletop(ceiling).plane is None
    # up=None takes any plane (normal towards the sensor): the wall, with the box on it
    legacy = segment_tabletop(np.vstack([wall, box]), SegmentParams(up=None))
    assert legacy.plane is not None and abs(legacy.plane[2]) > 0.99 and len(legacy.clusters) == 1
    # the same wall is a floor for a camera whose up is -z (looking straight down)
    down = segment_tabletop(np.vstack([wall, box]), SegmentParams(up=(0.0, 0.0, -1.0)))
    assert down.plane is not None and len(down.clusters) == 1


def test_bad_parameters_are_refused() -> None:
    for bad in ({'up': (0.0, 0.0, 0.0)}, {'up': (np.nan, 1.0, 0.0)}, {'up_tolerance_deg': 90.0},
                {'up_tolerance_deg': 0.0}, {'max_planes': 0}):
        with pytest.raises(ValueError):
            SegmentParams(**bad)


def test_bad_clouds_give_messages_and_no_clusters() -> None:
    empty = segment_tabletop(np.zeros((0, 3)))
    assert empty.clusters == [] and '0 finite points' in empty.messages[0]
    nan = segment_tabletop(np.full((48, 64, 3), np.nan))
    assert nan.clusters == [] and '0 finite points' in nan.messages[0]
    assert set(nan.cpu_ms) == {'downsample', 'plane', 'clusters'}
    blob = segment_tabletop(np.random.default_rng(0).normal(0, 0.001, (50, 3)))
    assert blob.clusters == [] and 'no table plane' in blob.messages[0]
    rng = np.random.default_rng(1)   # a bare table: a plane and nothing on it
    bare = segment_tabletop(horizontal(rng, 20000, DOWN, (-0.5, 0.5), (0.5, 1.5)))
    assert bare.plane is not None and bare.clusters == [] and 'no objects' in bare.messages[0]
    assert bare.plane[3] == pytest.approx(DOWN, abs=0.005)
    det = detect_cylinders(np.full((10, 3), np.nan))
    assert det.cylinders == [] and det.messages


def test_small_clusters_are_dropped_with_a_message() -> None:
    rng = np.random.default_rng(2)
    table = horizontal(rng, 20000, DOWN, (-0.5, 0.5), (0.5, 1.5))
    # 5 cm above the table, a few voxels
    crumb = rng.normal([0.0, DOWN - 0.05, 1.0], 0.002, (40, 3))
    seg = segment_tabletop(np.vstack([table, crumb]))
    assert seg.plane is not None and seg.clusters == []
    assert any('below' in m or 'no objects' in m for m in seg.messages)


def test_project_box() -> None:
    k = (500.0, 500.0, 320.0, 240.0)
    assert project_box(np.array([-0.1, -0.1, 1.0]), np.array([0.1, 0.1, 1.2]), k,
                       (640, 480)) == (270, 190, 370, 290)
    assert project_box(np.array([-0.1, -0.1, -2.0]), np.array([0.1, 0.1, -1.0]), k,
                       (640, 480)) is None

"""Tabletop segmentation (section 4.3.1) and the whole pipeline on a ray-cast tabletop frame."""

from __future__ import annotations

import numpy as np

from cylinder_detector_node.core.pipeline import detect_cylinders
from cylinder_detector_node.core.scene import make_tabletop
from cylinder_detector_node.core.segmentation import project_box, segment_tabletop


def test_tabletop_objects_are_segmented_and_cylinders_found() -> None:
    scene = make_tabletop(np.random.default_rng(0))
    assert scene.cloud.shape == (480, 640, 3)
    seg = segment_tabletop(scene.cloud, intrinsics=scene.intrinsics)
    assert seg.plane is not None
    assert 9 <= len(seg.clusters) <= 11          # 11 objects; a few may touch or hide behind another
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


def test_bad_clouds_give_messages_and_no_clusters() -> None:
    empty = segment_tabletop(np.zeros((0, 3)))
    assert empty.clusters == [] and '0 finite points' in empty.messages[0]
    nan = segment_tabletop(np.full((48, 64, 3), np.nan))
    assert nan.clusters == [] and '0 finite points' in nan.messages[0]
    blob = segment_tabletop(np.random.default_rng(0).normal(0, 0.001, (50, 3)))
    assert blob.clusters == [] and 'no table plane' in blob.messages[0]
    rng = np.random.default_rng(1)   # a bare table: a plane and nothing on it
    table = np.column_stack([rng.uniform(-0.5, 0.5, (20000, 2)), np.full(20000, 1.0)])
    bare = segment_tabletop(table)
    assert bare.plane is not None and bare.clusters == [] and 'no objects' in bare.messages[0]
    det = detect_cylinders(np.full((10, 3), np.nan))
    assert det.cylinders == [] and det.messages


def test_small_clusters_are_dropped_with_a_message() -> None:
    rng = np.random.default_rng(2)
    table = np.column_stack([rng.uniform(-0.5, 0.5, (20000, 2)), np.full(20000, 1.0)])
    crumb = rng.normal([0.0, 0.0, 0.95], 0.002, (40, 3))      # 5 cm above the table, a few voxels
    seg = segment_tabletop(np.vstack([table, crumb]))
    assert seg.clusters == []
    assert any('below' in m or 'no objects' in m for m in seg.messages)


def test_project_box() -> None:
    k = (500.0, 500.0, 320.0, 240.0)
    assert project_box(np.array([-0.1, -0.1, 1.0]), np.array([0.1, 0.1, 1.2]), k, (640, 480)) == (270, 190, 370, 290)
    assert project_box(np.array([-0.1, -0.1, -2.0]), np.array([0.1, 0.1, -1.0]), k, (640, 480)) is None

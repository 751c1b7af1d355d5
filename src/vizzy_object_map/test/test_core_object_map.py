"""The object map's fusion, naming, fading and merging (vizzy_object_map.core, no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vizzy_object_map.core.object_map import (
    CameraView,
    GeometryObservation,
    MapConfig,
    ObjectMap,
    Recognition,
)
from vizzy_object_map.core.observations import (
    cluster_observation,
    cylinder_extents,
    cylinder_observation,
)
from vizzy_vision.camera import camera_matrix

K = camera_matrix(640, 480, 85.4)


def camera_looking_along_x(height: float = 0.5) -> CameraView:
    """An optical frame at (0, 0, height) looking along +x (z forward, x right = -y,
    y down = -z)."""
    pose = np.eye(4)
    pose[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    pose[:3, 3] = (0.0, 0.0, height)
    return CameraView(K, pose, 640, 480)


def geometry(x: float, y: float, z: float, size: float = 0.07, t: float = 0.0,
             sigma: float = 0.01) -> GeometryObservation:
    return GeometryObservation(np.array([x, y, z]), np.eye(3) * sigma ** 2,
                               np.array([size, size, size]), t)


def pixel_of(view: CameraView, point: tuple[float, float, float]) -> tuple[float, float]:
    uv, _ = view.project(np.array([point]))
    return float(uv[0, 0]), float(uv[0, 1])


def test_repeated_clusters_become_established_objects_at_their_mean() -> None:
    rng = np.random.default_rng(0)
    m = ObjectMap(MapConfig(established_geometry=3))
    truth = np.array([[0.8, 0.1, 0.8], [0.9, -0.2, 0.78]])
    for i in range(20):
        obs = [geometry(*(p + rng.normal(0, 0.01, 3)), t=0.5 * i) for p in truth]
        ids = m.add_geometry(obs[::-1] if i % 2 else obs)       # order must not matter
        assert len(set(ids)) == 2
    objects = m.objects()
    assert len(objects) == 2
    for o in objects:
        err = np.min(np.linalg.norm(truth - o.position, axis=1))
        assert err < 0.01                       # 20 views of 1 cm noise
        assert o.geometry == 20 and m.is_established(o) and not m.is_confirmed(o)
        assert o.first_seen == 0.0 and o.last_seen == 9.5
        assert np.all(np.linalg.eigvalsh(o.covariance) >= m.config.min_sigma_m ** 2 - 1e-12)
    assert len(m.unrecognised()) == 2


def test_recognitions_name_the_front_object_under_their_pixel() -> None:
    view = camera_looking_along_x()
    m = ObjectMap(MapConfig(min_recognitions=2, min_label_share=0.5))
    near, far = (0.8, 0.0, 0.5), (1.2, 0.0, 0.5)       # far is hidden behind near
    side = (0.8, 0.3, 0.5)
    for t in range(3):
        m.add_geometry([geometry(*near, t=t), geometry(*far, t=t), geometry(*side, t=t)])
    ids = {tuple(np.round(o.position, 1)): o.id for o in m.objects()}
    u, v = pixel_of(view, near)
    out = m.add_recognitions([Recognition(u, v, 'can', 0.8, 3.0),
                              Recognition(*pixel_of(view, side), 'box', 0.6, 3.0)], view)
    assert out == [ids[(0.8, 0.0, 0.5)], ids[(0.8, 0.3, 0.5)]]
    can = m.get(out[0])
    assert can is not None and can.recognitions == 1 and not m.is_confirmed(can)
    m.add_recognitions([Recognition(u + 3, v - 2, 'can', 0.7, 4.0)], view)
    assert m.is_confirmed(can) and can.label('background') == ('can', 1.0)
    # a weaker third opinion keeps the name, with its share
    m.add_recognitions([Recognition(u, v, 'bottle', 0.5, 5.0)], view)
    label, share = can.label('background')
    assert label == 'can' and share == pytest.approx(1.5 / 2.0)
    assert [o.id for o in m.objects(confirmed_only=True)] == [can.id]
    # too weak to count
    assert m.add_recognitions([Recognition(u, v, 'jar', 0.1, 6.0)], view) == [None]
    assert 'jar' not in can.evidence


def test_a_recognition_on_the_wall_fades_and_a_repeated_one_is_kept() -> None:
    view = camera_looking_along_x()
    cfg = MapConfig(tentative_timeout_s=5.0, min_recognitions_without_geometry=3)
    m = ObjectMap(cfg)
    wall = np.array([3.5, 0.2, 1.2])
    u, v = pixel_of(view, tuple(wall))
    cov = np.eye(3) * 0.02 ** 2
    # without depth there is nowhere to put it
    assert m.add_recognitions([Recognition(u, v, 'bottle', 0.7, 1.0)], view) == [None]
    assert m.unplaced == 1 and len(m) == 0
    # with depth: a tentative object that fades
    [oid] = m.add_recognitions([Recognition(u, v, 'bottle', 0.7, 1.0, wall, cov)], view)
    assert oid is not None
    obj = m.get(oid)
    assert obj is not None and not m.is_confirmed(obj) and not m.is_established(obj)
    assert m.expire(5.5) == []                              # not yet 5 s
    assert m.expire(6.1) == [oid] and len(m) == 0 and m.expired == 1
    # seen three times (depth each time): confirmed without geometry, and kept
    for t in (10.0, 11.0, 12.0):
        m.add_recognitions([Recognition(u, v, 'bottle', 0.7, t, wall + 0.005, cov)], view)
    [obj] = m.objects()
    assert m.is_confirmed(obj) and obj.recognitions == 3
    assert m.expire(100.0) == []


def test_the_reject_label_names_nothing_and_outvotes_a_false_name() -> None:
    view = camera_looking_along_x()
    m = ObjectMap(MapConfig(min_recognitions=1, min_label_share=0.5))
    point = (0.9, 0.05, 0.45)
    m.add_geometry([geometry(*point)] * 1)
    u, v = pixel_of(view, point)
    [oid] = m.add_recognitions([Recognition(u, v, 'bottle', 0.4, 1.0)], view)
    obj = m.get(oid)
    assert obj is not None and m.is_confirmed(obj)
    m.add_recognitions([Recognition(u, v, 'background', 0.9, 2.0)], view)
    assert obj.recognitions == 1 and obj.label('background') == ('bottle', pytest.approx(0.4 / 1.3))
    assert not m.is_confirmed(obj)
    # a reject where no object is creates nothing, even with depth
    wall = np.array([3.0, -0.5, 1.0])
    wu, wv = pixel_of(view, tuple(wall))
    assert m.add_recognitions([Recognition(wu, wv, 'background', 0.9, 3.0, wall,
                                           np.eye(3) * 1e-4)], view) == [None]
    assert len(m) == 1 and m.unplaced == 0


def test_objects_closer_than_the_merge_radius_merge_with_their_evidence() -> None:
    view = camera_looking_along_x()
    m = ObjectMap(MapConfig(association_radius_m=0.025, merge_radius_m=0.03))
    a, b = (0.8, 0.0, 0.5), (0.8, 0.05, 0.5)
    m.add_geometry([geometry(*a, size=0.03), geometry(*b, size=0.03)])
    assert len(m) == 2
    m.add_recognitions([Recognition(*pixel_of(view, a), 'can', 0.9, 1.0)], view)
    m.add_recognitions([Recognition(*pixel_of(view, b), 'can', 0.8, 1.0)], view)
    # a precise view of b puts it 2.6 cm from a: one object after all
    m.add_geometry([geometry(0.8, 0.026, 0.5, size=0.03, t=2.0, sigma=0.001)])
    assert len(m) == 1 and m.merged == 1
    [obj] = m.objects()
    assert obj.evidence['can'] == pytest.approx(1.7) and obj.recognitions == 2
    assert obj.geometry == 3 and obj.last_seen == 2.0
    assert 0.0 < obj.position[1] < 0.026


def test_a_one_off_cluster_fades_but_an_object_named_once_seen_again_stays() -> None:
    m = ObjectMap(MapConfig(established_geometry=3, tentative_timeout_s=2.0))
    m.add_geometry([geometry(1.0, 0.4, 0.75, t=0.0)])
    assert m.expire(1.0) == [] and len(m) == 1
    assert len(m.expire(2.5)) == 1 and len(m) == 0


def test_geometry_observations_in_the_map_frame() -> None:
    # a sensor 0.5 m up, turned 90 deg about z: its x axis is the map's y
    pose = np.eye(4)
    pose[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = (0.0, 0.0, 0.5)
    obs = cluster_observation(pose, np.array([1.0, 0.0, 0.2]), np.eye(3),
                              np.array([0.2, 0.1, 0.05]), 3.0)
    np.testing.assert_allclose(obs.position, [0.0, 1.0, 0.7])
    np.testing.assert_allclose(obs.size, [0.1, 0.2, 0.05])
    assert obs.stamp == 3.0 and obs.kind == 'cluster'
    # a lying cylinder along the sensor's x = the map's y
    cyl = cylinder_observation(pose, np.array([1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]),
                               0.03, 0.2, 4.0)
    np.testing.assert_allclose(cyl.size, [0.06, 0.2, 0.06])
    assert cyl.kind == 'cylinder' and cyl.covariance[0, 0] < obs.covariance[0, 0]
    # an upright one, and a tilted one
    np.testing.assert_allclose(cylinder_extents(np.array([0, 0, 1.0]), 0.033, 0.122),
                               [0.066, 0.066, 0.122])
    tilted = cylinder_extents(np.array([1.0, 0.0, 1.0]), 0.05, 0.1)
    assert tilted[0] == pytest.approx(0.1 * math.sqrt(0.5) + 0.1 * math.sqrt(0.5))
    assert tilted[1] == pytest.approx(0.1)


def test_cylinders_settle_the_size_more_than_clusters() -> None:
    m = ObjectMap()
    m.add_geometry([geometry(0.8, 0.0, 0.5, size=0.04)])
    m.add_geometry([GeometryObservation(np.array([0.8, 0.0, 0.5]), np.eye(3) * 1e-4,
                                        np.array([0.066, 0.066, 0.122]), 1.0, 'cylinder')])
    [obj] = m.objects()
    assert obj.cylinders == 1
    np.testing.assert_allclose(obj.size, (np.array([0.04, 0.04, 0.04])
                                          + 3 * np.array([0.066, 0.066, 0.122])) / 4)


def test_bad_rules_are_refused_with_their_name() -> None:
    with pytest.raises(ValueError, match='association_radius_m'):
        MapConfig(association_radius_m=0.0)
    with pytest.raises(ValueError, match='min_recognitions'):
        MapConfig(min_recognitions=0)
    with pytest.raises(ValueError, match='min_label_share'):
        MapConfig(min_label_share=1.5)
    m = ObjectMap()
    m.reconfigure(min_recognitions=5)
    assert m.config.min_recognitions == 5


def test_looks_go_to_unnamed_objects_settle_dwell_and_give_up() -> None:
    from vizzy_object_map.core.attention import DWELL, IDLE, SACCADE, LookConfig, LookScheduler
    view = camera_looking_along_x()
    m = ObjectMap(MapConfig(established_geometry=1, min_recognitions=1))
    a, b = (0.8, 0.3, 0.5), (0.8, -0.1, 0.5)
    m.add_geometry([geometry(*a), geometry(*b)])
    looks = LookScheduler(LookConfig(dwell_s=1.0, max_looks=2, settle_timeout_s=3.0))
    origin = np.array([0.0, 0.0, 0.5])
    # the nearest in angle to where the eyes are (straight ahead): b
    first = looks.update(10.0, False, False, m, origin, np.array([1.0, 0.0, 0.5]))
    assert first is not None and np.allclose(first.position, b) and looks.state == SACCADE
    assert looks.update(10.1, True, True, m, origin, None) is None          # eyes moving
    assert looks.update(10.3, False, True, m, origin, None) is None         # settled
    assert looks.state == DWELL
    assert looks.update(11.0, False, True, m, origin, None) is None         # dwelling
    # named while dwelling: the next look at once (inhibition of return)
    m.add_recognitions([Recognition(*pixel_of(view, b), 'can', 0.9, 11.1)], view)
    second = looks.update(11.2, False, True, m, origin, None)
    assert second is not None and np.allclose(second.position, a)
    # never settles (preempted): abandoned after the timeout, a retries until max_looks
    assert looks.update(13.0, False, False, m, origin, None) is None
    third = looks.update(14.5, False, False, m, origin, None)
    assert third is not None and third.id == second.id and looks.abandoned == 1
    assert looks.update(18.0, False, False, m, origin, None) is None        # given up on a
    assert looks.state == IDLE and looks.looks[second.id] == 2 and looks.sent == 3


def test_two_pieces_of_one_large_box_merge_by_overlap() -> None:
    m = ObjectMap(MapConfig(association_radius_m=0.02, merge_radius_m=0.03, merge_overlap=0.5))
    # a 14 cm box seen as two clusters 6 cm apart: the small piece lies inside the big one
    big = GeometryObservation(np.array([0.9, 0.0, 0.3]), np.eye(3) * 1e-4,
                              np.array([0.14, 0.14, 0.12]), 0.0)
    piece = GeometryObservation(np.array([0.9, 0.06, 0.3]), np.eye(3) * 1e-4,
                                np.array([0.04, 0.04, 0.10]), 0.0)
    m.add_geometry([big, piece])
    assert len(m) == 1 and m.merged == 1
    # two small objects side by side, 5 cm apart, do not touch: kept apart
    m2 = ObjectMap(MapConfig(association_radius_m=0.02))
    m2.add_geometry([geometry(0.9, 0.0, 0.3, size=0.04), geometry(0.9, 0.05, 0.3, size=0.04)])
    assert len(m2) == 2
    with pytest.raises(ValueError, match='merge_overlap'):
        MapConfig(merge_overlap=0.0)


def test_a_name_at_the_fixation_goes_to_what_stands_in_front_of_it() -> None:
    """The camera looks at a short can's centre past a tall box in front of it: the image
    centre shows the box, so the name is the box's (the recogniser names the occluder)."""
    view = camera_looking_along_x(height=0.5)
    m = ObjectMap(MapConfig(association_radius_m=0.06))
    can = GeometryObservation(np.array([1.0, 0.0, 0.3]), np.eye(3) * 1e-4,
                              np.array([0.066, 0.066, 0.12]), 0.0)
    box = GeometryObservation(np.array([0.7, 0.0, 0.32]), np.eye(3) * 1e-4,
                              np.array([0.1, 0.1, 0.2]), 0.0)
    can_id, box_id = m.add_geometry([can, box])
    origin = view.origin
    assert m.first_on_ray(origin, can.position).id == box_id          # the box is in the way
    assert m.first_on_ray(origin, np.array([1.0, 0.3, 0.3])) is None   # nothing there
    # a ray that only grazes the box's loose corner does not count
    assert m.first_on_ray(origin, np.array([0.75, 0.049, 0.3])) is None
    rec = Recognition(*pixel_of(view, tuple(can.position)), 'box', 0.9, 1.0, can.position,
                      np.eye(3) * 1e-4)
    assert m.add_recognitions([rec], view) == [box_id]
    # the box is taller than the can: no point of the can is in sight
    from vizzy_object_map.core.attention import aim_point, choose_target
    can_obj, box_obj = m.get(can_id), m.get(box_id)
    assert can_obj is not None and box_obj is not None
    assert aim_point(m, box_obj, origin) is not None
    assert aim_point(m, can_obj, origin) is None          # hidden at its centre, top and sides
    chosen = choose_target([can_obj, box_obj], {}, 3, origin, None,
                           lambda o: aim_point(m, o, origin))
    assert chosen is not None and chosen[0] is box_obj     # the hidden can waits


def test_a_can_behind_a_low_box_is_aimed_at_over_it() -> None:
    view = camera_looking_along_x(height=0.5)
    m = ObjectMap()
    tall_can = GeometryObservation(np.array([1.0, 0.0, 0.3]), np.eye(3) * 1e-4,
                                   np.array([0.066, 0.066, 0.3]), 0.0)
    low_box = GeometryObservation(np.array([0.7, 0.0, 0.25]), np.eye(3) * 1e-4,
                                  np.array([0.1, 0.1, 0.3]), 0.0)
    assert m.first_on_ray(view.origin, tall_can.position) is None     # (empty map)
    can_id, box_id = m.add_geometry([tall_can, low_box])
    from vizzy_object_map.core.attention import aim_point
    assert m.first_on_ray(view.origin, tall_can.position).id == box_id   # centre: hidden
    can_obj = m.get(can_id)
    assert can_obj is not None
    aim = aim_point(m, can_obj, view.origin)
    assert aim is not None and aim[2] > tall_can.position[2]          # its upper part
    assert m.first_on_ray(view.origin, aim) is can_obj


def test_fixation_at_is_the_latest_still_recent_gaze_state_at_or_before_the_stamp() -> None:
    from vizzy_object_map.core.observations import fixation_at

    a, b = np.array([1.0, 0.0, 0.5]), np.array([0.8, 0.2, 0.4])
    states = [(1.0, a, False), (1.1, None, False), (1.2, b, True), (1.3, b, False)]
    assert np.array_equal(fixation_at(states, 1.05, 0.25), a)
    assert fixation_at(states, 1.15, 0.25) is None       # no fixation point (no active source)
    assert fixation_at(states, 1.25, 0.25) is None       # the eyes were moving
    assert np.array_equal(fixation_at(states, 1.4, 0.25), b)
    assert fixation_at(states, 1.6, 0.25) is None        # too old to tell of this image
    assert fixation_at(states, 0.5, 0.25) is None        # before every state

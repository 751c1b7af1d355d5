"""/foveation/detections_2d: pass-2 detections as vision_msgs/Detection2DArray (box geometry,
ranked class hypotheses, the message the node builds) on the bundled runtime."""

from __future__ import annotations

import numpy as np
import pytest

from foveation_node import node
from foveation_node.core.detections_2d import box_centre_size, ranked_hypotheses
from foveation_node.core.foveation import Foveator
from foveation_node.core.recognition import Classifier, Detection, two_pass
from vizzy_runtime import msgs

LABELS = ['cup', 'box', 'ball', 'can']
# pass-2 rows (one per pass-1 box centre) over LABELS
PROBS = np.array([[0.10, 0.60, 0.05, 0.25],
                  [0.70, 0.20, 0.04, 0.06]])


def _detection(class_id: int, row: int | None, box=(10, 20, 29, 59)) -> Detection:
    return Detection(class_id, LABELS[class_id], float(PROBS[row or 0, class_id]), box,
                     (12.0, 34.0), 1 if row is not None else 0, row=row)


def test_box_centre_and_size_of_inclusive_pixel_bounds() -> None:
    # pixels 10..29 (20 columns) and 20..59 (40 rows): centre between pixels 19 and 20
    assert box_centre_size((10, 20, 29, 59)) == (19.5, 39.5, 20.0, 40.0)
    assert box_centre_size((5, 7, 5, 7)) == (5.0, 7.0, 1.0, 1.0)      # one pixel
    u, v, w, h = box_centre_size((10, 20, 29, 59))
    assert (u - w / 2, u + w / 2) == (9.5, 29.5)                       # edges of pixels 10, 29
    with pytest.raises(ValueError, match=r'not a box .*\(10, 20, 9, 59\)'):
        box_centre_size((10, 20, 9, 59))


def test_hypotheses_own_label_first_then_its_row_by_probability() -> None:
    # 'can' was chosen from row 0, where 'box' is likelier (merge took 'box' elsewhere first)
    can = _detection(3, row=0)
    assert ranked_hypotheses(can, PROBS, LABELS, 4) == [
        ('can', 0.25), ('box', 0.60), ('cup', 0.10), ('ball', 0.05)]
    assert ranked_hypotheses(can, PROBS, LABELS, 2) == [('can', 0.25), ('box', 0.60)]
    assert ranked_hypotheses(can, PROBS, LABELS, 1) == [('can', 0.25)]
    assert len(ranked_hypotheses(can, PROBS, LABELS, 100)) == len(LABELS)
    cup = _detection(0, row=1)
    assert ranked_hypotheses(cup, PROBS, LABELS, 3) == [('cup', 0.70), ('box', 0.20),
                                                        ('can', 0.06)]


def test_hypotheses_refuse_what_does_not_fit() -> None:
    with pytest.raises(ValueError, match="'cup' \\(pass 0\\) has no pass-2 row"):
        ranked_hypotheses(_detection(0, row=None), PROBS, LABELS, 3)
    with pytest.raises(ValueError, match=r'row 2 is not in pass-2 probabilities of shape \(2, 4\)'):
        ranked_hypotheses(Detection(0, 'cup', 0.7, (0, 0, 1, 1), (0.0, 0.0), 1, row=2), PROBS,
                          LABELS, 3)
    with pytest.raises(ValueError, match='4 classes but there are 3 labels'):
        ranked_hypotheses(_detection(0, row=1), PROBS, LABELS[:3], 3)
    with pytest.raises(ValueError, match='top_k must be >= 1, got 0'):
        ranked_hypotheses(_detection(0, row=1), PROBS, LABELS, 0)


def test_two_pass_detections_carry_their_pass_two_row(stub_model) -> None:
    clf = Classifier(*stub_model)
    img = np.full((240, 320, 3), 40, np.uint8)
    img[48:72, 248:272] = (230, 30, 30)            # red, up right
    img[170:194, 40:64] = (30, 30, 230)            # blue, down left
    foveator = Foveator(320, 240, 4, 30.0)
    result = two_pass(clf, img, (159.5, 119.5), foveator.foveate, top_k=3)
    assert result.second and all(d.row is None for d in result.first)
    for d in result.second:
        assert d.row is not None
        # found in the image foveated at pass-1 box `row`'s centre, with that row's probability
        assert d.fixation == result.first[d.row].centre
        assert d.score == float(result.probs_second[d.row, d.class_id])


def test_the_node_builds_one_detection_2d_per_pass_two_detection() -> None:
    Header = msgs.get_message('std_msgs/msg/Header')
    header = Header(frame_id='left_camera_optical_frame')
    header.stamp.sec, header.stamp.nanosec = 7, 500
    dets = [_detection(0, row=1, box=(100, 50, 139, 69)), _detection(3, row=0)]
    out = node.detection_2d_array(header, dets, PROBS, LABELS, 3)
    assert msgs.type_of(out) == 'vision_msgs/msg/Detection2DArray'
    assert out.header == header and len(out.detections) == 2
    cup, can = out.detections
    assert cup.header == header and cup.id == ''
    assert (cup.bbox.center.position.x, cup.bbox.center.position.y) == (119.5, 59.5)
    assert cup.bbox.center.theta == 0.0 and (cup.bbox.size_x, cup.bbox.size_y) == (40.0, 20.0)
    assert [(r.hypothesis.class_id, r.hypothesis.score) for r in cup.results] == [
        ('cup', 0.70), ('box', 0.20), ('can', 0.06)]
    assert [r.hypothesis.class_id for r in can.results] == ['can', 'box', 'cup']
    assert (can.bbox.size_x, can.bbox.size_y) == (20.0, 40.0)
    # what crosses the wire
    back = msgs.deserialize(bytes(msgs.serialize(out)), 'vision_msgs/msg/Detection2DArray')
    assert back == out
    # no pass-2 detection (a frame of background only): an empty array with the frame's header
    empty = node.detection_2d_array(header, [], np.zeros((0, 4)), LABELS, 3)
    assert empty.header == header and list(empty.detections) == []

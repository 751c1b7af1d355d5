"""Scoring a map against ground truth: labels, radii, one-to-one pairing, false objects."""

import pytest

from vizzy_vision.object_scoring import Labelled, score

TRUTH = [Labelled('can', (1.0, 0.0, 0.7)), Labelled('box', (1.0, 0.3, 0.7)),
         Labelled('jar', (0.8, -0.2, 0.7))]


def test_right_label_within_the_radius_is_found_once() -> None:
    reported = [Labelled('can', (1.03, 0.0, 0.7)),      # 3 cm: found at 5 cm
                Labelled('can', (1.0, 0.02, 0.7)),      # a second map object on the same can
                Labelled('jar', (0.8, -0.2, 0.77)),     # 7 cm: found at 10 cm only
                Labelled('box', (1.0, -0.05, 0.7)),     # a box named on the can: misnamed
                Labelled('bottle', (3.0, 0.0, 1.2))]    # on the wall: a false object
    s5 = score(reported, TRUTH, 0.05)
    assert (s5.found, s5.false_objects, s5.misnamed) == (1, 1, 3)
    assert s5.recall == pytest.approx(1 / 3) and s5.precision == pytest.approx(1 / 5)
    s10 = score(reported, TRUTH, 0.10)
    assert s10.found == 2 and s10.as_dict()['recall'] == pytest.approx(2 / 3)


def test_empty_maps_and_truths() -> None:
    empty = score([], TRUTH)
    assert empty.recall == 0.0 and empty.precision == 1.0 and empty.false_objects == 0
    none = score([Labelled('can', (0.0, 0.0, 0.0))], [])
    assert none.recall == 1.0 and none.precision == 0.0 and none.false_objects == 1

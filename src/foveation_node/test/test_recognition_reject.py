"""The reject (background) class of core.recognition: never a detection, never localised, never
a saccade target; a pass-2 label counts only where it beats background.

On the stub colour-detector model of conftest.py with its blue output labelled 'background'
(no training, no rendering): a blue wash stands for a wall that the model calls background.
"""

from __future__ import annotations

import numpy as np
import pytest

from foveation_node.core.foveation import Foveator
from foveation_node.core.recognition import (
    BACKGROUND_LABEL,
    Classifier,
    Detection,
    merge_second_pass,
    saccade_target,
    two_pass,
)

W, H = 640, 480
LABELS = ('red', 'green', BACKGROUND_LABEL)        # the stub's blue detector is "background"
CENTRE = ((W - 1) / 2, (H - 1) / 2)


@pytest.fixture
def reject_model(stub_model, tmp_path) -> Classifier:
    labels = tmp_path / 'reject.labels'
    labels.write_text('\n'.join(LABELS) + '\n')
    return Classifier(stub_model[0], labels)


def _wall(red_patch: tuple[int, int] | None = None) -> np.ndarray:
    """A blue-tinted wall (the stub's background), optionally with a bright red patch."""
    img = np.empty((H, W, 3), np.uint8)
    img[:] = (40, 40, 120)
    if red_patch is not None:
        u, v = red_patch
        img[v - 20:v + 20, u - 20:u + 20] = (250, 10, 10)
    return img


def test_the_reject_class_is_found_by_its_label(stub_model, reject_model) -> None:
    assert reject_model.reject_class == 2 and reject_model.object_classes == [0, 1]
    plain = Classifier(*stub_model)                          # red, green, blue: no background
    assert plain.reject_class is None and plain.object_classes == [0, 1, 2]


def test_merge_never_returns_background_and_needs_a_class_to_beat_it() -> None:
    bg = 3
    probs = np.array([[0.10, 0.20, 0.05, 0.65],     # row 0: background best -> nothing
                      [0.50, 0.10, 0.15, 0.25],     # row 1: class 0 beats background (0.25)
                      [0.30, 0.35, 0.05, 0.30]])    # row 2: class 1 beats it, class 0 only ties
    chosen = merge_second_pass(probs, 3, reject=bg)
    assert chosen == [(0, 1, pytest.approx(0.50)), (1, 2, pytest.approx(0.35))]
    assert merge_second_pass(probs[:1], 3, reject=bg) == []
    # without a reject class the same rows give background as a label like any other
    assert 3 in [c for c, _, _ in merge_second_pass(probs, 3)]


def test_on_background_two_pass_reports_nothing_and_sends_no_saccade(reject_model) -> None:
    foveator = Foveator(W, H, 5, 100.0)
    result = two_pass(reject_model, _wall(), CENTRE, foveator.foveate, top_k=5)
    assert int(np.argmax(result.probs_first)) == reject_model.reject_class   # it says "wall"
    # pass 1 still localises the object classes (the candidates pass 2 looks at: two rows of
    # pass 2; top_k 5 is cut to the 2 object classes) but reports none: neither beats the wall
    assert result.first == []
    assert result.probs_second.shape == (2, 3)
    assert result.second == []                                # every row: background best
    assert saccade_target(result.second, CENTRE, 0.0, 0.0) is None


def test_an_object_that_beats_background_is_detected_and_targeted(reject_model) -> None:
    foveator = Foveator(W, H, 5, 100.0)
    patch = (520, 110)
    result = two_pass(reject_model, _wall(patch), CENTRE, foveator.foveate, top_k=5)
    labels = [d.label for d in (*result.first, *result.second)]
    assert BACKGROUND_LABEL not in labels
    assert [d.label for d in result.second] == ['red']       # green never beats the wall
    red = result.second[0]
    assert abs(red.centre[0] - patch[0]) < 40 and abs(red.centre[1] - patch[1]) < 40
    assert saccade_target(result.second, CENTRE, 0.3, 20.0) is red


def test_a_background_detection_is_never_a_saccade_target() -> None:
    wall = Detection(2, BACKGROUND_LABEL, 0.99, (600, 100, 620, 120), (0.0, 0.0), 1)
    can = Detection(0, 'can', 0.5, (100, 100, 120, 120), (0.0, 0.0), 1)
    assert saccade_target([wall], CENTRE, 0.0, 0.0) is None
    assert saccade_target([wall, can], CENTRE, 0.3, 20.0) is can

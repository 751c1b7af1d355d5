"""The packaged whole-frame recognition model (foveation_cnn: the foveated frame shrunk to
227x227; the node's default is the window model, test_window_model.py) on freshly rendered
held-out views (a seed used neither for
training nor for the training's held-out set): it beats chance by a wide margin, and its
saliency boxes land on the rendered object; its background class says "nothing here" on a
wall (rendered and synthetic) and not on objects."""

from __future__ import annotations

import numpy as np
import pytest

from foveation_node.core.foveation import Foveator
from foveation_node.core.recognition import BACKGROUND_LABEL, Classifier, localise, two_pass
from foveation_node.node import resolve_path
from vizzy_runtime.testing import no_renderer

pytest.importorskip('mujoco')
render_mod = pytest.importorskip('vizzy_sim_bridge.core.render')

PER_CLASS = 5
MODEL = 'package://foveation_node/models/foveation_cnn.pt'
LABELS = 'package://foveation_node/models/foveation_cnn.labels'


@pytest.fixture(scope='module')
def views():
    from foveation_node.training.object_views import CLASSES, ObjectViews
    try:
        with ObjectViews(640, 480, seed=7) as ov:
            return ov.dataset(PER_CLASS * len(CLASSES), seed=9001)
    except render_mod.RendererUnavailable as exc:
        no_renderer(str(exc))


@pytest.fixture(scope='module')
def classifier():
    return Classifier(resolve_path(MODEL), resolve_path(LABELS))


def test_the_packaged_model_loads_with_its_preprocessing(classifier) -> None:
    from foveation_node.training.object_views import CLASSES
    assert classifier.labels == [*CLASSES, BACKGROUND_LABEL]
    assert classifier.reject_class == len(CLASSES)
    assert classifier.preprocessing.input_size == (227, 227)
    assert classifier.window == 0                                   # the whole frame
    assert resolve_path(MODEL).stat().st_size < 2 * 1024 * 1024     # small for the repo


def test_beats_chance_on_fresh_renders(classifier, views) -> None:
    probs = classifier.classify([v.rgb for v in views])
    labels = np.array([v.label for v in views])
    accuracy = float((probs.argmax(axis=1) == labels).mean())        # background: wrong
    chance = 1.0 / (classifier.num_classes - 1)                      # 0.14 (7 objects)
    assert accuracy >= 0.6, f'top-1 accuracy {accuracy:.2f} on {len(views)} views'
    top2 = np.argsort(-probs, axis=1)[:, :2]
    assert (top2 == labels[:, None]).any(axis=1).mean() >= 0.8
    assert accuracy > 4 * chance


@pytest.mark.slow
def test_saliency_boxes_land_on_the_object(classifier, views) -> None:
    hits = 0
    for view in views:
        (box,) = localise(classifier, view.rgb, [view.label], threshold=0.7)
        cu, cv = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
        x0, y0, x1, y1 = view.box
        pad = 15                                                   # px of 640x480
        hits += x0 - pad <= cu <= x1 + pad and y0 - pad <= cv <= y1 + pad
    # a box centre dropped at random lands in (padded) object boxes ~10 % of the time
    assert hits >= 0.75 * len(views), f'{hits} of {len(views)} saliency boxes on the object'


def test_says_background_on_a_wall_and_reports_no_object_there(classifier, wall_view) -> None:
    from foveation_node.training.background_views import object_distance
    view, fixation = wall_view            # conftest: the wall the demo once stared at

    fov = Foveator(640, 480, 5, 100.0)
    assert object_distance(view.extents, *fixation) > 150    # wall, objects below
    probs = classifier.classify(fov.foveate(view.rgb, fixation))[0]
    assert classifier.labels[int(probs.argmax())] == BACKGROUND_LABEL, probs.round(2)
    # two passes from the wall: whatever pass 2 reports lies on an object (its fovea moved to
    # one of the table's objects), never on the wall
    res = two_pass(classifier, view.rgb, fixation, fov.foveate)
    for d in res.second:
        assert d.label != BACKGROUND_LABEL
        assert object_distance(view.extents, *d.centre) <= 10, (d.label, d.score, d.centre)
    # a synthetic plain wall (uniform grey, as the room's walls and ceiling): nothing at all
    plain = np.full((480, 640, 3), 175, np.uint8)
    probs = classifier.classify(fov.foveate(plain, (319.5, 239.5)))[0]
    assert classifier.labels[int(probs.argmax())] == BACKGROUND_LABEL, probs.round(2)
    assert two_pass(classifier, plain, (319.5, 239.5), fov.foveate).second == []


def test_objects_are_rarely_rejected_as_background(classifier, views) -> None:
    probs = classifier.classify([v.rgb for v in views])
    rejected = float((probs.argmax(axis=1) == classifier.reject_class).mean())
    assert rejected <= 0.10, f'{rejected:.2f} of {len(views)} single-object views rejected'

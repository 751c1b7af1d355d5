"""The packaged recognition model on freshly rendered held-out views (a seed used neither for
training nor for the training's held-out set): it beats chance by a wide margin, and its
saliency boxes land on the rendered object."""

from __future__ import annotations

import numpy as np
import pytest

from foveation_node.core.recognition import Classifier, localise
from foveation_node.node import DEFAULT_LABELS, DEFAULT_MODEL, resolve_path

pytest.importorskip('mujoco')
render_mod = pytest.importorskip('vizzy_sim_bridge.core.render')

PER_CLASS = 5


@pytest.fixture(scope='module')
def views():
    from foveation_node.training.object_views import CLASSES, ObjectViews
    try:
        with ObjectViews(640, 480, seed=7) as ov:
            return ov.dataset(PER_CLASS * len(CLASSES), seed=9001)
    except render_mod.RendererUnavailable as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope='module')
def classifier():
    return Classifier(resolve_path(DEFAULT_MODEL), resolve_path(DEFAULT_LABELS))


def test_the_packaged_model_loads_with_its_preprocessing(classifier) -> None:
    from foveation_node.training.object_views import CLASSES
    assert classifier.labels == list(CLASSES)
    assert classifier.preprocessing.input_size == (227, 227)
    assert resolve_path(DEFAULT_MODEL).stat().st_size < 2 * 1024 * 1024     # small for the repo


def test_beats_chance_on_fresh_renders(classifier, views) -> None:
    probs = classifier.classify([v.rgb for v in views])
    labels = np.array([v.label for v in views])
    accuracy = float((probs.argmax(axis=1) == labels).mean())
    chance = 1.0 / classifier.num_classes                            # 0.14
    assert accuracy >= 0.6, f'top-1 accuracy {accuracy:.2f} on {len(views)} views'
    top2 = np.argsort(-probs, axis=1)[:, :2]
    assert (top2 == labels[:, None]).any(axis=1).mean() >= 0.8
    assert accuracy > 4 * chance


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

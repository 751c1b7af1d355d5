"""Rendered tabletop views (core.tabletop_views) and the node's default model on them: the ground
truth is where the objects are, and two-pass recognition names the object under its box well
above chance on scenes used neither in training nor in the experiment."""

from __future__ import annotations

import numpy as np
import pytest

from foveation_node.training.tabletop_views import TableObject, object_at
from vizzy_runtime.testing import no_renderer

pytest.importorskip('mujoco')
render_mod = pytest.importorskip('vizzy_sim_bridge.core.render')

SEEDS = (900, 901, 902, 903)          # experiment: 500-519; training: >= 10000
REJECTED_AT_OBJECTS = 0.10            # fixed after the model's held-out figures (docs)


def _obj(label: int, box: tuple[int, int, int, int], visible: bool = True) -> TableObject:
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
    return TableObject(label, f'o{label}', box, centre, 1.0, visible)


def test_object_at_prefers_visible_boxes_holding_the_point() -> None:
    big = _obj(0, (0, 0, 200, 160))
    small = _obj(1, (90, 90, 130, 130))
    hidden = _obj(2, (95, 95, 105, 105), visible=False)
    far = _obj(3, (400, 400, 420, 420))
    objects = [big, small, hidden, far]
    assert object_at(objects, 100, 100) is small      # inside both: the nearer centre
    assert object_at(objects, 20, 20) is big
    assert object_at(objects, 300, 300) is far        # in no box: the nearest centre
    assert object_at([], 1, 1) is None


@pytest.fixture(scope='module')
def views():
    from foveation_node.training.tabletop_views import DEFAULT_JOINTS, TabletopViews
    try:
        with TabletopViews() as tv:
            return [tv.view(s, DEFAULT_JOINTS) for s in SEEDS]
    except render_mod.RendererUnavailable as exc:
        no_renderer(str(exc))


def test_ground_truth_boxes_hold_the_objects(views) -> None:
    for view in views:
        assert view.rgb.shape == (480, 640, 3)
        visible = [o for o in view.objects if o.visible]
        assert len(visible) >= 5                       # a cluttered table in view
        for o in view.objects:
            x0, y0, x1, y1 = o.box
            assert x0 <= o.centre[0] <= x1 and y0 <= o.centre[1] <= y1
            assert 0.2 < o.depth < 3.0
        # the table's objects differ from the wall behind them: the boxes are not background
        inside = np.concatenate([view.rgb[o.box[1]:o.box[3] + 1, o.box[0]:o.box[2] + 1]
                                 .reshape(-1, 3) for o in visible])
        assert inside.std() > 10


@pytest.mark.slow
def test_two_pass_names_the_object_under_its_box(views) -> None:
    from foveation_node.core.foveation import Foveator
    from foveation_node.core.recognition import Classifier, two_pass
    from foveation_node.node import DEFAULT_LABELS, DEFAULT_MODEL, resolve_path

    clf = Classifier(resolve_path(DEFAULT_MODEL), resolve_path(DEFAULT_LABELS))
    fov = Foveator(640, 480, 5, 100.0)
    rng = np.random.default_rng(0)
    right, cases = 0, 0
    for view in views:
        for fix in [(319.5, 239.5)] + [tuple(rng.uniform((0, 0), (639, 479))) for _ in range(3)]:
            second = two_pass(clf, view.rgb, fix, fov.foveate, top_k=5, threshold=0.7).second
            cases += 1
            if not second:                 # every candidate rejected as background: wrong
                continue
            best = second[0]
            right += best.class_id == object_at(view.objects, *best.centre).label
    # chance: 1/7 = 0.14 (always the commonest class here: ~0.3); the model trained on single
    # objects only got 0.30 on the experiment's scenes
    assert right / cases >= 0.4, f'{right} of {cases} final labels name the object under the box'


def test_objects_on_the_table_are_seldom_rejected_as_background(views) -> None:
    from foveation_node.core.foveation import Foveator
    from foveation_node.core.recognition import Classifier
    from foveation_node.node import DEFAULT_LABELS, DEFAULT_MODEL, resolve_path

    clf = Classifier(resolve_path(DEFAULT_MODEL), resolve_path(DEFAULT_LABELS))
    fov = Foveator(640, 480, 5, 100.0)
    fixated = [(view, o.centre) for view in views for o in view.objects if o.visible]
    images = [fov.foveate(view.rgb, centre) for view, centre in fixated]
    # a window model sees the window at each fixation; a whole-frame model ignores the centres
    top1 = clf.classify(images, [centre for _, centre in fixated]).argmax(axis=1)
    rejected = float((top1 == clf.reject_class).mean())
    assert rejected <= REJECTED_AT_OBJECTS, f'{rejected:.2f} of {len(images)} object fixations'

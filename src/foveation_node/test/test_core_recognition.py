"""core.recognition: model loading and its errors, saliency boxes, the two passes of Fig. 2.5.

All on the stub colour-detector model of conftest.py (no training, no rendering).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import torch

from foveation_node.core.foveation import Foveator
from foveation_node.core.recognition import (
    Classifier,
    Detection,
    ModelError,
    load_preprocessing,
    merge_second_pass,
    saccade_target,
    saliency_box,
    two_pass,
)
from vizzy_vision.rays import back_project

W, H = 640, 480


def _image_with_patches(patches: dict[tuple[int, int], tuple[int, int, int]],
                        half: int = 20) -> np.ndarray:
    """A dark grey image with square colour patches {(u, v) centre: rgb}."""
    img = np.full((H, W, 3), 40, np.uint8)
    for (u, v), rgb in patches.items():
        img[v - half:v + half, u - half:u + half] = rgb
    return img


def test_bad_model_files_are_refused_with_the_reason(tmp_path, stub_model) -> None:
    model, labels = stub_model
    garbage = tmp_path / 'garbage.pt'
    garbage.write_bytes(b'not a torchscript archive')
    with pytest.raises(ModelError, match='cannot load TorchScript model'):
        Classifier(garbage, labels)
    with pytest.raises(ModelError, match='cannot load'):
        Classifier(tmp_path / 'missing.pt', labels)
    four = tmp_path / 'four.labels'
    four.write_text('a\nb\nc\nd\n')
    with pytest.raises(ModelError, match=r'outputs \(1, 3\).*has 4 labels'):
        Classifier(model, four)
    empty = tmp_path / 'empty.labels'
    empty.write_text('\n  \n')
    with pytest.raises(ModelError, match='no labels'):
        Classifier(model, empty)
    with pytest.raises(ModelError, match='cannot read labels'):
        Classifier(model, tmp_path / 'missing.labels')
    # a model that does not take images
    with warnings.catch_warnings():      # torch >= 2.9 deprecates TorchScript (tests only)
        warnings.simplefilter('ignore', DeprecationWarning)
        torch.jit.script(torch.nn.Linear(4, 3)).save(str(tmp_path / 'linear.pt'))
    with pytest.raises(ModelError, match='fails on a 1x3x227x227 input'):
        Classifier(tmp_path / 'linear.pt', labels)
    Classifier(model, labels)                               # the good pair loads


def test_preprocessing_json(tmp_path, stub_model) -> None:
    model, labels = stub_model
    assert Classifier(model, labels).preprocessing.input_size == (227, 227)   # no json: ImageNet
    model.with_suffix('.json').write_text(json.dumps(
        {'input_size': [96, 64], 'mean': [0.5, 0.5, 0.5], 'std': [0.25, 0.25, 0.25]}))
    clf = Classifier(model, labels)
    assert clf.preprocessing.input_size == (96, 64)
    x = clf.preprocess(np.full((H, W, 3), 255, np.uint8))
    assert x.shape == (1, 3, 64, 96) and torch.allclose(x, torch.full_like(x, 2.0))
    bad = tmp_path / 'bad.json'
    bad.write_text('{"input_size": [3]}')
    with pytest.raises(ModelError, match='input_size'):
        load_preprocessing(bad)


def test_classify_and_saliency_box_land_on_the_object(stub_model) -> None:
    clf = Classifier(*stub_model)
    img = _image_with_patches({(500, 120): (230, 30, 30), (150, 380): (30, 200, 30)})
    probs = clf.classify(img)[0]
    assert probs.argmax() == 0 and probs.sum() == pytest.approx(1.0, abs=1e-5)
    maps = clf.saliency(img, [0, 1])
    assert maps.shape == (2, 227, 227) and maps.max() == pytest.approx(1.0)
    for k, (u, v) in enumerate(((500, 120), (150, 380))):
        x0, y0, x1, y1 = clf.box_to_image(saliency_box(maps[k], 0.7), W, H)
        # the saliency is the 5x5 window (in 227 px: 14 x 11 image px) on the patch
        assert u - 20 - 14 <= x0 <= x1 <= u + 20 + 14 and v - 20 - 11 <= y0 <= y1 <= v + 20 + 11
        assert x1 - x0 < 40 and y1 - y0 < 40


def test_one_image_s_saliency_from_one_forward_pass_matches_the_batched_maps(stub_model) -> None:
    # one image, several classes: one forward pass and a backward pass per class, the maps the
    # batched pass over copies of the image gives (to float rounding), classify's probabilities
    clf = Classifier(*stub_model)
    img = _image_with_patches({(500, 120): (230, 30, 30), (150, 380): (30, 200, 30)})
    forwards: list[int] = []
    real_model = clf.model

    def counted(x: torch.Tensor) -> torch.Tensor:
        forwards.append(x.shape[0])
        return real_model(x)

    clf.model = counted
    one = clf.saliency(img, [0, 1, 2])
    assert forwards == [1]
    batched = clf.saliency([img, img, img], [0, 1, 2])
    np.testing.assert_allclose(one, batched, atol=1e-5)
    probs, maps = clf.classify_with_saliency(img, None, lambda p: list(np.argsort(-p)[:2]))
    np.testing.assert_array_equal(probs, clf.classify(img)[0])
    np.testing.assert_allclose(maps, batched[np.argsort(-probs)[:2]], atol=1e-5)
    assert clf.classify_with_saliency(img, None, lambda p: [])[1].shape == (0, 227, 227)


def test_saliency_box_thresholds_relative_to_the_peak() -> None:
    m = np.zeros((10, 20))
    m[2, 3], m[7, 15], m[5, 9] = 1.0, 0.8, 0.5
    assert saliency_box(m, 0.7) == (3, 2, 15, 7)
    assert saliency_box(m, 0.9) == (3, 2, 3, 2)
    assert saliency_box(m, 0.4) == (3, 2, 15, 7)
    assert saliency_box(np.zeros((4, 4)), 0.7) == (0, 0, 3, 3)     # flat: everything


def test_merge_keeps_the_best_non_repeated_labels() -> None:
    probs = np.array([[0.60, 0.30, 0.05, 0.05],     # fixation 0: class 0 best
                      [0.70, 0.05, 0.20, 0.05],     # fixation 1: class 0 again, higher
                      [0.10, 0.10, 0.10, 0.70]])    # fixation 2: class 3
    chosen = merge_second_pass(probs, 3)
    assert [c for c, _, _ in chosen] == [0, 3, 1]
    assert chosen[0] == (0, 1, pytest.approx(0.70))   # the higher of the two class-0 scores
    assert len({c for c, _, _ in merge_second_pass(probs, 4)}) == 4


def test_two_pass_foveates_at_the_box_centres_and_batches_pass_two(stub_model) -> None:
    clf = Classifier(*stub_model)
    img = _image_with_patches({(560, 90): (230, 30, 30), (90, 400): (30, 30, 230)})
    calls: list[tuple[float, float]] = []
    foveator = Foveator(W, H, 5, 30.0)

    def foveate(image: np.ndarray, fixation: tuple[float, float]) -> np.ndarray:
        calls.append(fixation)
        return foveator.foveate(image, fixation)

    forwards = []
    real_model = clf.model
    clf.model = lambda x: forwards.append(x.shape[0]) or real_model(x)   # count batch sizes
    result = two_pass(clf, img, (319.5, 239.5), foveate, top_k=3, threshold=0.7)
    assert calls[0] == (319.5, 239.5) and len(calls) == 4
    assert [d.pass_index for d in result.first] == [0, 0, 0]
    assert calls[1:] == [d.centre for d in result.first]
    # pass 1: one forward pass of its image gives its probabilities and (a backward pass per
    # class) 3 saliency maps; pass 2: 3 images in one batch, then the 3 chosen labels'
    # saliency in one batch
    assert forwards == [1, 3, 3]
    labels = [d.label for d in result.second]
    assert len(labels) == len(set(labels)) == 3 and {d.pass_index for d in result.second} == {1}
    assert [d.score for d in result.second] == sorted((d.score for d in result.second),
                                                      reverse=True)
    red = next(d for d in result.first if d.label == 'red')
    assert abs(red.centre[0] - 560) < 40 and abs(red.centre[1] - 90) < 40
    best = result.second[0]
    assert best.label in ('red', 'blue') and best.score > 0.5
    # the best pass-2 label was found with the fovea on its own patch
    patch = (560, 90) if best.label == 'red' else (90, 400)
    assert abs(best.fixation[0] - patch[0]) < 40 and abs(best.fixation[1] - patch[1]) < 40


def test_back_projection_and_saccade_choice() -> None:
    k = [400.0, 0.0, 320.0, 0.0, 400.0, 240.0, 0.0, 0.0, 1.0]
    assert back_project(320.0, 240.0, k, 2.0) == pytest.approx((0.0, 0.0, 2.0))
    x, y, z = back_project(720.0, 240.0, k, 1.0)             # 45 deg to the right
    assert (x, y, z) == pytest.approx((2 ** -0.5, 0.0, 2 ** -0.5))
    far = Detection(0, 'a', 0.9, (600, 100, 620, 120), (0.0, 0.0), 1)
    near = Detection(1, 'b', 0.95, (315, 235, 325, 245), (0.0, 0.0), 1)
    assert saccade_target([far], (320.0, 240.0), 0.3, 20.0) is far
    assert saccade_target([far], (320.0, 240.0), 0.95, 20.0) is None     # too unsure
    assert saccade_target([near, far], (320.0, 240.0), 0.3, 20.0) is None  # best is centred
    assert saccade_target([], (320.0, 240.0), 0.0, 0.0) is None

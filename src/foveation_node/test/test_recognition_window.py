"""Window models: the network sees the square around each fixation, not the whole image; and
grid_recognition, their uniform-resolution counterpart over the whole frame."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from foveation_node.core.recognition import (
    Classifier,
    ModelError,
    crop_window,
    grid_centres,
    grid_recognition,
    two_pass,
    window_region,
)

W, H = 320, 240
RED, GREEN = (60, 60), (250, 180)


def _window_model(stub_model: tuple[Path, Path], window: int = 64,
                  size: int = 32) -> Classifier:
    model, labels = stub_model
    model.with_suffix('.json').write_text(json.dumps(
        {'input_size': [size, size], 'mean': [0.5] * 3, 'std': [0.25] * 3, 'window': window}))
    return Classifier(model, labels)


def _scene() -> np.ndarray:
    """Grey, a red patch at RED and a green one at GREEN (12 x 12 px each)."""
    img = np.full((H, W, 3), 128, np.uint8)
    for (u, v), colour in ((RED, (230, 20, 20)), (GREEN, (20, 230, 20))):
        img[v - 6:v + 6, u - 6:u + 6] = colour
    return img


def test_crop_window_centres_and_mirrors_at_the_border() -> None:
    img = np.arange(20 * 30 * 3, dtype=np.int32).reshape(20, 30, 3).astype(np.uint8)
    inner = crop_window(img, (15.0, 10.0), 8)
    np.testing.assert_array_equal(inner, img[6:14, 11:19])
    corner = crop_window(img, (0.0, 0.0), 8)           # mirrored (reflect 101) beyond the edge
    assert corner.shape == (8, 8, 3)
    np.testing.assert_array_equal(corner[4:, 4:], img[:4, :4])
    np.testing.assert_array_equal(corner[3, 4:], img[1, :4])
    with pytest.raises(ValueError, match='outside'):
        crop_window(img, (100.0, 10.0), 8)


def test_a_window_model_names_what_lies_at_each_fixation(stub_model) -> None:
    clf = _window_model(stub_model)
    assert clf.window == 64
    img = _scene()
    probs = clf.classify(img, [RED, GREEN, (160.0, 30.0)])
    assert [clf.labels[int(np.argmax(p))] for p in probs[:2]] == ['red', 'green']
    assert probs[2, 2] == pytest.approx(1 / 3, abs=0.05)     # grey only: no colour wins
    # the whole-image stub sees both patches wherever it "looks": no blue, two colours
    whole = Classifier(*stub_model, preprocessing_path=stub_model[0].with_suffix('.none'))
    p = whole.classify(img)[0]
    assert min(p[0], p[1]) > p[2]


def test_two_pass_with_a_window_model_boxes_the_fixated_object_in_image_pixels(
        stub_model) -> None:
    clf = _window_model(stub_model)
    img = _scene()
    result = two_pass(clf, img, (70.0, 52.0), lambda im, fix: im, top_k=1)
    [red] = result.first
    assert red.label == 'red'
    x0, y0, x1, y1 = red.box                  # the saliency box, back in image pixels
    assert x0 <= RED[0] <= x1 and y0 <= RED[1] <= y1 and x1 - x0 < 40
    assert result.second[0].label == 'red' and result.second[0].fixation == red.centre


def test_two_pass_given_its_first_image_and_a_batch_foveation_finds_the_same(
        stub_model) -> None:
    from foveation_node.core.foveation import Foveator
    clf = _window_model(stub_model)
    img = _scene()
    foveator = Foveator(W, H, levels=4, f0=40.0)
    fixation = (70.0, 52.0)
    calls: list[tuple[float, float]] = []

    def counted(im: np.ndarray, fix: tuple[float, float]) -> np.ndarray:
        calls.append(fix)
        return foveator.foveate(im, fix)

    plain = two_pass(clf, img, fixation, counted, top_k=2)
    assert len(calls) == 1 + 2                  # pass 1, then each of pass 1's two boxes
    calls.clear()
    asked = []

    def many(image: np.ndarray, fixations: list[tuple[float, float]],
             regions: list[tuple[int, int, int, int]] | None = None) -> list[np.ndarray]:
        asked.append(regions)
        return foveator.foveate_many(image, fixations, regions)

    shared = two_pass(clf, img, fixation, counted, top_k=2,
                      first_image=foveator.foveate(img, fixation), foveate_many=many)
    assert calls == []                          # nothing foveated one image at a time
    # only the window each pass-2 image is classified in is foveated
    assert asked == [[window_region(d.centre, 64) for d in plain.first]]
    assert shared.first == plain.first and shared.second == plain.second
    np.testing.assert_array_equal(shared.probs_second, plain.probs_second)
    with pytest.raises(ValueError, match='first_image'):
        two_pass(clf, img, fixation, counted, first_image=img[:10])


def test_grid_recognition_covers_the_frame_and_finds_both_patches(stub_model) -> None:
    clf = _window_model(stub_model)
    centres = grid_centres(W, H, 40)
    assert len(centres) == 8 * 6 and centres[0] == (19.5, 19.5)
    detections, probs = grid_recognition(clf, _scene(), 40)
    assert probs.shape == (48, 3)
    found = {d.label: d for d in detections if d.score > 0.5}
    for label, (u, v) in (('red', RED), ('green', GREEN)):
        d = found[label]
        assert abs(d.fixation[0] - u) <= 40 and abs(d.fixation[1] - v) <= 40
        assert d.pass_index == 0 and d.box[2] - d.box[0] <= 63
    whole = Classifier(*stub_model, preprocessing_path=stub_model[0].with_suffix('.none'))
    with pytest.raises(ValueError, match='window model'):
        grid_recognition(whole, _scene(), 40)


def test_a_bad_window_is_refused_in_one_line(stub_model) -> None:
    model, labels = stub_model
    model.with_suffix('.json').write_text(json.dumps({'window': 3}))
    with pytest.raises(ModelError, match='window must be'):
        Classifier(model, labels)


@pytest.mark.slow
def test_the_shared_training_epoch_learns_a_separable_toy_set() -> None:
    """train_epoch (both trainers' loop): red vs green 8x8 images, a linear model, two epochs."""
    import torch
    from torch import nn

    from foveation_node.training.train_classifier import train_epoch
    rng = np.random.default_rng(0)
    x = np.zeros((64, 8, 8, 3), np.uint8)
    y = np.arange(64) % 2
    x[y == 0, :, :, 0] = 200
    x[y == 1, :, :, 1] = 200
    model = nn.Sequential(nn.Flatten(), nn.Linear(8 * 8 * 3, 2))
    opt = torch.optim.SGD(model.parameters(), lr=0.05)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: 1.0)

    def to_input(batch: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(batch)).permute(0, 3, 1, 2).float() / 255

    losses = [train_epoch(model, opt, sched, x, y, rng.permutation(64), 8, to_input, rng,
                          'toy', sort_batches=bool(e))[0] for e in range(3)]
    assert losses[-1] < losses[0]
    with torch.no_grad():
        assert (model(to_input(x)).argmax(1).numpy() == y).all()

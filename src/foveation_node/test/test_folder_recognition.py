"""core.folder_recognition and the recognize_folder CLI: folder formats, ranks, two passes,
localisation, and the CLI's output and one-line errors. On the stub colour-detector model of
conftest.py and small images written by the test (no real photographs, no ImageNet network)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from foveation_node import recognize_folder
from foveation_node.core.folder_recognition import (
    FolderError,
    Foveators,
    evaluate_image,
    fit,
    grid_fixations,
    iou,
    load_folder,
    localisation_hits,
    paste,
    read_rgb,
    top_errors,
    true_rank,
)
from foveation_node.core.recognition import Classifier

LABELS = ['red', 'green', 'blue']
COLOURS = {'red': (230, 20, 20), 'green': (20, 200, 20), 'blue': (20, 20, 230)}


def _write(path: Path, rgb: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    return path


def _patch_image(colour: str, w: int = 120, h: int = 90) -> np.ndarray:
    img = np.full((h, w, 3), 60, np.uint8)
    img[h // 2 - 12:h // 2 + 12, w // 2 - 12:w // 2 + 12] = COLOURS[colour]
    return img


def _decoy_scene() -> np.ndarray:
    """227 x 227: a small bright red patch in a corner and a large dull green one: red wins
    unfoveated or with the fovea on it; a small fovea at the centre blurs the red patch away."""
    img = np.full((227, 227, 3), 60, np.uint8)
    img[20:28, 20:28] = (255, 0, 0)
    img[150:200, 150:200] = (60, 140, 60)
    return img


def test_three_folder_formats(tmp_path) -> None:
    # 1. file names: <label>[_anything].<ext>, and WordNet-id-like heads
    names = tmp_path / 'names'
    for i, c in enumerate(LABELS):
        _write(names / f'{c}_{i}.png', _patch_image(c))
    _write(names / 'blue.jpg', _patch_image('blue'))
    (names / 'notes.txt').write_text('ignored: not an image')
    items = load_folder(names, LABELS)
    assert [(p.path.name, p.label) for p in items] == [
        ('blue.jpg', 2), ('blue_2.png', 2), ('green_1.png', 1), ('red_0.png', 0)]
    wnid = ['n01440764_tench', 'n01443537_goldfish']
    _write(tmp_path / 'wn' / 'n01443537_goldfish.JPEG', _patch_image('red'))
    _write(tmp_path / 'wn' / 'n01440764_10029.JPEG', _patch_image('red'))
    assert [p.label for p in load_folder(tmp_path / 'wn', wnid)] == [0, 1]
    # 2. sub-folders per label
    sub = tmp_path / 'sub'
    _write(sub / 'green' / 'a.png', _patch_image('green'))
    _write(sub / 'Blue' / 'b.bmp', _patch_image('blue'))
    assert [p.label for p in load_folder(sub, LABELS)] == [2, 1]
    # 3. CSV (header, comment, optional box) wins over the names
    (names / 'labels.csv').write_text('file,label,x0,y0,x1,y1\n# a comment\n'
                                      'red_0.png,green,1,2,30,40\nblue.jpg,blue\n')
    items = load_folder(names, LABELS)
    assert [(p.path.name, p.label, p.box) for p in items] == [
        ('red_0.png', 1, (1, 2, 30, 40)), ('blue.jpg', 2, None)]


@pytest.mark.parametrize('setup, match', [
    (lambda d: _write(d / 'purple_1.png', _patch_image('red')), r'purple_1\.png.*matches none'),
    (lambda d: (d / 'labels.csv').write_text('x.png,red\n'), r'labels\.csv:1: image .*x\.png'),
    (lambda d: (_write(d / 'a.png', _patch_image('red')),
                (d / 'labels.csv').write_text('a.png,mauve\n')), r"labels\.csv:1: label 'mauve'"),
    (lambda d: (_write(d / 'a.png', _patch_image('red')),
                (d / 'labels.csv').write_text('a.png,red,1,2\n')), r'labels\.csv:1: expected'),
    (lambda d: (_write(d / 'a.png', _patch_image('red')),
                (d / 'labels.csv').write_text('a.png,red,9,2,3,4\n')), r'labels\.csv:1: box'),
    (lambda d: _write(d / 'mauve' / 'a.png', _patch_image('red')), r"folder name 'mauve'"),
    (lambda d: None, 'no images'),
])
def test_folder_errors_name_the_file(tmp_path, setup, match) -> None:
    setup(tmp_path)
    with pytest.raises(FolderError, match=match):
        load_folder(tmp_path, LABELS)


def test_read_fit_grid_iou_ranks(tmp_path) -> None:
    bad = tmp_path / 'bad.png'
    bad.write_bytes(b'not an image')
    with pytest.raises(FolderError, match=r'bad\.png: not an image'):
        read_rgb(bad)
    img = _patch_image('red', 200, 100)
    assert np.array_equal(read_rgb(_write(tmp_path / 'ok.png', img)), img)   # RGB, lossless
    small, box = fit(img, 50, (0, 0, 199, 99))
    assert small.shape == (50, 50, 3) and box == (0, 0, 49, 49)
    assert fit(img, 50, (100, 50, 149, 74))[1] == (25, 25, 37, 37)
    g = grid_fixations(227, 227, 3)
    assert len(g) == 9 and g[4] == (113.0, 113.0)
    assert g[0] == pytest.approx((37.33, 37.33), abs=0.01)
    assert iou((0, 0, 9, 9), (0, 0, 9, 9)) == 1.0
    assert iou((0, 0, 9, 9), (5, 0, 14, 9)) == pytest.approx(50 / 150)
    probs = np.array([[0.1, 0.6, 0.3], [0.5, 0.2, 0.3]])
    assert true_rank(probs, 2).tolist() == [1, 1]
    assert true_rank(probs, 0).tolist() == [2, 0]
    fovs = Foveators(keep=2)
    a = fovs.get(64, 48, 10.0)
    assert fovs.get(64, 48, 10) is a and fovs.get(64, 64, 10.0) is not a
    fovs.get(80, 64, 10.0)
    assert fovs.get(64, 48, 10.0) is not a               # evicted: at most `keep` held
    errs = top_errors(np.array([0, 1, 4, 7, -1]))
    assert errs == {'top1_error': 0.75, 'top5_error': 0.25}
    assert top_errors(np.array([-1])) == {'top1_error': None, 'top5_error': None}


def test_second_pass_recovers_what_a_small_fovea_lost(stub_model) -> None:
    clf = Classifier(*stub_model)
    img = _decoy_scene()
    fix = [(113.0, 113.0), (24.0, 24.0)]              # the centre; on the red patch
    r = evaluate_image(clf, img, 0, [10.0, 50.0], passes=2, fixations=fix).ranks
    assert r.shape == (3, 2, 2)
    assert r[2].tolist() == [[0, 0], [0, 0]]          # unfoveated: red first
    assert r[0, 0, 0] == 2 and r[0, 0, 1] == 0        # f0 10 at the centre: last, then first
    assert r[0, 1].tolist() == [0, 0]                 # fixating the patch: right at once
    assert r[1, 0, 0] == 0                            # f0 50 reaches the patch
    one = evaluate_image(clf, img, 0, [10.0], passes=1, fixations=fix).ranks
    assert one[:, :, 0].tolist() == r[[0, 2], :, 0].tolist() and (one[:, :, 1] == -1).all()


def test_paste_and_localisation(stub_model) -> None:
    clf = Classifier(*stub_model)
    rng = np.random.default_rng(0)
    photo = _patch_image('blue', 100, 100)
    bg = np.zeros((50, 80, 3), np.uint8)
    scene, box = paste(photo, 227, 0.5, rng, background=bg)
    x0, y0, x1, y1 = box
    assert scene.shape == (227, 227, 3) and x1 - x0 == y1 - y0 == 113
    assert np.array_equal(scene[y0:y1 + 1, x0:x1 + 1], fit(photo, 114)[0])
    assert scene.sum() == scene[y0:y1 + 1, x0:x1 + 1].sum()      # black background elsewhere
    with pytest.raises(ValueError, match='scale'):
        paste(photo, 227, 1.5, rng)
    # a 5x5 blue patch alone on the canvas: its saliency box is the stub's 5x5 window on it
    canvas = np.full((227, 227, 3), 60, np.uint8)
    canvas[100:105, 60:65] = COLOURS['blue']
    near = (59, 99, 65, 105)                                     # IoU 25 / 49 with the patch
    hits = localisation_hits(clf, canvas, near, None, (113, 113), [0.5, 0.99])
    assert hits.dtype == bool and hits.tolist() == [True, True]
    assert localisation_hits(clf, canvas, near, 30.0, (62, 102), [0.5]).tolist() == [True]
    assert localisation_hits(clf, canvas, (150, 10, 220, 80), None, (113, 113),
                             [0.5]).tolist() == [False]
    assert localisation_hits(clf, canvas, (58, 98, 66, 106), None, (113, 113),
                             [0.5]).tolist() == [False]               # IoU 25 / 81


def _stub_folder(tmp_path: Path) -> Path:
    folder = tmp_path / 'images'
    for c in LABELS:
        for i in range(2):
            _write(folder / f'{c}_{i}.png', _patch_image(c, 100 + 20 * i, 80))
    return folder


@pytest.mark.slow
def test_cli_reports_errors_and_writes_strict_json(tmp_path, stub_model, capsys) -> None:
    model, labels = stub_model
    folder = _stub_folder(tmp_path)
    out = tmp_path / 'res.json'
    rc = recognize_folder.main([str(folder), '--model', str(model), '--f0', '20', '80',
                                '--grid', '2', '--two-pass', '--json', str(out)])
    stdout = capsys.readouterr().out.strip().splitlines()
    assert rc == 0
    summary = json.loads(stdout[-1])
    assert summary['images'] == 6 and summary['fixations'] == 5 and summary['passes'] == 2
    rows = {str(r['f0_px']): r for r in summary['by_f0']}
    assert set(rows) == {'20.0', '80.0', 'unfoveated'}
    assert rows['unfoveated']['centred']['pass1'] == {'top1_error': 0.0, 'top5_error': 0.0}
    assert rows['80.0']['centred']['pass2']['top1_error'] == 0.0
    assert 'off_centre' in rows['20.0'] and 'off_centre' not in rows['unfoveated']
    saved = json.loads(out.read_text())                   # strict JSON (no NaN) parses back
    assert len(saved['images']) == 6 and saved['images'][0]['unfoveated_top5'][0] == 'blue'
    assert np.array(saved['images'][0]['ranks']).shape == (3, 5, 2)
    # --size 0: each image foveated at its own size (100x80 and 120x80 here)
    assert recognize_folder.main([str(folder), '--model', str(model), '--size', '0',
                                  '--f0', '30']) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary['size_px'] is None
    assert summary['by_f0'][-1]['centred']['pass1']['top1_error'] == 0.0


@pytest.mark.parametrize('args, match', [
    (['{folder}', '--model', '{tmp}/none.pt'], r'none\.pt: model file does not exist'),
    (['{tmp}/nowhere', '--model', '{model}'], r'nowhere: not a folder'),
    (['{folder}', '--model', '{model}', '--f0', '-3'], r'--f0 values must be finite and > 0'),
    (['{folder}', '--model', '{model}', '--size', '8'], r'--size must be 0 or >= 2\^levels'),
    (['{folder}', '--model', '{model}', '--grid', 'x'], r"argument --grid: invalid int"),
    (['{folder}', '--model', '{model}', '--labels', '{tmp}/no.labels'], r'no\.labels: labels'),
    (['{folder}', '--model', '{tmp}/garbage.pt', '--labels', '{labels}'],
     r'cannot load TorchScript model'),
    (['{bad}', '--model', '{model}'], r'red_9\.png: not an image'),
])
def test_cli_bad_input_is_one_line_and_status_2(tmp_path, stub_model, capsys, args,
                                                match) -> None:
    model, labels = stub_model
    folder = _stub_folder(tmp_path)
    bad = tmp_path / 'bad'
    _write(bad / 'red_0.png', _patch_image('red'))
    (bad / 'red_9.png').write_bytes(b'\x89PNG truncated')
    (tmp_path / 'garbage.pt').write_bytes(b'zip?')
    argv = [a.format(folder=folder, tmp=tmp_path, model=model, labels=labels, bad=bad)
            for a in args]
    with pytest.raises(SystemExit) as exc:
        raise SystemExit(recognize_folder.main(argv))
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('recognize_folder: ')
    assert re.search(match, err[0]), err[0]


def test_cli_imagenet_photos_with_the_default_model_say_how_to_get_an_imagenet_one(
        tmp_path, capsys) -> None:
    """No --model: the simulator's network, which knows no ImageNet class; the one-line error
    names the tool that makes an ImageNet model (issue 31)."""
    _write(tmp_path / 'n01484850_great_white_shark.png', _patch_image('red'))
    assert recognize_folder.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'none of the model' in err[0]
    assert 'export_imagenet_classifier' in err[0] and '--model' in err[0]

"""stereo_file: the command-line disparity map of a rectified pair (one JSON line; exit 2 and one
stderr line for bad input)."""

import json
import math
import subprocess
import sys

import cv2
import numpy as np
import pytest

from stereo_ses_node import stereo_file
from stereo_ses_node.core.synthetic import Layer, layered_pair, plane_texture
from vizzy_runtime.testing import scaled

W, H = 256, 192
D_BACK, D_FRONT = 12.0, 28.0


@pytest.fixture(scope='module')
def pair(tmp_path_factory):
    """PNG files of a rectified pair: a background at 12 px, a square at 28 px over the centre."""
    tex = [np.repeat(plane_texture(W, seed=s)[:H, :, None], 3, axis=2) for s in (0, 1)]
    square = np.zeros((H, W), bool)
    square[60:140, 80:180] = True
    left, right, gt, visible = layered_pair([Layer(tex[0], (0.0, 0.0, D_BACK)),
                                             Layer(tex[1], (0.0, 0.0, D_FRONT), square)], W, H,
                                            noise_sd=1.0, seed=0)
    folder = tmp_path_factory.mktemp('pair')
    paths = folder / 'left.png', folder / 'right.png'
    cv2.imwrite(str(paths[0]), left[..., ::-1])
    cv2.imwrite(str(paths[1]), right[..., ::-1])
    return paths, np.where(visible, gt, np.nan), folder


def run(capsys, *args):
    """(exit status, stdout, stderr) of stereo_file with args (argparse errors exit)."""
    try:
        code = stereo_file.main([str(a) for a in args])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize('sensor', ['logpolar', 'cartesian', 'full'])
def test_disparity_map_and_json(pair, capsys, sensor):
    (left, right), truth, folder = pair
    out_path = folder / f'{sensor}.npy'
    code, out, err = run(capsys, left, right, '--sensor', sensor, '--out', out_path, '--n-rf',
                         100)
    assert code == 0 and err == ''
    lines = out.splitlines()
    assert len(lines) == 1
    doc = json.loads(lines[0], parse_constant=lambda c: pytest.fail(f'non-strict JSON: {c}'))
    assert doc['sensor'] == sensor and (doc['width'], doc['height']) == (W, H)
    assert doc['ms'] > 0 and doc['cpu_ms'] >= 0 and doc['stages_ms']
    assert doc['window'] == [0, W // 3] and doc['fixation'] == [(W - 1) / 2, (H - 1) / 2]
    disp = np.load(out_path)
    assert disp.dtype == np.float32 and disp.shape == (H, W)
    assert doc['valid_points'] == int(np.isfinite(disp).sum()) > 0.5 * W * H
    assert np.isnan(disp).any()                          # the left border, occlusions
    # the square (28 px) at the fixation, the background (12 px) around it
    tol = 0.5 if sensor != 'cartesian' else 2.0
    assert abs(np.nanmedian(disp[90:110, 118:138]) - D_FRONT) < tol
    assert abs(np.nanmedian(disp[160:185, 100:200]) - D_BACK) < 2 * tol
    if sensor == 'logpolar':
        assert doc['fovea_radius_px'] == pytest.approx(1 / (2 * math.pi / 100), abs=0.01)
        assert doc['levels'] >= 3 and 'level0' in doc['searched']
        fovea = np.hypot(*np.mgrid[0:H, 0:W][::-1] - np.array([[[127.5]], [[95.5]]])) < 15.9
        err_fovea = np.abs(disp - truth)[fovea]
        assert np.mean(err_fovea <= 2.0) > 0.95


def test_geometry_and_fixation(pair, capsys):
    (left, right), _, _ = pair
    f, b = 400.0, 0.1
    code, out, _ = run(capsys, left, right, '--focal', f, '--baseline', b, '--depth-range', 0.5,
                       20, '--fixation', 60, 170)
    doc = json.loads(out)
    assert code == 0 and doc['window'] == [2, 81]          # f b / 20 m = 2 px, f b / 0.5 m = 80
    assert doc['fixation'] == [60, 170]
    assert doc['fixation_depth_m'] == pytest.approx(f * b / D_BACK, rel=0.03)   # background
    code, out, _ = run(capsys, left, right, '--focal', f, '--baseline', b, '--sensor', 'full')
    assert json.loads(out)['fixation_depth_m'] == pytest.approx(f * b / D_FRONT, rel=0.03)
    code, out, _ = run(capsys, left, right, '--disparity-range', -8, 40)
    assert code == 0 and json.loads(out)['window'] == [-8, 40]


def test_bad_input_is_one_line_and_status_2(pair, capsys, tmp_path):
    (left, right), _, _ = pair
    text = tmp_path / 'notes.png'
    text.write_text('not an image')
    small = tmp_path / 'small.png'
    cv2.imwrite(str(small), np.zeros((100, 120, 3), np.uint8))
    cases = [
        ((tmp_path / 'missing.png', right), 'missing.png: no such file'),
        ((text, right), 'notes.png: not an image'),
        ((left, small), 'small.png: 120x100 differs'),
        ((left, right, '--focal', 300), '--focal and --baseline go together'),
        ((left, right, '--focal', -3, '--baseline', 0.1), '--focal must be a positive'),
        ((left, right, '--depth-range', 1, 2), '--depth-range needs --focal'),
        ((left, right, '--focal', 300, '--baseline', 0.1, '--depth-range', 2, 1), 'NEAR < FAR'),
        ((left, right, '--disparity-range', 10, 5), 'MIN < MAX'),
        ((left, right, '--fixation', 300, 10), 'outside the 256x192 image'),
        ((left, right, '--out', tmp_path / 'no' / 'd.npy'), 'd.npy: its folder does not exist'),
        ((left, right, '--out', tmp_path), 'is a folder'),
        ((left, right, '--max-level', 9), '--max-level must be in'),
        ((left, right, '--n-rf', 4), '--n-rf must be in'),
        ((left, right, '--sensor', 'fisheye'), "invalid choice: 'fisheye'"),
        ((left,), 'the following arguments are required: right'),
    ]
    for args, expected in cases:
        code, out, err = run(capsys, *args)
        assert code == 2, args
        assert out == '' and len(err.strip().splitlines()) == 1, (args, err)
        assert err.startswith('stereo_file: ') and expected in err, (args, err)


def test_console_entry_point_reports_without_traceback(tmp_path):
    proc = subprocess.run([sys.executable, '-m', 'stereo_ses_node.stereo_file',
                           str(tmp_path / 'a.png'), str(tmp_path / 'b.png')],
                          capture_output=True, text=True, timeout=scaled(120))
    assert proc.returncode == 2 and proc.stdout == ''
    assert proc.stderr.strip() == f'stereo_file: {tmp_path / "a.png"}: no such file'

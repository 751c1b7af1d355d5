"""The detect_file command-line tool on small synthetic .ply and .pcd files: its JSON, the table it
picks in a room with default options, its CPU times, and one line + exit 2 for every bad file."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

from cylinder_detector_node import detect_file
from cylinder_detector_node.core.scene import make_room, make_tabletop

STAGES = ['load', 'downsample', 'plane', 'clusters', 'classification', 'fitting', 'total']


def write_ply(path: Path, pts: np.ndarray, ascii: bool = False) -> None:
    pts = pts.reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)),
                             write_ascii=ascii)


def write_pcd(path: Path, cloud: np.ndarray, data: str = 'binary') -> None:
    """An organized (H, W, 3) cloud as a PCD v0.7 file (binary or ascii), NaN kept."""
    h, w, _ = cloud.shape
    head = (f'# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n'
            f'WIDTH {w}\nHEIGHT {h}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {w * h}\nDATA {data}\n')
    xyz = cloud.astype('<f4').reshape(-1, 3)
    body = xyz.tobytes() if data == 'binary' else ''.join(
        f'{x:.5f} {y:.5f} {z:.5f}\n' for x, y, z in xyz).encode()
    path.write_bytes(head.encode() + body)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    try:
        code = detect_file.main([str(a) for a in argv])
    except SystemExit as exc:          # argparse's errors (one line: detect_file.OneLineParser)
        code = exc.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_json_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = make_tabletop(np.random.default_rng(0), n_cylinders=1, n_distractors=0, width=320,
                          height=240)
    f = tmp_path / 'one.ply'
    write_ply(f, scene.cloud)
    code, out, err = run(capsys, f, '--plot', tmp_path / 'one.png')
    assert code == 0
    res = json.loads(out)
    assert len(res['cylinders']) == 1
    c = res['cylinders'][0]
    assert set(c) >= {'centre', 'axis', 'radius', 'height', 'confidence',
                      'axis_to_table_normal_deg'}
    base, r, h = scene.cylinders[0]
    assert abs(c['radius'] - r) < 0.3 * r
    assert np.linalg.norm(np.array(c['centre']) - base) < h
    assert c['axis_to_table_normal_deg'] < 10
    assert (tmp_path / 'one.png').stat().st_size > 0
    # CPU time per stage, wall time named as such; the classifier was off (no image): 0, "skipped"
    assert list(res['cpu_ms']) == STAGES and list(res['wall_ms']) == STAGES
    assert res['cpu_ms']['classification'] == 0.0 and res['classifier'] is False
    assert res['cpu_ms']['total'] >= res['cpu_ms']['load'] + res['cpu_ms']['fitting'] > 0
    assert 'timings_ms' not in res
    line = err.strip().splitlines()[-1]
    assert 'CPU ms: load' in line and 'classification skipped' in line and 'wall total' in line


def test_room_with_default_options_finds_the_tabletop_cylinders(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A room (back wall the largest plane, clutter on the floor 2 m away) as an organized binary
    .pcd: with default options the table is found and its cylinders, nothing near the wall."""
    scene = make_room(np.random.default_rng(1), width=320, height=240)
    f = tmp_path / 'room.pcd'
    write_pcd(f, scene.cloud)
    code, out, _ = run(capsys, f)
    assert code == 0
    res = json.loads(out)
    assert res['organized'] is True
    assert res['table']['height_m'] == pytest.approx(scene.table_height, abs=0.01)
    assert np.array(res['table']['normal']) @ scene.up > np.cos(np.radians(2.0))
    assert len(res['cylinders']) >= 2
    assert max(c['range_m'] for c in res['cylinders']) < 1.6       # the clutter is 2.1 m away
    for base, _r, h in scene.cylinders:
        centre = base + 0.5 * h * scene.up
        c = min(res['cylinders'], key=lambda c: np.linalg.norm(np.array(c['centre']) - centre))
        assert np.linalg.norm(np.array(c['centre']) - centre) < 0.06
        assert c['axis_to_table_normal_deg'] < 6.0
    # the up direction matters: a cloud in a z-up frame needs --up 0,0,1, and with it the same table
    z_up = tmp_path / 'room_zup.ply'
    r = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])        # optical (y down) -> z up
    write_ply(z_up, scene.cloud.reshape(-1, 3) @ r.T)
    code, out, _ = run(capsys, z_up, '--up', '0,0,1', '--up-tolerance', '45', '--no-classifier')
    assert code == 0
    assert json.loads(out)['table']['height_m'] == pytest.approx(scene.table_height, abs=0.01)


def test_bad_files_end_with_one_line_and_exit_2(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    cloud = np.random.default_rng(3).uniform(-1, 1, (12, 10, 3)).astype(np.float32)
    good_bin, good_ascii = tmp_path / 'good.pcd', tmp_path / 'good_ascii.pcd'
    write_pcd(good_bin, cloud)
    write_pcd(good_ascii, cloud, 'ascii')
    ply_bin, ply_ascii = tmp_path / 'good.ply', tmp_path / 'good_ascii.ply'
    write_ply(ply_bin, cloud)
    write_ply(ply_ascii, cloud, ascii=True)
    for f in (good_bin, good_ascii, ply_bin, ply_ascii):       # the intact files are read
        code, out, _ = run(capsys, f, '--no-classifier')
        assert code == 0 and json.loads(out)['n_points'] == 120, f
    compressed = tmp_path / 'compressed.pcd'
    o3d.io.write_point_cloud(str(compressed), o3d.geometry.PointCloud(
        o3d.utility.Vector3dVector(cloud.reshape(-1, 3).astype(np.float64))), compressed=True)

    def cut(src: Path, keep: float) -> Path:
        dst = tmp_path / f'cut_{keep}_{src.name}'
        data = src.read_bytes()
        dst.write_bytes(data[:int(len(data) * keep)])
        return dst

    header = ('ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n'
              'property float z\nend_header\n')
    no_vertices = tmp_path / 'no_vertices.ply'
    no_vertices.write_text(header.format(0))
    no_points = tmp_path / 'no_points.pcd'
    no_points.write_text('VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 0\n'
                         'HEIGHT 1\nPOINTS 0\nDATA ascii\n')
    no_xyz = tmp_path / 'no_xyz.pcd'
    no_xyz.write_text('VERSION 0.7\nFIELDS a b\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\n'
                      'POINTS 1\nDATA ascii\n1 2\n')
    mismatch = tmp_path / 'mismatch.pcd'
    mismatch.write_text('VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\n'
                        'HEIGHT 2\nPOINTS 5\nDATA ascii\n' + '1 2 3\n' * 5)
    words = tmp_path / 'words.ply'
    words.write_text(header.format(2) + '1 2 3\nfour five six\n')
    garbage_pcd, garbage_ply = tmp_path / 'garbage.pcd', tmp_path / 'garbage.ply'
    garbage_pcd.write_bytes(os.urandom(4096))
    garbage_ply.write_bytes(b'ply\n' + os.urandom(4096))
    renamed = tmp_path / 'renamed.pcd'              # a text file with the right suffix
    renamed.write_text('hello world\n')
    txt = tmp_path / 'cloud.txt'
    txt.write_text('1 2 3\n')
    cases = {
        tmp_path / 'missing.pcd': 'no such file',
        tmp_path: 'is a directory',
        txt: '.pcd or .ply',
        renamed: 'not a PCD file',
        garbage_pcd: 'not a PCD file',
        garbage_ply: 'PLY',
        cut(good_bin, 0.5): 'truncated',
        cut(good_ascii, 0.5): 'truncated',
        cut(good_ascii, 0.995): 'truncated',            # the last line cut short
        cut(compressed, 0.7): 'truncated',
        cut(ply_bin, 0.6): 'truncated',
        cut(ply_ascii, 0.5): 'truncated',
        no_vertices: 'no points',
        no_points: 'no points',
        no_xyz: 'no x, y, z',
        mismatch: 'POINTS 5',
        words: 'not numbers',
    }
    for f, problem in cases.items():
        code, out, err = run(capsys, f)
        assert code == 2, f
        assert out == '', f
        assert len(err.strip().splitlines()) == 1, err
        assert problem in err and str(f) in err, err


def test_bad_options_end_with_one_line_and_exit_2(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / 'c.ply'
    write_ply(f, np.random.default_rng(0).uniform(-1, 1, (100, 3)))
    for argv, problem in ((['--up', '0,0,0'], 'non-zero vector'),
                          (['--up', '1,2'], 'non-zero vector'),
                          (['--up-tolerance', '95'], 'below 90'),
                          (['--plot', tmp_path / 'no' / 'p.png'], 'cannot write'),
                          (['--voxel', '-1'], 'positive'),
                          (['--radius-min', '0.2'], 'radius'),
                          (['--image', tmp_path / 'no.png'], 'not a readable image')):
        code, out, err = run(capsys, f, *argv)
        assert code == 2 and out == '', argv
        assert len(err.strip().splitlines()) == 1 and problem in err, err


def test_a_cloud_of_nans_is_read_and_has_nothing(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    nan = tmp_path / 'nan.ply'
    nan.write_text('ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n'
                   'property float z\nend_header\n' + 'nan nan nan\n' * 3)
    code, out, err = run(capsys, nan)
    assert code == 0
    res = json.loads(out)
    assert res['cylinders'] == [] and res['table'] is None and res['n_points'] == 0
    assert '0 finite points' in err

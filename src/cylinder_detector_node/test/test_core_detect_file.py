"""The detect_file command-line tool on small synthetic .ply files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

from cylinder_detector_node import detect_file
from cylinder_detector_node.core.scene import make_tabletop


def write_ply(path: Path, pts: np.ndarray) -> None:
    pts = pts.reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)))


def test_json_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = make_tabletop(np.random.default_rng(0), n_cylinders=1, n_distractors=0, width=320, height=240)
    f = tmp_path / 'one.ply'
    write_ply(f, scene.cloud)
    assert detect_file.main([str(f), '--plot', str(tmp_path / 'one.png')]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out['cylinders']) == 1
    c = out['cylinders'][0]
    assert set(c) >= {'centre', 'axis', 'radius', 'height', 'confidence'}
    base, r, h = scene.cylinders[0]
    assert abs(c['radius'] - r) < 0.3 * r
    assert np.linalg.norm(np.array(c['centre']) - base) < h
    assert (tmp_path / 'one.png').stat().st_size > 0


def test_bad_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert detect_file.main([str(tmp_path / 'missing.pcd')]) == 2
    assert 'no such file' in capsys.readouterr().err
    txt = tmp_path / 'cloud.txt'
    txt.write_text('1 2 3\n')
    assert detect_file.main([str(txt)]) == 2
    assert '.pcd or .ply' in capsys.readouterr().err
    renamed = tmp_path / 'renamed.pcd'   # a text file with the right suffix: not an empty cloud
    renamed.write_text('hello world\n')
    assert detect_file.main([str(renamed)]) == 2
    assert 'not a readable PCD point cloud' in capsys.readouterr().err
    header = 'ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n'
    empty = tmp_path / 'empty.ply'
    empty.write_text(header.format(0))
    nan = tmp_path / 'nan.ply'
    nan.write_text(header.format(3) + 'nan nan nan\n' * 3)
    for f in (empty, nan):
        assert detect_file.main([str(f)]) == 0
        cap = capsys.readouterr()
        assert json.loads(cap.out)['cylinders'] == []
        assert '0 finite points' in cap.err

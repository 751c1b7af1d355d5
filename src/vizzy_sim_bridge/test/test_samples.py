"""The shipped samples/ (issue 29 item 8) are what vizzy_sim_bridge.make_samples makes, and the
tools the docs run on them accept them.

Cheap: nothing is rendered. The files are checked against manifest.json (sizes, SHA-256, no file
missing or extra), their layout and counts against the manifest, the geometry-only parts (the
pedestrians' ground truth, the stereo geometry) recomputed by the generator, README.md against
the generator's text, and `evaluate` run once on the sequence (a few seconds).
"""

from __future__ import annotations

import configparser
import hashlib
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from vizzy_sim_bridge import make_samples

REPO = Path(__file__).resolve().parents[3]   # this file's checkout, wherever the package is
SAMPLES = REPO / 'samples'
LIMIT_BYTES = 5_000_000          # the issue: small samples, well under 5 MB in all


@pytest.fixture(scope='module')
def manifest() -> dict:
    path = SAMPLES / 'manifest.json'
    assert path.is_file(), f'{path} missing: run python -m vizzy_sim_bridge.make_samples'
    return json.loads(path.read_text())


def test_files_are_the_manifests(manifest: dict) -> None:
    """Every file listed, with its size and hash, and nothing else (a stale or hand-edited file
    fails here); small in all."""
    on_disk = make_samples.file_table(SAMPLES)
    assert sorted(on_disk) == sorted(manifest['files'])
    for name, entry in manifest['files'].items():
        raw = (SAMPLES / name).read_bytes()
        assert len(raw) == entry['bytes'], name
        assert hashlib.sha256(raw).hexdigest() == entry['sha256'], name
    total = sum(f.stat().st_size for f in SAMPLES.rglob('*') if f.is_file())
    assert total < LIMIT_BYTES, f'samples/ holds {total} bytes'
    assert set(make_samples.PARTS) <= set(manifest)


def test_readme_is_the_generators(manifest: dict) -> None:
    """README.md's numbers are the manifest's (the generator writes both)."""
    assert (SAMPLES / 'README.md').read_text() == make_samples.readme(manifest)


def test_mot_sequence_layout_and_ground_truth(manifest: dict) -> None:
    mot = manifest['mot']
    seq = SAMPLES / make_samples.MOT_NAME
    info = configparser.ConfigParser()
    info.read(seq / 'seqinfo.ini')
    s = info['Sequence']
    assert (int(s['seqLength']), int(s['imWidth']), int(s['imHeight'])) == (
        mot['frames'], mot['width'], mot['height'])
    frames = sorted((seq / s['imDir']).glob(f'*{s["imExt"]}'))
    assert [f.name for f in frames] == [f'{i:06d}.jpg' for i in range(1, mot['frames'] + 1)]
    for f in frames:
        image = cv2.imread(str(f))
        assert image is not None and image.shape == (mot['height'], mot['width'], 3), f
    rows = (seq / 'gt' / 'gt.txt').read_text().splitlines()
    assert len(rows) == mot['gt_rows'] > 0
    values = np.array([[float(v) for v in r.split(',')] for r in rows])
    assert values.shape[1] == 9                                   # MOT16/17 rows
    assert len(np.unique(values[:, 1])) == mot['gt_ids'] == mot['people']
    assert values[:, 0].min() == 1 and values[:, 0].max() == mot['frames']
    x, y, w, h = values[:, 2:6].T
    assert (x >= 0).all() and (y >= 0).all() and (w > 0).all() and (h > 0).all()
    assert (x + w <= mot['width'] + 1e-6).all() and (y + h <= mot['height'] + 1e-6).all()
    assert ((values[:, 8] > 0) & (values[:, 8] <= 1)).all()
    # the walkers' geometry, recomputed without rendering, gives the same rows
    assert make_samples.pedestrian_rows() == rows


def test_evaluate_runs_on_the_sequence(tmp_path: Path) -> None:
    """The docs' `evaluate samples/sim-pedestrians-s0` works and scores both modes."""
    evaluate = pytest.importorskip('mot_planner_node.evaluate')
    motchallenge = pytest.importorskip('mot_planner_node.core.motchallenge')
    seq = SAMPLES / make_samples.MOT_NAME
    loaded = motchallenge.load_sequence(seq)
    assert len(loaded) == make_samples.MOT_FRAMES
    out = tmp_path / 'eval.json'
    assert evaluate.main([str(seq), '--quiet', '--no-timing', '--output', str(out)]) == 0
    overall = json.loads(out.read_text())['overall']
    for mode in ('planner', 'full_frame'):
        mota = overall[mode]['mota']
        assert mota is not None and math.isfinite(mota) and -1.0 < mota <= 1.0, (mode, mota)
        assert overall[mode]['num_objects'] == json.loads(
            (SAMPLES / 'manifest.json').read_text())['mot']['gt_rows']


def test_stereo_pair(manifest: dict) -> None:
    """A rectified pair with its true disparity: the geometry is the generator's, the KITTI-style
    disparity map decodes to the recorded range, and a plain block matcher told that range
    agrees with it (the pair is the right way round and rectified)."""
    st = manifest['stereo']
    folder = SAMPLES / 'stereo'
    assert json.loads((folder / 'pair.json').read_text()) == st
    geometry = make_samples.stereo_geometry()
    assert {k: st[k] for k in geometry} == json.loads(json.dumps(geometry))
    assert st['rectified'] and st['baseline_m'] == pytest.approx(0.204)
    gray = {}
    for side in ('left', 'right'):
        image = cv2.imread(str(folder / f'{side}.jpg'))
        assert image is not None and image.shape == (st['height'], st['width'], 3), side
        gray[side] = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    raw = cv2.imread(str(folder / 'disparity.png'), cv2.IMREAD_UNCHANGED)
    assert raw is not None and raw.dtype == np.uint16 and raw.shape == (st['height'], st['width'])
    truth = np.where(raw > 0, raw / 256.0, np.nan)
    assert np.isfinite(truth).mean() == pytest.approx(st['known_fraction'], abs=1e-4)
    lo, hi = st['true_disparity_px']
    assert np.nanmin(truth) == pytest.approx(lo, abs=0.06)
    assert np.nanmax(truth) == pytest.approx(hi, abs=0.06)
    cy, cx = (int(round(c)) for c in st['principal_point'][::-1])
    assert truth[cy, cx] == pytest.approx(st['true_disparity_centre_px'], abs=0.01)
    first = int(lo) // 16 * 16
    count = -(-(int(hi) + 2 - first) // 16) * 16
    sgbm = cv2.StereoSGBM.create(minDisparity=first, numDisparities=count, blockSize=5, P1=200,
                                  P2=800, uniquenessRatio=5)
    found = sgbm.compute(gray['left'], gray['right']).astype(float) / 16.0
    both = (found >= first) & np.isfinite(truth)
    assert both.mean() > 0.6
    bad = np.abs(found - truth)[both] > 2.0
    assert bad.mean() < 0.1, f'bad-2.0 {bad.mean():.3f}'


def test_cloud_is_an_organized_pcd(manifest: dict) -> None:
    cl = manifest['cloud']
    path = SAMPLES / make_samples.CLOUD_NAME
    cloudfile = pytest.importorskip('cylinder_detector_node.core.cloudfile')
    points, image = cloudfile.read_cloud(path)                    # the detect_file reader
    assert points.shape == (cl['height'], cl['width'], 3)
    assert image is not None and image.shape == (cl['height'], cl['width'], 3)
    valid = np.isfinite(points).all(axis=2)
    assert int(valid.sum()) == cl['valid_points'] > 0.3 * cl['width'] * cl['height']
    z = points[valid][:, 2]
    assert z.min() > 0.3 and z.max() < 5.0                        # metres, the Xtion's range
    assert len(cl['cylinders_in_scene']) >= 3


def test_object_views(manifest: dict) -> None:
    ob = manifest['objects']
    folder = SAMPLES / 'objects'
    rows = (folder / 'labels.csv').read_text().splitlines()
    assert rows[0] == 'file,label,x0,y0,x1,y1' and len(rows) - 1 == ob['images'] >= 5
    labels_file = REPO / 'src/foveation_node/foveation_node/models/fovea_cnn.labels'
    known = set(labels_file.read_text().split())
    for row in rows[1:]:
        name, label, *box = row.split(',')
        assert label in known, row
        x0, y0, x1, y1 = (int(v) for v in box)
        assert 0 <= x0 < x1 < ob['window'] and 0 <= y0 < y1 < ob['window'], row
        assert x0 < ob['window'] // 2 < x1 and y0 < ob['window'] // 2 < y1, row   # centred
        image = cv2.imread(str(folder / name))
        assert image is not None and image.shape == (ob['window'], ob['window'], 3), name
    assert sorted({r.split(',')[1] for r in rows[1:]}) == ob['labels']

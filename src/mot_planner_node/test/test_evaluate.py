"""MOTChallenge reading, metrics against hand-computed values, and the evaluate tool."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from mot_planner_node import evaluate
from mot_planner_node.core.detector import HOG_SHRINK, Detections
from mot_planner_node.core.metrics import MotEvaluator, iou_distance, summarize
from mot_planner_node.core.motchallenge import MotFolderError, find_sequences, load_sequence
from mot_planner_node.core.observation import DetectorGeometry
from mot_planner_node.core.tracker import DEPLOYED

SIZE = (320, 240)
# Two people as a sliding-window detector sees them (windows keep the 1:2 aspect) and their
# ground-truth boxes (the windows through the HOG box shrink).
WINDOWS = np.array([[30.0, 40.0, 72.0, 144.0], [190.0, 60.0, 80.0, 160.0]])
O1, O2 = (tuple(b) for b in HOG_SHRINK.apply(WINDOWS))


def make_sequence(root: Path, gt_rows: list[str], n_frames: int = 3, name: str = 'SEQ-01',
                  seqinfo: str | None = None) -> Path:
    seq = root / name
    (seq / 'img1').mkdir(parents=True)
    (seq / 'gt').mkdir()
    for f in range(1, n_frames + 1):
        image = np.full((SIZE[1], SIZE[0], 3), 90, np.uint8)
        cv2.imwrite(str(seq / 'img1' / f'{f:06d}.jpg'), image)
    (seq / 'gt' / 'gt.txt').write_text('\n'.join(gt_rows) + '\n')
    (seq / 'seqinfo.ini').write_text(seqinfo if seqinfo is not None else (
        f'[Sequence]\nname={name}\nimDir=img1\nframeRate=30\nseqLength={n_frames}\n'
        f'imWidth={SIZE[0]}\nimHeight={SIZE[1]}\nimExt=.jpg\n'))
    return seq


def static_rows(n_frames: int = 3) -> list[str]:
    rows = []
    for f in range(1, n_frames + 1):
        rows.append(f'{f},1,{O1[0]},{O1[1]},{O1[2]},{O1[3]},1,1,1.0')
        rows.append(f'{f},2,{O2[0]},{O2[1]},{O2[2]},{O2[3]},1,1,0.8')
    return rows


def test_metrics_match_hand_computation(tmp_path: Path) -> None:
    rows = static_rows() + [
        '2,3,280,10,20,50,0,1,1.0',          # conf 0: ignored
        '3,4,100,150,30,60,1,7,1.0',         # static person: a distractor
        '1,5,0,0,10,10,1,3,1.0',             # a car: ignored
    ]
    seq = load_sequence(make_sequence(tmp_path, rows))
    assert seq.image_size == SIZE and seq.frame_rate == 30 and len(seq) == 3
    o1, o2 = np.array([O1]), np.array([O2])
    shrink_h = lambda b, h: np.array([[b[0][0], b[0][1], b[0][2], h]])   # noqa: E731
    hyps = {
        # frame 1: h1 on o1 with IoU 0.8, h2 on o2 exactly.
        1: ([1, 2], np.concatenate([shrink_h(o1, 0.8 * O1[3]), o2])),
        # frame 2: h1 on o1 with IoU 0.6, o2 missed, h3 a false positive.
        2: ([1, 3], np.concatenate([shrink_h(o1, 0.6 * O1[3]), [[250, 200, 20, 30]]])),
        # frame 3: h1 on o1, o2 now taken by h4 (an identity switch), h5 on the distractor.
        3: ([1, 4, 5], np.concatenate([o1, o2, [[100, 150, 30, 60]]])),
    }
    ev = MotEvaluator()
    for f in (1, 2, 3):
        gt_ids, gt_boxes, distractors = seq.gt.frame(f)
        assert sorted(gt_ids.tolist()) == [1, 2]
        ev.update(f, gt_ids, gt_boxes, np.array(hyps[f][0]), hyps[f][1], distractors)
    m = summarize({'s': ev})['s']
    # 6 objects: 4 matches + 1 switch (py-motmetrics counts a switch apart from the matches),
    # 1 miss, 1 false positive (h5 dropped: on a distractor).
    assert (m['num_objects'], m['num_matches'], m['num_misses'], m['num_false_positives'],
            m['num_switches']) == (6, 4, 1, 1, 1)
    assert m['mota'] == pytest.approx(1 - 3 / 6)
    # MOTP: mean 1 - IoU over the 5 matched pairs = (0.2 + 0 + 0.4 + 0 + 0) / 5.
    assert m['motp_distance'] == pytest.approx(0.12)
    assert m['motp'] == pytest.approx(88.0)
    # IDF1: best id pairing o1-h1 (3 frames), o2-h2 or o2-h4 (1): IDTP = 4;
    # 2 IDTP / (6 gt + 6 hypotheses, after dropping h5) = 8 / 12.
    assert m['idf1'] == pytest.approx(8 / 12)


def test_iou_distance() -> None:
    d = iou_distance(np.array([[0, 0, 10, 10.0]]), np.array([[0, 0, 10, 8.0], [0, 0, 10, 4.0]]))
    assert d[0, 0] == pytest.approx(0.2) and np.isnan(d[0, 1])


class StaticOracle:
    """Finds the two static people exactly, inside the regions it is given."""

    geometry = DetectorGeometry()
    box_shrink = HOG_SHRINK

    def detect(self, image, regions=None) -> Detections:
        win = WINDOWS.copy()
        if regions is not None:
            cx, cy = win[:, 0] + win[:, 2] / 2, win[:, 1] + win[:, 3] / 2
            regions = np.asarray(regions)
            keep = ((regions[:, None, 0] <= cx) & (cx <= regions[:, None, 2])
                    & (regions[:, None, 1] <= cy) & (cy <= regions[:, None, 3])).any(axis=0)
            win = win[keep]
        return Detections(win, np.ones(len(win)))


def test_evaluate_end_to_end_with_a_bad_frame(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path, static_rows(5), n_frames=5)
    (seq / 'img1' / '000003.jpg').write_bytes(b'not a jpeg at all')
    args = evaluate.parser().parse_args([str(tmp_path), '--quiet', '--iterations', '20',
                                         '--k-max', '1'])
    result = evaluate.evaluate(args.paths, args, detector=StaticOracle())
    assert list(result['sequences']) == ['SEQ-01']
    assert result['bad_frames'] == [{'sequence': 'SEQ-01', 'frame': 3,
                                     'problem': '000003.jpg: cannot be read or decoded'}]
    for mode in ('planner', 'full_frame'):
        m = result['overall'][mode]
        assert m['mota'] == pytest.approx(1.0) and m['idf1'] == pytest.approx(1.0)
        assert m['motp'] == pytest.approx(100.0)
        assert m['num_frames'] == 5
    # Frames 2-5 after the bootstrap; frame 3 could not be read (nothing processed).
    assert result['overall']['full_frame']['processed_fraction'] == 0.75
    assert result['overall']['planner']['processed_fraction'] < 0.75
    assert result['overall']['motp_delta'] == pytest.approx(0.0)
    assert 'detector_speedup' in result['sequences']['SEQ-01']


def test_evaluate_main_prints_json(tmp_path: Path, capsys) -> None:
    make_sequence(tmp_path, static_rows(2), n_frames=2)
    assert evaluate.main([str(tmp_path / 'SEQ-01'), '--quiet', '--mode', 'full']) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    m = out['overall']['full_frame']
    # HOG finds no one on a flat grey image: every object is a miss.
    assert m['mota'] == 0.0 and m['num_misses'] == 4 and m['motp'] is None
    assert 'planner' not in out['overall']


@pytest.mark.parametrize('rows,seqinfo,match', [
    (['1,1,0,0,10'], None, 'line 1: expected at least 6'),
    (['1,1,0,0,10,10', '2,1,0,0,x,10'], None, 'line 2: not a number'),
    (['4,1,0,0,10,10'], None, 'frame 4 is beyond'),
    (['1,1,0,0,10,10', '1,1,5,5,10,10'], None, 'id 1 appears twice in frame 1'),
    (['0,1,0,0,10,10'], None, 'frame must be an integer >= 1'),
    (['1,1,0,0,0,10'], None, 'width and height must be > 0'),
    (['1,1,0,0,10,nan'], None, 'non-finite'),
    ([], '[Sequence]\nname=x\n', 'no seqLength'),
    ([], '[Sequence]\nseqLength=three\n', 'seqLength must be an integer'),
    ([], '[Sequence]\nseqLength=5\nimExt=.jpg\n', '2 of the 5 frames'),
    ([], 'garbage without section', 'not a valid ini file'),
])
def test_malformed_folders(tmp_path: Path, rows, seqinfo, match) -> None:
    seq = make_sequence(tmp_path, rows, seqinfo=seqinfo)
    with pytest.raises(MotFolderError, match=match):
        load_sequence(seq)


def test_missing_parts_and_cli_errors(tmp_path: Path, capsys) -> None:
    with pytest.raises(MotFolderError, match='not a folder'):
        find_sequences(tmp_path / 'nope')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(MotFolderError, match='neither a MOTChallenge sequence'):
        find_sequences(tmp_path / 'empty')
    seq = make_sequence(tmp_path, static_rows())
    (seq / 'gt' / 'gt.txt').unlink()
    with pytest.raises(MotFolderError, match='ground truth file not found'):
        load_sequence(seq)
    assert evaluate.main([str(seq), '--quiet']) == 2
    assert 'evaluate: error:' in capsys.readouterr().err
    no_info = make_sequence(tmp_path, static_rows(), name='SEQ-02')
    (no_info / 'seqinfo.ini').unlink()
    assert len(load_sequence(no_info)) == 3                      # frames found in img1/
    (no_info / 'img1' / '000002.jpg').rename(no_info / 'img1' / '000007.jpg')
    with pytest.raises(MotFolderError, match='numbered 1, 2'):
        load_sequence(no_info)
    assert evaluate.main([str(seq.parent / 'SEQ-01'), '--quiet', '--s-max', '2']) == 2


@pytest.mark.parametrize('spec, said', [
    ('foo.bar:baz', "--detector foo.bar:baz: cannot import 'foo.bar' (No module named 'foo')"),
    ('json:no_such_factory', "--detector json:no_such_factory: module 'json' has no "
                             "'no_such_factory'"),
    ('json:__name__', "--detector json:__name__: '__name__' is not callable"),
])
def test_a_mistyped_detector_is_one_line(tmp_path: Path, capsys, spec: str, said: str) -> None:
    """Issue 29 item 6: a typo in --detector printed an ImportError traceback."""
    seq = make_sequence(tmp_path, static_rows())
    assert evaluate.main([str(seq), '--quiet', '--detector', spec]) == 2
    assert capsys.readouterr().err == f'evaluate: error: {said}\n'


def test_mot15_rows_keep_every_box(tmp_path: Path) -> None:
    """MOT15's gt.txt puts world coordinates (or -1) where MOT16/17 have class and visibility:
    ten values per row. Read as class/visibility they would drop every box."""
    rows = []
    for f in (1, 2):
        rows.append(f'{f},1,{O1[0]},{O1[1]},{O1[2]},{O1[3]},1,12.5,3.25,0')
        rows.append(f'{f},2,{O2[0]},{O2[1]},{O2[2]},{O2[3]},1,-1,-1,-1')
    seq = load_sequence(make_sequence(tmp_path, rows, n_frames=2))
    gt = seq.gt
    assert list(gt.classes) == [-1] * 4 and list(gt.visibility) == [1.0] * 4
    args = evaluate.parser().parse_args([str(tmp_path), '--quiet', '--mode', 'full'])
    result = evaluate.evaluate(args.paths, args, detector=StaticOracle())
    assert result['overall']['full_frame']['num_objects'] == 4
    assert result['overall']['full_frame']['mota'] == pytest.approx(1.0)


def test_no_target_objects_is_an_error_and_the_json_is_valid(tmp_path: Path, capsys) -> None:
    rows = [f'{f},1,{O1[0]},{O1[1]},{O1[2]},{O1[3]},0,1,1.0' for f in (1, 2)]  # conf 0: ignored
    make_sequence(tmp_path, rows, n_frames=2)
    assert evaluate.main([str(tmp_path / 'SEQ-01'), '--quiet', '--mode', 'full']) == 2
    assert 'no target objects' in capsys.readouterr().err
    assert evaluate.finite_or_none({'a': [float('-inf'), 1.5, float('nan')], 'b': 'x'}) == \
        {'a': [None, 1.5, None], 'b': 'x'}


@pytest.mark.parametrize('tail,classes,visibility', [
    ('', [-1, -1], [1.0, 1.0]),                             # six values
    (',1', [-1, -1], [1.0, 1.0]),                           # conf
    (',1,1', [1, 1], [1.0, 1.0]),                           # conf, class
    (',1,1,0.4', [1, 1], [0.4, 0.4]),                       # MOT16/17/20
    (',1,-1,-1', [-1, -1], [-1.0, -1.0]),                   # MOT16-style, unused columns -1
    (',1,-1,-1,-1', [-1, -1], [1.0, 1.0]),                  # MOT15, no world coordinates
    (',1,3.5,-2.25,0', [-1, -1], [1.0, 1.0]),               # MOT15 with world coordinates
])
def test_every_published_gt_layout_keeps_its_boxes(tmp_path: Path, tail, classes,
                                                   visibility) -> None:
    rows = [f'1,{i},{b[0]},{b[1]},{b[2]},{b[3]}{tail}' for i, b in ((1, O1), (2, O2))]
    gt = load_sequence(make_sequence(tmp_path, rows, n_frames=1)).gt
    assert gt.classes.tolist() == classes and gt.visibility.tolist() == visibility
    ids, boxes, _ = gt.frame(1)
    assert ids.tolist() == [1, 2]
    np.testing.assert_allclose(boxes, [O1, O2])


@pytest.mark.parametrize('rows,match', [
    (['1,1,0,0,10,10,1,1,1,0,0'], 'line 1: 11 values; MOTChallenge ground truth has 6 to 9'),
    (['1,1,0,0,10,10,1,1,1', '2,1,0,0,10,10,1,-1,-1,-1'], 'line 2: 10 values, but the first row'),
    (['1,1,0,0,10,10,1,1.5,1'], 'line 1: class must be an integer'),
    (['1,1,0,0,10,10,1,1,7'], 'line 1: visibility must be in'),
])
def test_other_gt_layouts_are_refused_in_one_line(tmp_path: Path, capsys, rows, match) -> None:
    seq = make_sequence(tmp_path, rows, n_frames=2)
    with pytest.raises(MotFolderError, match=match):
        load_sequence(seq)
    assert evaluate.main([str(seq), '--quiet']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(seq / 'gt' / 'gt.txt') in err


class MovingOracle:
    """Finds two people walking right at 3 px/frame inside the regions it is given, with a
    deterministic jitter."""

    geometry = DetectorGeometry()
    box_shrink = HOG_SHRINK

    def __init__(self) -> None:
        self.calls = 0

    def detect(self, image, regions=None) -> Detections:
        frame = int(image[0, 0, 0]) - 10           # the frame number is painted in pixel (0, 0)
        self.calls += 1
        win = WINDOWS.copy()
        win[:, 0] += 3.0 * frame + np.array([1.0, -1.0]) * (frame % 3)
        if regions is not None:
            r = np.asarray(regions)
            inside = ((r[:, None, 0] <= win[:, 0]) & (win[:, 0] + win[:, 2] <= r[:, None, 2])
                      & (r[:, None, 1] <= win[:, 1]) & (win[:, 1] + win[:, 3] <= r[:, None, 3]))
            win = win[inside.any(axis=0)]
        return Detections(win, np.ones(len(win)))


def moving_sequence(root: Path, n_frames: int) -> Path:
    rows = []
    for f in range(1, n_frames + 1):
        for i, w in enumerate(WINDOWS, 1):
            b = HOG_SHRINK.apply(w[None] + [[3.0 * (f - 1), 0, 0, 0]])[0]
            rows.append(f'{f},{i},{b[0]:.2f},{b[1]:.2f},{b[2]:.2f},{b[3]:.2f},1,1,1')
    seq = make_sequence(root, rows, n_frames=n_frames)
    for f in range(1, n_frames + 1):
        image = np.full((SIZE[1], SIZE[0], 3), 90, np.uint8)
        image[0, 0] = 10 + (f - 1)
        cv2.imwrite(str(seq / 'img1' / f'{f:06d}.png'), image)
        (seq / 'img1' / f'{f:06d}.jpg').unlink()
    info = (seq / 'seqinfo.ini').read_text().replace('imExt=.jpg', 'imExt=.png')
    (seq / 'seqinfo.ini').write_text(info)
    return seq


def test_fixed_seed_and_iterations_give_identical_json(tmp_path: Path, capsys,
                                                       monkeypatch) -> None:
    """The deployed protocol is the default; with --budget-iterations the JSON (timings left
    out) is the same run after run, and the share of each frame read is reported and bound by
    S_max."""
    seq = moving_sequence(tmp_path, 24)
    monkeypatch.setattr(evaluate, 'make_detector', lambda spec, args: MovingOracle())
    argv = [str(seq), '--quiet', '--budget-iterations', '40', '--seed', '3', '--no-timing',
            '--s-max', '0.4', '--k-max', '1']
    outs = []
    for _ in range(2):
        assert evaluate.main(argv) == 0
        outs.append(capsys.readouterr().out.strip().splitlines()[-1])
    assert outs[0] == outs[1]
    result = json.loads(outs[0])
    assert result['config']['protocol'] == 'deployed'
    assert result['config']['new_tracks'] == 'budget' and result['config']['area'] == 'scaled'
    assert result['config']['horizon'] == DEPLOYED['horizon'] == 1
    assert 'detector_ms_per_frame' not in result['overall']['planner']
    p = result['overall']['planner']
    per_frame = result['sequences']['SEQ-01']['planner']['read_fraction_per_frame']
    assert len(per_frame) == 24 and per_frame[0] == 1.0
    # every tracking frame reads at most (1 - birth_share) S_max
    assert p['read_fraction_max_tracking'] <= (1 - DEPLOYED['birth_share']) * 0.4 + 1e-4
    assert p['read_fraction_mean'] == pytest.approx(np.mean(per_frame), abs=1e-4)
    assert p['full_frames'] >= 2                       # births paid from the budget
    assert p['mota'] > 0.9 and p['num_switches'] == 0
    # The thesis protocol starts no tracks after the first frame.
    assert evaluate.main(argv + ['--protocol', 'thesis']) == 0
    thesis = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert thesis['config']['new_tracks'] == 'none' and thesis['config']['area'] == 'centres'
    assert thesis['config']['horizon'] == 3                       # the thesis's T
    assert thesis['overall']['planner']['full_frames'] == 1


def test_bad_options_are_one_line(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        evaluate.main(['x', '--protocol', 'other'])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'invalid choice' in err
    assert evaluate.main(['.', '--budget-iterations', '0', '--quiet']) == 2
    assert 'max_iterations' in capsys.readouterr().err
    assert evaluate.main(['.', '--horizon', '0', '--quiet']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'depth must be in [1, 8]' in err


def test_the_default_plans_by_iterations_not_by_the_clock(tmp_path: Path, capsys,
                                                          monkeypatch) -> None:
    """Without options a run is the same on any machine at any load (a fixed number of MCTS
    runs per frame, by protocol); --wall-clock plans as the node does, for --budget-ms."""
    seq = moving_sequence(tmp_path, 12)
    monkeypatch.setattr(evaluate, 'make_detector', lambda spec, args: MovingOracle())
    argv = [str(seq), '--quiet', '--no-timing', '--s-max', '0.4', '--k-max', '1']
    outs = []
    for _ in range(2):
        assert evaluate.main(argv) == 0
        outs.append(capsys.readouterr().out.strip().splitlines()[-1])
    assert outs[0] == outs[1]
    config = json.loads(outs[0])['config']
    assert config['budget_iterations'] == evaluate.DEFAULT_BUDGET_ITERATIONS['deployed']
    assert evaluate.main(argv + ['--protocol', 'thesis']) == 0
    config = json.loads(capsys.readouterr().out.strip().splitlines()[-1])['config']
    assert config['budget_iterations'] == evaluate.DEFAULT_BUDGET_ITERATIONS['thesis']
    args = evaluate.parser().parse_args([str(seq), '--wall-clock', '--budget-ms', '7'])
    planner = evaluate.tracker_config(args, 'planner').planner
    assert planner.budget_ms == 7.0 and planner.max_iterations is None

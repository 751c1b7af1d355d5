"""camera_calibration.py: camera_calibration_parsers' YAML written and read, camera_info_manager's
URLs resolved, every unusable file refused with one line saying why; the vizzy_camera_calibration
tool (issue 29 item 4). Plain pytest, no ROS."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from vizzy_sim_bridge import camera_calibration as cc
from vizzy_sim_bridge.camera_calibration import (
    CalibrationError,
    load_calibration,
    parse_calibration,
    resolve_url,
    sim_calibration,
    to_yaml,
)
from vizzy_vision.camera import camera_matrix
from vizzy_vision.kinematics import BASELINE

# as the ROS camera_calibration GUI (cameracalibrator) saves it: its spacing, '1.' and '0.'
CAMERACALIBRATOR = """image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [ 415.12614,    0.     ,  319.52373,
            0.     ,  410.49986,  240.14929,
            0.     ,    0.     ,    1.     ]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.017697, -0.007270, 0.005751, -0.000139, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [ 1., 0., 0.,
          0., 1., 0.,
          0., 0., 1.]
projection_matrix:
  rows: 3
  cols: 4
  data: [ 415.12614, 0., 319.52373, 0.,
          0., 410.27547, 239.89776, 0.,
          0., 0., 1., 0.]
"""

# camera_calibration_parsers' keys, in the order its writer (writeCalibrationYml) emits them
PARSER_KEYS = ['image_width', 'image_height', 'camera_name', 'camera_matrix', 'distortion_model',
               'distortion_coefficients', 'rectification_matrix', 'projection_matrix']


def test_a_cameracalibrator_file_is_read() -> None:
    cal = parse_calibration(CAMERACALIBRATOR)
    assert (cal.camera_name, cal.width, cal.height, cal.distortion_model) == (
        'narrow_stereo', 640, 480, 'plumb_bob')
    assert cal.k == (415.12614, 0.0, 319.52373, 0.0, 410.49986, 240.14929, 0.0, 0.0, 1.0)
    assert cal.d == (-0.017697, -0.00727, 0.005751, -0.000139, 0.0)
    assert cal.r == (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    assert cal.p[5] == 410.27547 and len(cal.p) == 12


def test_the_sims_calibration_is_written_in_the_parsers_layout_and_reads_back_exactly() -> None:
    for baseline in (0.0, BASELINE):
        cal = sim_calibration('vizzy_right', 640, 480, 85.4, baseline)
        text = to_yaml(cal, 'a comment\nof two lines')
        assert text.startswith('# a comment\n# of two lines\nimage_width: 640\n')
        doc = yaml.safe_load(text)
        assert list(doc) == PARSER_KEYS
        assert doc['camera_matrix']['rows'] == 3 and doc['projection_matrix']['cols'] == 4
        assert doc['distortion_coefficients'] == {'rows': 1, 'cols': 5, 'data': [0] * 5}
        assert parse_calibration(text) == cal            # every float, bit for bit
    k = camera_matrix(640, 480, 85.4)
    assert cal.k == tuple(k.reshape(-1))
    assert cal.p[3] == pytest.approx(-k[0, 0] * BASELINE) and cal.p[3] != 0.0
    assert '-0' not in to_yaml(sim_calibration('vizzy_left', 640, 480, 85.4))   # no -0.0


def test_small_and_large_numbers_survive_a_yaml_1_1_reader() -> None:
    """repr(1e-05) is '1e-05', which PyYAML (YAML 1.1) reads as a string: written as 1.0e-05,
    and such strings in a file (yaml-cpp reads them as numbers) are taken as numbers too."""
    cal = replace(sim_calibration('vizzy_left', 640, 480, 85.4),
                  d=(1e-05, -2.5e-07, 3e20, 0.0, 1e-300))
    text = to_yaml(cal)
    assert '1.0e-05' in text and '-2.5e-07' in text
    assert parse_calibration(text) == cal
    assert parse_calibration(text.replace('1.0e-05', '1e-05')).d[0] == 1e-05


def test_absent_name_and_model_default_as_the_parser_does() -> None:
    lines = [ln for ln in CAMERACALIBRATOR.splitlines()
             if not ln.startswith(('camera_name', 'distortion_model'))]
    cal = parse_calibration('\n'.join(lines))
    assert (cal.camera_name, cal.distortion_model) == ('unknown', 'plumb_bob')


def _broken(old: str, new: str) -> str:
    assert old in CAMERACALIBRATOR
    return CAMERACALIBRATOR.replace(old, new, 1)


@pytest.mark.parametrize(('text', 'why'), [
    ('image_width: [640', 'not YAML at line 1'),
    ('- 1\n- 2\n', 'not a map of calibration fields (a list)'),
    ('', 'not a map of calibration fields (a NoneType)'),
    (_broken('image_height: 480\n', ''), 'no image_height'),
    (_broken('image_width: 640', 'image_width: -640'),
     'image_width must be a positive integer, got -640'),
    (_broken('image_width: 640', 'image_width: true'),
     'image_width must be a positive integer, got True'),
    (_broken('image_width: 640', 'image_width: 640.5'),
     'image_width must be a positive integer, got 640.5'),
    (_broken('projection_matrix:', 'projection:'), 'no projection_matrix'),
    (_broken('camera_matrix:\n  rows: 3', 'camera_matrix:\n  rows: 2'),
     'camera_matrix must be 3x3, got 2x3'),
    (_broken('camera_matrix:\n  rows: 3\n  cols: 3\n', 'camera_matrix:\n  cols: 3\n'),
     'camera_matrix must be a map of rows, cols and data'),
    (_broken('[ 1., 0., 0.,', '[ 0., 0.,'),
     'rectification_matrix: data must list rows x cols = 9 numbers, got 8'),
    (_broken('[ 1., 0., 0.,', '[ x, 0., 0.,'), 'rectification_matrix: data must be finite numbers'),
    (_broken('[ 1., 0., 0.,', '[ .nan, 0., 0.,'),
     'rectification_matrix: data must be finite numbers'),
    (_broken('0.005751, -0.000139, 0.000000]', '0.005751, -0.000139]').replace(
        'cols: 5', 'cols: 4'), 'plumb_bob takes 5 distortion coefficients, got 4'),
    (_broken('distortion_model: plumb_bob', 'distortion_model: 3'),
     'distortion_model must be a name, got 3'),
    (_broken('415.12614,    0.', '0.,    0.'),
     'camera_matrix: fx, fy must be in [1, 1e+06] px, got 0, 410.5'),
    (_broken('0., 410.27547', '0., 1e-300'),
     'projection_matrix: fx, fy must be in [1, 1e+06] px, got 415.126, 1e-300'),
])
def test_an_unusable_file_is_refused_in_one_line(text: str, why: str) -> None:
    with pytest.raises(CalibrationError) as err:
        parse_calibration(text)
    assert str(err.value).startswith(why) and '\n' not in str(err.value)


def test_another_distortion_model_keeps_its_coefficients() -> None:
    text = _broken('distortion_model: plumb_bob', 'distortion_model: rational_polynomial')
    with pytest.raises(CalibrationError, match='rational_polynomial takes 8'):
        parse_calibration(text)
    text = _broken('distortion_model: plumb_bob', 'distortion_model: fisheye_custom')
    assert len(parse_calibration(text).d) == 5        # a driver's own model: passed through


def test_urls_resolve_as_camera_info_manager_resolves_them(monkeypatch, tmp_path) -> None:
    assert resolve_url('file:///etc/cam.yaml', 'x') == Path('/etc/cam.yaml')
    assert resolve_url('FILE:///etc/cam.yaml', 'x') == Path('/etc/cam.yaml')
    assert resolve_url('file:///cal/${NAME}.yaml', 'vizzy_left') == Path('/cal/vizzy_left.yaml')
    monkeypatch.setenv('ROS_HOME', str(tmp_path))
    assert resolve_url('file://${ROS_HOME}/camera_info/${NAME}.yaml', 'vizzy_rgbd') == (
        tmp_path / 'camera_info' / 'vizzy_rgbd.yaml')
    monkeypatch.delenv('ROS_HOME')
    assert resolve_url('file://${ROS_HOME}/c.yaml', 'x') == Path.home() / '.ros' / 'c.yaml'
    # package://: the package's share directory (its source folder without ROS 2)
    sim_yaml = resolve_url('package://vizzy_sim_bridge/config/sim.yaml', 'x')
    assert sim_yaml.is_file() and sim_yaml.parts[-3:] == ('vizzy_sim_bridge', 'config', 'sim.yaml')


@pytest.mark.parametrize(('url', 'why'), [
    ('http://example.com/cam.yaml', "'http://example.com/cam.yaml' is no calibration URL"),
    ('file://relative/cam.yaml', "'file://relative/cam.yaml' is no calibration URL"),
    ('/abs/cam.yaml', "'/abs/cam.yaml' is no calibration URL"),
    ('package://vizzy_sim_bridge', "'package://vizzy_sim_bridge': expected package://<package>"),
    ('package://no_such_package_xyz/c.yaml', "'package://no_such_package_xyz/c.yaml': package "
                                             "'no_such_package_xyz' is not installed"),
])
def test_a_bad_url_is_refused_in_one_line(url: str, why: str) -> None:
    with pytest.raises(CalibrationError) as err:
        resolve_url(url, 'vizzy_left')
    assert str(err.value).startswith(why) and '\n' not in str(err.value)


def test_load_checks_the_file_and_the_image_size(tmp_path) -> None:
    cal = sim_calibration('vizzy_left', 320, 240, 60.0)
    (tmp_path / 'vizzy_left.yaml').write_text(to_yaml(cal))
    url = f'file://{tmp_path}/${{NAME}}.yaml'
    assert load_calibration(url, 'vizzy_left', 320, 240) == cal
    with pytest.raises(CalibrationError) as err:
        load_calibration(url, 'vizzy_left', 640, 480)
    assert str(err.value) == (f'{tmp_path}/vizzy_left.yaml is for 320x240 images, the camera '
                              'gives 640x480')
    with pytest.raises(CalibrationError) as err:
        load_calibration(url, 'vizzy_right', 320, 240)
    assert str(err.value) == (f'cannot read {tmp_path}/vizzy_right.yaml: No such file or '
                              'directory')
    (tmp_path / 'bad.yaml').write_text(to_yaml(cal).replace('image_height: 240\n', ''))
    with pytest.raises(CalibrationError) as err:
        load_calibration(f'file://{tmp_path}/bad.yaml', 'vizzy_left', 320, 240)
    assert str(err.value) == f'{tmp_path}/bad.yaml: no image_height'
    (tmp_path / 'binary.yaml').write_bytes(b'\xff\xfe\x00')
    with pytest.raises(CalibrationError, match='cannot read .*binary.yaml'):
        load_calibration(f'file://{tmp_path}/binary.yaml', 'vizzy_left', 320, 240)


def test_the_tool_writes_what_the_sim_publishes_and_checks_files(tmp_path, capsys) -> None:
    out = tmp_path / 'right.yaml'
    assert cc.main(['right', '-o', str(out)]) == 0
    cal = parse_calibration(out.read_text())
    assert cal == sim_calibration('vizzy_right', 640, 480, 85.4, BASELINE)   # sim's defaults
    assert out.read_text().startswith("# The simulated Vizzy head's right camera")
    assert cc.main(['rgbd', '--width', '320', '--height', '240']) == 0
    assert parse_calibration(capsys.readouterr().out) == sim_calibration('vizzy_rgbd', 320, 240,
                                                                         58.0)
    assert cc.main(['--check', f'file://{out}', 'right']) == 0
    assert capsys.readouterr().out.startswith(f'file://{out}: vizzy_right 640x480, fx 346.781')
    assert cc.main(['--check', f'file://{out}', 'right', '--width', '320']) == 1
    err = capsys.readouterr().err
    assert err == (f'vizzy_camera_calibration: {out} is for 640x480 images, the camera gives '
                   '320x480\n')
    assert cc.main(['left', '-o', str(tmp_path / 'no' / 'dir' / 'x.yaml')]) == 1
    assert 'cannot write' in capsys.readouterr().err
    assert cc.main(['left', '--horizontal-fov-deg', '190']) == 2
    assert 'horizontal FOV must be in (0, 180)' in capsys.readouterr().err

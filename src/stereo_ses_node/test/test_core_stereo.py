"""Sensors as Gaussian RFs (section 3.3.2) and SGBM stereo on what each sensor sees."""

import numpy as np
import pytest

from stereo_ses_node.core.geometry import vergence_poses
from stereo_ses_node.core.sensors import cartesian_sensor, logpolar_sensor
from stereo_ses_node.core.ses import SensoryEgoSphere
from stereo_ses_node.core.stereo import StereoPipeline
from stereo_ses_node.core.synthetic import plane_texture, render_plane
from stereo_ses_node.core.ut import StereoRig
from vizzy_vision.logpolar import LogPolarRetina

W, H = 320, 240
F = 160.0 / np.tan(np.radians(85.4 / 2))
K = np.array([[F, 0, 159.5], [0, F, 119.5], [0, 0, 1.0]])


def test_cartesian_sensor_grid_and_lookup():
    s = cartesian_sensor(640, 480, 200, 200)
    assert s.n_rf == 40000 and np.allclose(s.sigmas, 1.6)
    idx = np.array([0, 199, 200, 39999])
    np.testing.assert_array_equal(s.rf_index(s.centers[idx, 0], s.centers[idx, 1]), idx)


def test_logpolar_sensor_reuses_retina():
    r = LogPolarRetina(W, H, rings=40, wedges=60)
    s = logpolar_sensor(r)
    assert s.n_rf == 2400
    idx = np.array([0, 39, 40, 2399])
    np.testing.assert_array_equal(s.rf_index(s.centers[idx, 0], s.centers[idx, 1]), idx)
    sig = s.sigmas.reshape(60, 40)
    assert np.all(np.diff(sig[0]) >= 0)                   # RFs grow with eccentricity


@pytest.mark.parametrize('sensor', ['cartesian', 'logpolar'])
def test_plane_depth_recovered_and_fused(sensor):
    depth = 1.0
    pl, pr = vergence_poses(0.204, 2 * np.arctan(0.102 / depth))
    rig = StereoRig.create(K, K, pl, pr)
    tex = plane_texture(512)
    left = render_plane(K, pl, W, H, depth, tex, 0.004)
    right = render_plane(K, pr, W, H, depth, tex, 0.004)
    pipe = StereoPipeline(W, H, sensor, (100, 100) if sensor == 'cartesian' else (60, 80),
                          retina_kwargs={'max_level': 2} if sensor == 'logpolar' else None)
    frame = pipe.process(left, right, rig)
    assert frame.means.shape[0] > 1000
    z = frame.means[:, 2]
    assert abs(np.median(z) - depth) < 0.02
    assert np.mean(np.abs(z - depth) < 0.1) > 0.8
    assert frame.colors.shape == (frame.means.shape[0], 3)
    ses = SensoryEgoSphere(2000, seed=0)
    rep = ses.fuse(frame.means, frame.covs)
    assert rep.fused == frame.means.shape[0]


def test_bad_images_rejected():
    pipe = StereoPipeline(W, H, 'cartesian', (100, 100))
    pl, pr = vergence_poses(0.204, 0.2)
    rig = StereoRig.create(K, K, pl, pr)
    img = np.zeros((H, W, 3), np.uint8)
    with pytest.raises(ValueError, match='differ'):
        pipe.process(img, img[:, :-1], rig)
    with pytest.raises(ValueError, match='expects'):
        pipe.process(img[:, :-1], img[:, :-1], rig)
    with pytest.raises(ValueError, match='8-bit'):
        pipe.process(img.astype(np.float32), img.astype(np.float32), rig)
    frame = pipe.process(img, img, rig)          # no texture: every disparity is NaN
    assert frame.means.shape == (0, 3) and frame.rejected['nan disparity'] > 0

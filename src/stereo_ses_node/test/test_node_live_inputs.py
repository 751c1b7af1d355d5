"""The stereo_ses node live: bad inputs skipped with the sphere consistent, refusals counted per
topic and reason (split from test_node_live.py; the rig is stereo_live_rig.py)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from stereo_ses_node import node as ses_node
from stereo_ses_node.messages import NO_PARTNER, PAIR_FAILED, UNUSABLE_K
from vizzy_runtime.convert import (
    SHORT_DATA,
    UNSUPPORTED_ENCODING,
)
from vizzy_runtime.input_health import DIAGNOSTICS_TOPIC
from vizzy_runtime.ros import (
    Parameter,
)
from vizzy_runtime.testing import reported_status, wait_until

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stereo_live_rig import (  # noqa: E402 (the rig and its helpers; the graph fixture: conftest.py)
    FRAMES,
    TIMEOUT,
    CameraInfo,
    DiagnosticArray,
    F,
    H,
    W,
    _feed,
    _stamps,
    _take,
)

pytestmark = pytest.mark.live  # also run on the real rclpy (scripts/test_ros.sh)


def test_bad_inputs_are_skipped_and_the_sphere_stays_consistent(graph, capfd) -> None:
    rig, ses, executor = graph
    rig.publish_info()
    rig.publish_tf()
    assert wait_until(lambda: len(ses._k) == 2 and ses._tf.can_transform('ego', FRAMES['right']),
                      TIMEOUT, spin=executor)
    assert _feed(rig, ses, executor) and ses.frames_fused == 1
    obs = ses._ses.n_obs.copy()
    info = ses._ses.info.copy()

    # left and right sizes differ
    stamp = next(_stamps)
    narrow = rig.image('right', stamp, rig.images['right'][:, :-20].copy())
    assert _feed(rig, ses, executor, rig.image('left', stamp), narrow)
    assert 'differ' in capfd.readouterr().err
    # an image whose size disagrees with camera_info (both eyes)
    stamp = next(_stamps)
    small = {e: rig.image(e, stamp, rig.images[e][:200, :280].copy()) for e in FRAMES}
    assert _feed(rig, ses, executor, small['left'], small['right'])
    assert 'camera_info' in capfd.readouterr().err
    # textureless images: only NaN disparities
    stamp = next(_stamps)
    flat = {e: rig.image(e, stamp, np.full((H, W, 3), 90, np.uint8)) for e in FRAMES}
    assert _feed(rig, ses, executor, flat['left'], flat['right'])
    assert 'no valid correspondences' in capfd.readouterr().err
    assert ses.frames_skipped == 3 and ses.frames_fused == 1
    assert np.array_equal(ses._ses.n_obs, obs) and np.array_equal(ses._ses.info, info)

    # the eyes' images may arrive interleaved: pairs still form by stamp
    received = ses.pairs_received
    processed = ses.pairs_processed
    first = _take(2)
    for k in (first, first + 1):
        rig.image_pubs['left'].publish(rig.image('left', k))
    for k in (first, first + 1):
        rig.image_pubs['right'].publish(rig.image('right', k))
    assert wait_until(lambda: ses.pairs_received >= received + 1, TIMEOUT, spin=executor)
    assert wait_until(lambda: ses.pairs_processed > processed, TIMEOUT, spin=executor)
    assert ses.frames_fused >= 2 and ses.images_unpaired == 0
    # stamps that never match: no pair is formed, the unpaired images go with a message
    received = ses.pairs_received
    first = _take(12)
    for k in range(6):
        rig.image_pubs['right'].publish(rig.image('right', first + 2 * k))
        rig.image_pubs['left'].publish(rig.image('left', first + 1 + 2 * k))
        wait_until(lambda: False, 0.05, spin=executor)
    assert wait_until(lambda: 'stamps differ' in capfd.readouterr().err, TIMEOUT,
                      spin=executor)
    assert ses.pairs_received == received and ses.images_unpaired >= 6
    # a mono8 image is dropped with a message
    mono = rig.image('left', next(_stamps), np.zeros((H, W), np.uint8), 'mono8')
    rig.image_pubs['left'].publish(mono)
    assert wait_until(lambda: "'mono8'" in capfd.readouterr().err, TIMEOUT, spin=executor)
    # the node still works
    fused = ses.frames_fused
    assert _feed(rig, ses, executor) and ses.frames_fused == fused + 1

    # parameters at run time: a new bias rebuilds the sphere, bad values are refused
    change = [Parameter('bias', value='down'), Parameter('n_cells', value=1000)]
    assert all(r.successful for r in ses.set_parameters(change))
    assert _feed(rig, ses, executor)
    assert ses._ses.n_cells == 1000 and ses._ses.directions[:, 2].mean() < -0.3
    assert not ses.set_parameters([Parameter('ucb_alpha', value=-1.0)])[0].successful
    assert not ses.set_parameters([Parameter('bias_weights', value=[0.5, 0.5])])[0].successful
    assert ses.set_parameters([Parameter('ucb_alpha', value=float('inf'))])[0].successful


def test_refused_inputs_are_counted_per_topic_and_reason(graph, capfd, monkeypatch) -> None:
    """Bad images and camera_info are refused and counted per (topic, reason) in input_health
    (logged, on /diagnostics); the valid pair right after is fused; no exception escapes, and
    one raised in a callback or the worker is counted too."""
    rig, ses, executor = graph
    health = ses.input_health
    left, right = (ses._image_subs[e].topic_name for e in ('left', 'right'))
    left_info = ses._info_subs['left'].topic_name
    reports: list[Any] = []
    rig.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, reports.append, 10)
    rig.publish_info()
    rig.publish_tf()
    assert wait_until(lambda: len(ses._k) == 2 and ses._tf.can_transform('ego', FRAMES['right']),
                      TIMEOUT, spin=executor)
    assert health.refused() == {}
    assert wait_until(lambda: health.accepted().get(left_info) == 1, TIMEOUT, spin=executor)

    zero_k = CameraInfo(width=W, height=H)                    # fx = fy = 0: unusable
    zero_k.header.frame_id = FRAMES['left']
    zero_k.k = [0.0] * 9
    rig.info_pubs['left'].publish(zero_k)
    first = _take(4)
    unknown = rig.image('left', first)
    unknown.encoding = 'yuv9'
    rig.image_pubs['left'].publish(unknown)
    short = rig.image('right', first)
    short.height = 2 * H                                      # more rows than the data holds
    rig.image_pubs['right'].publish(short)
    rig.image_pubs['left'].publish(rig.image('left', first + 1))  # its right never comes
    expected = {(left_info, UNUSABLE_K): 1,
                (left, UNSUPPORTED_ENCODING): 1,
                (right, SHORT_DATA): 1}
    assert wait_until(lambda: health.refused() == expected and len(ses._unpaired['left']) == 1,
                      TIMEOUT, spin=executor), health.refused()
    assert ses._k['left'][0, 0] == pytest.approx(F)           # the last good K stays in use

    # a valid pair: the waiting left image is dropped without a partner, the pair is fused
    fused, accepted = ses.frames_fused, health.accepted()
    rig.image_pubs['left'].publish(rig.image('left', first + 2))
    rig.image_pubs['right'].publish(rig.image('right', first + 2))
    assert wait_until(lambda: ses.frames_fused == fused + 1
                      and any(p.header.stamp.sec == 100 + first + 2 for p in rig.points),
                      TIMEOUT, spin=executor)
    expected[(left, NO_PARTNER)] = 1
    assert health.refused() == expected
    now = health.accepted()
    assert now[left] == accepted.get(left, 0) + 1 and now[right] == accepted.get(right, 0) + 1
    # a valid camera_info after the bad one is accepted again
    rig.publish_info()
    assert wait_until(lambda: health.accepted().get(left_info) == accepted[left_info] + 1,
                      TIMEOUT, spin=executor)

    # /diagnostics: the node's status carries the counts
    name = ses.get_fully_qualified_name()

    assert wait_until(lambda: reported_status(reports, name).get(f'{left}: {NO_PARTNER}')
                      == '1', TIMEOUT, spin=executor), reported_status(reports, name)
    values = reported_status(reports, name)
    assert values[f'{left_info}: {UNUSABLE_K}'] == '1'
    assert values[f'{right}: {SHORT_DATA}'] == '1'
    # each first refusal logged once, naming topic and reason; nothing raised
    err = capfd.readouterr().err
    assert err.count(f'{left_info}: refused: {UNUSABLE_K}') == 1, err
    assert f"{left}: refused: {UNSUPPORTED_ENCODING}: 'yuv9'" in err, err
    assert f'{right}: refused: {SHORT_DATA}' in err, err
    assert (f'{left}: refused: {NO_PARTNER}: image stamped {100 + first + 1}.000 s'
            in err), err
    assert 'Traceback' not in err
    assert not any(reason.startswith('failed on') for _, reason in health.refused())

    # an exception in a subscription callback (guarded) or in the worker: counted on its topic
    def boom(*_: Any, **__: Any) -> None:
        raise RuntimeError('on fire')

    monkeypatch.setattr(ses_node, 'camera_k', boom)
    rig.publish_info()
    right_info = ses._info_subs['right'].topic_name
    for topic in (left_info, right_info):
        expected[(topic, 'failed on a camera_info: RuntimeError')] = 1
    assert wait_until(lambda: health.refused() == expected, TIMEOUT, spin=executor), \
        health.refused()
    monkeypatch.setattr(ses, '_prepare', boom)
    skipped = ses.frames_skipped
    rig.image_pubs['left'].publish(rig.image('left', first + 3))
    rig.image_pubs['right'].publish(rig.image('right', first + 3))
    for topic in (left, right):
        expected[(topic, f'{PAIR_FAILED}: RuntimeError')] = 1
    assert wait_until(lambda: health.refused() == expected, TIMEOUT, spin=executor), \
        health.refused()
    assert ses.frames_skipped == skipped + 1
    monkeypatch.undo()                       # and the node goes on
    fused = ses.frames_fused
    assert _feed(rig, ses, executor) and ses.frames_fused == fused + 1
    assert 'refused: failed on a camera_info: RuntimeError: on fire' in capfd.readouterr().err

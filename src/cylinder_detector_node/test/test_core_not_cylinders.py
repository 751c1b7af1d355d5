"""What must not be reported as a cylinder (issue 31): a box seen across its corner (its two faces
fit a circle of half its width well enough for Eq. 4.4: a real milk carton scored 0.52) and a part
of a larger object (a bottle's handle, which the clustering splits off its body). Small synthetic
clouds in a camera optical frame (y down, table at y = DOWN), ~1 mm noise as a depth camera's."""

from __future__ import annotations

import numpy as np
import pytest

from cylinder_detector_node.core.fitting import (
    FitParams,
    fit_cylinder,
    fit_with_axis,
    refine_axis,
    rotation_to_z,
)
from cylinder_detector_node.core.geometry import normals_and_curvature
from cylinder_detector_node.core.pipeline import detect_cylinders, parts_of_objects
from cylinder_detector_node.core.segmentation import segment_tabletop
from cylinder_detector_node.core.synthetic import axis_angle_deg, make_cylinder

DOWN = 0.5   # m: the table lies this far below the camera
NOISE = 0.001


def table(rng: np.random.Generator) -> np.ndarray:
    return np.column_stack([rng.uniform(-0.5, 0.5, 30000), np.full(30000, DOWN),
                            rng.uniform(0.5, 1.3, 30000)])


def upright(rng: np.random.Generator, n: int, x: float, z: float, r: float, y0: float,
            y1: float) -> np.ndarray:
    """n points on the camera-facing half of an upright cylinder's side between heights y0 > y1
    (y is down), axis through (x, z)."""
    a, t = rng.uniform(np.pi, 2 * np.pi, n), rng.uniform(y1, y0, n)
    return np.column_stack([x + r * np.cos(a), t, z + r * np.sin(a)])


def box_corner(rng: np.random.Generator, n: int, x: float, z: float, half: float,
               height: float) -> np.ndarray:
    """n points on the two faces of an upright square box (side 2 * half) that face the camera
    when its corner points at it (rotated 45 degrees about the vertical); its top is out of view
    (a camera at its mid-height)."""
    d = half * np.sqrt(2.0)                       # centre to corner
    corner = np.array([x, z - d])
    u = rng.uniform(0.0, 1.0, n)
    left = rng.random(n) < 0.5
    end = np.where(left[:, None], [x - d, z], [x + d, z])
    xz = corner + u[:, None] * (end - corner)
    return np.column_stack([xz[:, 0], rng.uniform(DOWN - height, DOWN, n), xz[:, 1]])


def noisy(rng: np.random.Generator, pts: np.ndarray) -> np.ndarray:
    return pts + rng.normal(0.0, NOISE, pts.shape)


@pytest.mark.parametrize('seed', range(3))
def test_a_box_corner_is_no_cylinder_but_a_cylinder_is(seed: int) -> None:
    """A 7 cm square carton 23 cm high seen across its corner: Eq. 4.4 alone passes it (0.52-0.66
    on these seeds; the real carton 0.52) with a circle of about half its width through the faces;
    under half of the faces' normals are within 20 deg of radial, so detect_cylinders refuses it.
    A half-seen cylinder of the same size under the same noise is kept."""
    rng = np.random.default_rng(seed)
    box = noisy(rng, box_corner(rng, 3000, 0.0, 0.9, 0.035, 0.23))
    up = np.array([0.0, -1.0, 0.0])
    eq44 = fit_cylinder(box @ rotation_to_z(up).T, FitParams())
    assert eq44 is not None and eq44.confidence >= 0.5                 # the defect
    assert eq44.normal_agreement < 0.6
    det = detect_cylinders(np.vstack([table(rng), box]))
    assert det.n_clusters == 1 and det.cylinders == []
    assert det.rejected_surface == 1
    assert any('flat faces' in m for m in det.messages)
    cyl = noisy(rng, upright(rng, 3000, 0.0, 0.9, 0.035, DOWN, DOWN - 0.23))
    det = detect_cylinders(np.vstack([table(rng), cyl]))
    assert len(det.cylinders) == 1 and det.rejected_surface == 0
    c = det.cylinders[0]
    assert c.radius == pytest.approx(0.035, rel=0.2)
    assert c.normal_agreement > 0.9


def bottle_with_handle(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A bottle (r 5 cm, 25 cm) and its handle: a vertical bar (r 1.2 cm) 15-23 cm above the
    table, 2.5 cm beside the body (beyond the clustering's 2 cm reach, so a cluster of its own)."""
    body = upright(rng, 6000, 0.0, 0.9, 0.05, DOWN, DOWN - 0.25)
    a, t = rng.uniform(0, 2 * np.pi, 1500), rng.uniform(DOWN - 0.23, DOWN - 0.15, 1500)
    hx = 0.05 + 0.025 + 0.012
    handle = np.column_stack([hx + 0.012 * np.cos(a), t, 0.9 + 0.012 * np.sin(a)])
    handle = handle[handle[:, 2] < 0.9 + 0.004]      # the half the camera sees
    return noisy(rng, body), noisy(rng, handle)


def test_a_handle_beside_its_bottle_is_a_part_not_a_cylinder() -> None:
    rng = np.random.default_rng(0)
    body, handle = bottle_with_handle(rng)
    cloud = np.vstack([table(rng), body, handle])
    seg = segment_tabletop(cloud)
    assert len(seg.clusters) == 2                    # the handle is split off: the defect's cause
    assert seg.plane is not None
    parts = parts_of_objects(seg.clusters, seg.plane, 0.04)
    i_handle = int(np.argmin([len(c.points) for c in seg.clusters]))
    assert parts[i_handle] == 1 - i_handle and parts[1 - i_handle] is None
    det = detect_cylinders(cloud)
    assert det.rejected_parts == 1
    assert len(det.cylinders) == 1                   # the bottle only, not its handle
    assert det.cylinders[0].radius == pytest.approx(0.05, rel=0.1)
    assert any('a handle' in m for m in det.messages)


def test_objects_standing_on_the_table_are_no_parts() -> None:
    """A small cylinder standing beside a tall one (3 cm apart), and one alone off the table (a
    cluster with nothing beside it), stay objects: only a cluster hanging beside another is a
    part."""
    rng = np.random.default_rng(1)
    tall = upright(rng, 6000, 0.0, 0.9, 0.05, DOWN, DOWN - 0.25)
    small = upright(rng, 2000, 0.05 + 0.03 + 0.03, 0.9, 0.03, DOWN, DOWN - 0.08)
    floating = upright(rng, 2000, -0.3, 0.9, 0.03, DOWN - 0.1, DOWN - 0.18)
    cloud = np.vstack([table(rng), noisy(rng, tall), noisy(rng, small), noisy(rng, floating)])
    det = detect_cylinders(cloud)
    assert det.rejected_parts == 0
    radii = sorted(round(c.radius, 2) for c in det.cylinders)
    assert radii == [0.03, 0.03, 0.05]


def test_an_axis_one_accumulator_cell_off_is_refined_from_the_normals() -> None:
    """N_d = 450 cells lie ~10 deg apart: with its axis 9 deg off, a lying pipe's normals look
    tilted from radial (simulated lying pipes fell below 0.7 this way). refine_axis takes the axis
    the side normals are most orthogonal to, and the agreement comes back."""
    rng = np.random.default_rng(4)
    s = make_cylinder(rng, 0.025, 0.28, 3000, 0.0, NOISE, axis=np.array([1.0, 0.0, 0.0]),
                      centre=np.array([0.0, 0.0, 0.9]))
    normals, _, _ = normals_and_curvature(s.points, 15)
    tilt = np.radians(9.0)
    off = np.array([np.cos(tilt), np.sin(tilt), 0.0])
    params = FitParams(radius_min=0.01, radius_max=0.1)
    rough = fit_with_axis(s.points, normals, off, params)
    assert rough is not None and rough.normal_agreement < 0.7
    fine = refine_axis(s.points, normals, rough, params)
    assert fine is not None
    assert axis_angle_deg(np.array(fine.axis), s.axis) < 2.0
    assert fine.normal_agreement > 0.9
    assert fine.radius == pytest.approx(0.025, rel=0.1)

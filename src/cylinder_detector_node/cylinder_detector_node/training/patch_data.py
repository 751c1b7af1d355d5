"""Labelled patches the thesis's way (section 4.3.2): simulated tabletop scenes, our 3D
segmentation, each cluster's image box cut out of the RGB image, labelled by the scene's ground
truth.

Labels: each cluster point goes to the object whose surface is nearest; the cluster takes the
majority object's shape (cylinder or not) and keeps that majority fraction as its purity. Clusters
far from every object (> 3 cm median) or merging objects (purity < MIN_PURITY) are kept with their
purity so callers can drop them.

Alongside each patch: the Eq. 4.4 fit quality of the same cluster (the baseline of Fig. 4.8),
fitted the pipeline's way (table frame, mild prior, no confidence threshold).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cylinder_detector_node.core.accumulator import TABLE_4_1
from cylinder_detector_node.core.classifier import extract_patch
from cylinder_detector_node.core.fitting import (
    FitParams,
    fit_cylinder,
    make_directions,
    rotation_to_z,
)
from cylinder_detector_node.core.segmentation import SegmentParams, segment_tabletop

from .sim_frames import SimFrame

MIN_PURITY = 0.7
MAX_MEDIAN_DISTANCE = 0.03   #: m
SEGMENT = SegmentParams(max_range=3.0)
BASELINE_FIT = FitParams(gmm=TABLE_4_1['mild'], min_confidence=0.0)


@dataclass
class FramePatches:
    patches: NDArray[np.uint8]        #: (N, S, S, 3)
    labels: NDArray[np.int64]         #: 1 cylinder, 0 not
    purity: NDArray[np.float64]
    fit_quality: NDArray[np.float64]  #: Eq. 4.4 N_model / N_cluster (0 when the fit fails)
    names: list[str]                  #: the majority object's name


def label_cluster(frame: SimFrame, pts: NDArray[np.float64],
                  rng: np.random.Generator) -> tuple[int, float, str]:
    """(label, purity, object name) of a cluster: its points vote for the object with the nearest
    surface; purity 0 when the majority object's median distance is above MAX_MEDIAN_DISTANCE."""
    if len(pts) > 200:
        pts = pts[rng.choice(len(pts), 200, replace=False)]
    d = frame.surface_distances(pts)
    counts = np.bincount(np.argmin(d, axis=1), minlength=len(frame.objects))
    j = int(np.argmax(counts))
    if np.median(d[:, j]) > MAX_MEDIAN_DISTANCE:
        return 0, 0.0, ''
    o = frame.objects[j]
    return int(o.is_cylinder), float(counts[j] / len(pts)), o.name


def frame_patches(frame: SimFrame, seed: int = 0) -> FramePatches:
    """Segment the frame, cut every cluster's patch, label it and fit the baseline."""
    rng = np.random.default_rng(seed)
    seg = segment_tabletop(frame.cloud, SEGMENT)
    patches, labels, purity, quality, names = [], [], [], [], []
    if seg.plane is not None and seg.clusters:
        rot = rotation_to_z(seg.plane[:3])
        directions = make_directions(BASELINE_FIT)
        for cl in seg.clusters:
            lab, pur, name = label_cluster(frame, cl.points, rng)
            c = fit_cylinder(cl.points @ rot.T, BASELINE_FIT, directions)
            assert cl.patch is not None   # the frames are organized: every cluster has a box
            patches.append(extract_patch(frame.image, cl.patch))
            labels.append(lab)
            purity.append(pur)
            quality.append(0.0 if c is None else c.confidence)
            names.append(name)
    s = 64 if not patches else patches[0].shape[0]
    return FramePatches(np.stack(patches) if patches else np.zeros((0, s, s, 3), np.uint8),
                        np.asarray(labels, np.int64), np.asarray(purity), np.asarray(quality),
                        names)

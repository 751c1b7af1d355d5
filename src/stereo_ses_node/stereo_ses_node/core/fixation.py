"""The gaze-decision bookkeeping of the stereo_ses node (ROS-free; not thread-safe: the node
holds its lock around every call): saccadic suppression, when the next fixation may be chosen,
the cells not to choose again (refused; inhibition of return), and the next fixation among the
rest."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from stereo_ses_node.core.decision import Decision, choose_fixation, reachable_cells
from stereo_ses_node.core.ses import SensoryEgoSphere

# After a gaze command, frames do not count towards frames_per_fixation until the saccade has
# started (in_saccade seen) or this long has passed (a tiny or refused movement).
SACCADE_START_TIMEOUT_S = 1.0


class FixationPolicy:
    """Saccade state, frames counted since this node's saccade settled, and refused cells."""

    def __init__(self, source: str) -> None:
        self.source = source                          # this node's GazeCommand.source
        self.in_saccade = False
        self.settled_at = -math.inf                   # stamp of the last saccade's end
        self.awaiting_saccade_until = -math.inf       # node-clock deadline after a command
        self.frames_since_settle = 0
        self.last_command = -math.inf                 # node clock [s] (sim time in the graph)
        self.refused: set[int] = set()   # cells not to choose: refused, or fixating gave nothing
        self.fixated: tuple[int, int] | None = None   # (cell, its n_obs) of the last command
        self.own_saccade = False          # the saccade under way is this node's
        self.served = False               # the gaze controller served the last command
        # inhibition of return: (unit direction in the ego frame, node-clock time it ends) of
        # this node's fixations (next_fixation skips cells near them when its angle is > 0)
        self.inhibited: list[tuple[np.ndarray, float]] = []
        # the nearest observed point this node fixated [m] (search_nearest: only nearer ones
        # compete with unobserved space afterwards)
        self.nearest_fixated = math.inf

    def on_gaze_state(self, saccade: bool, active_source: str, stamp: float) -> None:
        """A GazeState: in_saccade, its active_source, its stamp [s]."""
        if saccade:
            self.awaiting_saccade_until = -math.inf
            if active_source == self.source:
                self.own_saccade = True          # our command moves the eyes
                self.served = True
        if self.in_saccade and not saccade:
            # pairs stamped before this were taken before or during the movement
            # (blurred; saccadic suppression)
            self.settled_at = stamp
            if self.own_saccade:
                # our own saccade settled: count the frames of its fixation. Other sources'
                # saccades (the object map's looks every ~1.1 s, foveation's) do not restart
                # the count: their frames are observations too, and restarting on them left
                # this node one decision in 30 s of the deployed graph (issue 26)
                self.own_saccade = False
                self.frames_since_settle = 0
        self.in_saccade = saccade

    def suppressed(self, stamp: float) -> bool:
        """Is a pair stamped stamp [s] taken in a saccade (not to be fused)?"""
        return self.in_saccade or stamp < self.settled_at

    def reset(self) -> None:
        """The ego-sphere was rebuilt: its cells are new."""
        self.refused.clear()
        self.fixated = None
        self.inhibited.clear()
        self.nearest_fixated = math.inf

    def inhibited_directions(self, now: float) -> np.ndarray:
        """(K, 3) unit directions still inhibited at node-clock time now (expired dropped)."""
        self.inhibited = [(d, until) for d, until in self.inhibited if until > now]
        return np.array([d for d, _ in self.inhibited], np.float64).reshape(-1, 3)

    def on_fused(self, now: float, frames_per_fixation: int, n_obs: np.ndarray) -> None:
        """A frame was fused at node-clock time now; n_obs: the cells' observation counts."""
        if now >= self.awaiting_saccade_until:
            self.frames_since_settle += 1
        fixated = self.fixated
        if fixated is not None and self.frames_since_settle >= frames_per_fixation:
            cell, seen = fixated
            self.fixated = None
            if self.served and n_obs[cell] == seen:
                # the fixation gave its cell no observation (the eyes sit in front of ego,
                # so the fixated point may fall in a neighbouring cell): without this, an
                # unobserved cell keeps its prior and would be chosen for ever
                self.refused.add(cell)

    def ready(self, now: float, frames_per_fixation: int, period_s: float) -> bool:
        """May the next fixation be chosen at node-clock time now?"""
        return (not self.in_saccade and now >= self.awaiting_saccade_until
                and self.frames_since_settle >= frames_per_fixation
                and now - self.last_command >= period_s)

    def fixating(self, now: float, cell: int, ses: SensoryEgoSphere, point: np.ndarray,
                 p: Mapping[str, Any]) -> None:
        """A command to fixate point (ego frame), chosen for cell of ses under the node's
        parameters p, went out at now: commanded(), and the nearest observed point fixated."""
        self.commanded(now, cell, int(ses.n_obs[cell]), ses.directions[cell],
                       float(p['inhibition_of_return_s']))
        if ses.n_frames[cell] >= observed_frames(p):
            self.nearest_fixated = min(self.nearest_fixated, float(np.linalg.norm(point)))

    def commanded(self, now: float, cell: int, n_obs: int, direction: np.ndarray | None = None,
                  inhibit_s: float = 0.0) -> None:
        """A command to fixate cell (n_obs observations so far, its ego-frame direction) went
        out at now; the direction stays inhibited for inhibit_s."""
        self.last_command = now
        if direction is not None and inhibit_s > 0:
            d = np.asarray(direction, np.float64)
            self.inhibited.append((d / max(float(np.linalg.norm(d)), 1e-12), now + inhibit_s))
        self.awaiting_saccade_until = now + SACCADE_START_TIMEOUT_S
        self.frames_since_settle = 0
        self.fixated = (cell, n_obs)
        self.served = False          # a pre-empted command fixated nothing: no refusal


def fixation_candidates(means: np.ndarray, directions: np.ndarray, min_z: float,
                        azimuth_limit: float, elevation_limits: tuple[float, float],
                        refused: list[int], inhibited: np.ndarray | None = None,
                        inhibition_rad: float = 0.0) -> np.ndarray:
    """Cells that may be fixated: mean above min_z [m], reachable (angles [rad]), not refused,
    and (inhibition of return) not within inhibition_rad of an inhibited (K, 3) unit
    direction."""
    candidates = (means[:, 2] >= min_z) & reachable_cells(directions, azimuth_limit,
                                                           elevation_limits)
    candidates[refused] = False
    if inhibited is not None and len(inhibited) and inhibition_rad > 0:
        near = directions @ np.asarray(inhibited, np.float64).T >= math.cos(inhibition_rad)
        candidates &= ~near.any(axis=1)
    return candidates


def clamp_distance(point: np.ndarray, dmin: float, dmax: float) -> np.ndarray:
    """point moved along its direction into [dmin, dmax] of distance."""
    dist = float(np.linalg.norm(point))
    return point * (min(max(dist, dmin), dmax) / max(dist, 1e-9))


def observed_frames(p: Mapping[str, Any]) -> int:
    """The fused frames a cell must be seen in to count as observed (min_observations, at
    least 1): fewer, and next_fixation scores it as never seen."""
    return max(int(p.get('min_observations', 1)), 1)


def next_fixation(ses: SensoryEgoSphere, p: Mapping[str, Any], refused: list[int],
                  inhibited: np.ndarray | None = None,
                  nearer_than: float = math.inf) -> tuple[Decision, np.ndarray] | None:
    """(the cell the node's parameters p choose among the reachable cells above min_z_m not in
    refused nor within inhibition_of_return_deg of an inhibited direction, its fixation point
    moved into fixation_distance_m), or None: no cell to fixate. With p['search_nearest'], an
    observed cell competes only if it lies nearer than nearer_than [m] (the nearest point
    fixated so far): a search for the nearest object looks again only where it can improve on
    what it has seen, and at unobserved space otherwise."""
    el = np.radians(p['elevation_limits_deg'])
    candidates = fixation_candidates(ses.mean, ses.directions, p['min_z_m'],
                                     math.radians(p['azimuth_limit_deg']), (el[0], el[1]),
                                     refused, inhibited,
                                     math.radians(p.get('inhibition_of_return_deg', 0.0)))
    if not np.any(candidates):
        return None
    means, covs = ses.mean, ses.cov
    least = observed_frames(p)
    observed = ses.n_frames >= least
    if least > 1:
        # a cell seen in fewer frames is scored as never seen (stereo mismatches 0.4-0.9 m in
        # front of the eyes, from one fixation's frames, would otherwise be the nearest thing
        # there is; a surface stays in the 85 deg field of view over several fixations)
        few = (ses.n_frames > 0) & (ses.n_frames < least)
        if np.any(few):
            means, covs = means.copy(), covs.copy()
            means[few] = float(p['prior_distance_m']) * ses.directions[few]
            covs[few] = np.eye(3) * float(p['prior_sigma_m']) ** 2
    if p.get('search_nearest', False) and math.isfinite(nearer_than):
        candidates = candidates & ~(observed & (np.linalg.norm(ses.mean, axis=1) >= nearer_than))
        if not np.any(candidates):
            return None
    decision = choose_fixation(means, covs, p['acquisition'], float(p['ucb_alpha']),
                               candidates=candidates)
    coverage = math.radians(float(p.get('explore_coverage_deg', 0.0)))
    if coverage > 0 and not observed[decision.cell]:
        decision = widest_unobserved(ses.directions, means, candidates & ~observed, coverage)
    point = decision.fixation
    radius = float(p.get('fixation_cluster_m', 0.0))
    if radius > 0 and observed[decision.cell]:
        point = cluster_centre(ses.mean, observed, point, radius)
    dmin, dmax = p['fixation_distance_m']
    return decision, clamp_distance(point, dmin, dmax)


def widest_unobserved(directions: np.ndarray, means: np.ndarray, unobserved: np.ndarray,
                      radius: float, samples: int = 256) -> Decision:
    """Among the unobserved candidate cells (a boolean mask, not empty), the one with the most
    unobserved candidates within radius [rad] of its direction (the widest unexplored view, of
    up to `samples` evenly spread candidates): unobserved cells all score alike under UCB, and
    their index order sends the eyes to arbitrary directions, ceiling included."""
    idx = np.flatnonzero(unobserved)
    pick = idx if idx.size <= samples else idx[np.linspace(0, idx.size - 1, samples).astype(int)]
    counts = (directions[pick] @ directions[idx].T >= math.cos(radius)).sum(axis=1)
    cell = int(pick[int(np.argmax(counts))])
    return Decision(cell, means[cell].copy(), float(counts.max()))


def cluster_centre(means: np.ndarray, observed: np.ndarray, point: np.ndarray,
                   radius: float, iterations: int = 3) -> np.ndarray:
    """The middle of the surface a chosen cell lies on, not its edge: a few mean-shift steps
    (flat kernel of radius [m]) over the observed cell means from point (a cell's mean is one
    surface point; a can 0.5 m away spans 7 x 14 deg, so a cell on its rim is 6-7 deg off its
    middle)."""
    seen = means[observed]
    for _ in range(iterations):
        near = np.linalg.norm(seen - point, axis=1) <= radius
        if not np.any(near):
            break
        point = seen[near].mean(axis=0)
    return point

"""The self-collision stage (docs/method.md §4.2): candidates kept across steps (fraytool.collision.candidates),
proximity pass, interval CCD passes with the inelastic response, and the failsafe
(fraytool.sim.kernels.self_collision). See docs/self-collision.md.
"""
from __future__ import annotations

import numpy as np

from fraytool.collision.broadphase import candidate_pairs_of_segments_kernel
from fraytool.collision.candidates import (
    check_candidates,
    escaped_segments,
    inflate_boxes,
    merge_pairs,
    particle_reach,
    reattached_pairs,
    rebox_segments,
    segment_boxes,
    update_reach,
)
from fraytool.collision.narrow import ccd_pairs
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.kernels.self_collision import freeze_pairs, repel_close_pairs, respond_pairs
from fraytool.sim.model import Model

CONTACT_FRACTION = 0.5
"""d_c = CONTACT_FRACTION x thickness."""
SLACK_FRACTION = 0.25
"""Broad-phase slack = SLACK_FRACTION x spacing (fraytool.collision.candidates)."""
LOOKAHEAD_STEPS = 3.0
"""A build sweeps every segment on to x + LOOKAHEAD_STEPS (x - x_prev) (fraytool.collision.candidates)."""
REBOX_LIMIT = 64
"""More segments out of their slack at once than this start a full build instead of re-boxing them."""
PATCH_LIMIT = 512
"""More segments touching re-attached end particles at once than this start a full build instead."""


def yarn_segment_ids(model: Model) -> np.ndarray:
    """Yarn id of every spring slot: weft yarn j -> j, warp yarn i -> weft_yarns + i, others -1."""
    yarn = model.spring_yarn()
    assert ((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)).sum() == (yarn >= 0).sum()
    return yarn


class SelfCollision:
    """The self-collision stage: detect (broad + interval CCD), respond, repeat up to a cap."""

    name = "self_collision"
    kernel = "ccd_pairs"

    def __init__(self, model: Model):
        self.model = model
        self.spring_yarn = yarn_segment_ids(model)
        self.contact_distance_m = CONTACT_FRACTION * model.thickness_m
        self.iterations = model.self_collision_iterations
        self.slack_m = SLACK_FRACTION * model.spacing_m
        """Extra broad-phase margin: candidates stay valid while no end point leaves its box by more."""
        self.margin_m = 0.5 * self.contact_distance_m + self.slack_m
        self.friction = model.self_collision_friction
        self.yarn_segments = np.nonzero(self.spring_yarn >= 0)[0].astype(np.int32)
        self._cand = None
        self._box_lo = self._box_hi = None
        self._inflated = None
        """Build boxes inflated by the margin, (M, 6)."""
        self._reach = None
        """Per particle, the box it may stay in (``particle_reach``), (P, 6)."""
        self._ends = None
        """End particles of every yarn segment at the build or the last patch, (M, 2) int32."""
        self._alive = None
        """Yarn segments alive at the build."""
        self.broad_phase_builds = 0
        self.broad_phase_patches = 0
        """Candidate patches after re-attachments (module docstring, "Candidates")."""
        self.broad_phase_reboxes = 0
        """Partial updates for segments that left their slack (module docstring, "Candidates")."""
        self.pairs_last = 0
        """Crossing pairs found by the first CCD pass of the last step."""
        self.proximity_last = 0
        """Pairs pushed apart by the proximity pass of the last step."""
        self.proximity_total = 0
        self.pairs_total = 0
        self.cap_hits = 0
        """Steps that still had colliding pairs after the last pass."""

    def _build(self, state, prev_position_m) -> None:
        """Broad phase on the segments swept from x_prev to the look-ahead x + LOOKAHEAD_STEPS (x - x_prev),
        boxes inflated by d_c/2 + slack (module docstring, "Candidates")."""
        x = state.particle_position_m
        a, b = state.spring_particle_a, state.spring_particle_b
        ahead = x + LOOKAHEAD_STEPS * (x - prev_position_m)
        self._cand = candidate_pairs_of_segments_kernel(prev_position_m, ahead, a, b, state.spring_alive,
                                                        self.yarn_segments, self.margin_m, 0.0)
        self._box_lo, self._box_hi = segment_boxes(prev_position_m, ahead, a, b, self.yarn_segments)
        self._inflated = inflate_boxes(self._box_lo, self._box_hi, self.margin_m)
        self._ends = np.stack([a[self.yarn_segments], b[self.yarn_segments]], axis=1)
        self._alive = state.spring_alive[self.yarn_segments]
        self.broad_phase_builds += 1

    def _ensure_valid(self, state, prev_position_m) -> None:
        """Keep, re-box, patch or build the candidates (module docstring, "Candidates")."""
        x = state.particle_position_m
        a, b, alive = state.spring_particle_a, state.spring_particle_b, state.spring_alive
        if self._cand is not None and check_candidates(prev_position_m, x, a, b, alive, self.yarn_segments,
                                                       self._reach, self._ends, self._alive):
            return
        if self._cand is None:
            self._build(state, prev_position_m)
        else:
            escaped = escaped_segments(prev_position_m, x, a, b, alive, self.yarn_segments, self._box_lo,
                                       self._box_hi, self.slack_m, self._alive)
            touched = np.zeros(x.shape[0], np.bool_)
            if len(escaped) > REBOX_LIMIT:
                self._build(state, prev_position_m)
                touched = None
            elif len(escaped):
                self._cand = rebox_segments(prev_position_m, x, a, b, alive, self.yarn_segments, escaped,
                                            LOOKAHEAD_STEPS, self.margin_m, self._box_lo, self._box_hi,
                                            self._inflated, self._alive, self._cand)
                touched[a[self.yarn_segments[escaped]]] = True
                touched[b[self.yarn_segments[escaped]]] = True
                self.broad_phase_reboxes += 1
            ends = np.stack([a[self.yarn_segments], b[self.yarn_segments]], axis=1)
            changed = np.nonzero(np.any(ends != self._ends, axis=1) & alive[self.yarn_segments])[0]
            if touched is not None and len(changed):
                extra, ok = reattached_pairs(a, b, alive, self.yarn_segments, self._ends, self._inflated,
                                             x.shape[0], PATCH_LIMIT)
                if ok:
                    self._cand = merge_pairs(self._cand, extra)
                    touched[self._ends[changed].ravel()] = True
                    touched[ends[changed].ravel()] = True
                    self._ends = ends
                    self.broad_phase_patches += 1
                else:
                    self._build(state, prev_position_m)
                    touched = None
            if touched is not None and not len(escaped) and not len(changed):
                touched = None  # the check failed for another reason (a segment cut since): start afresh
            if touched is not None:
                update_reach(self._reach, touched, a, b, alive, self.yarn_segments, self._box_lo, self._box_hi,
                             self.slack_m)
                return
        self._reach = particle_reach(a, b, alive, self.yarn_segments, self._box_lo, self._box_hi, self.slack_m,
                                     x.shape[0])

    def __call__(self, state, prev_position_m: np.ndarray, dt_s: float) -> None:
        x = state.particle_position_m
        a, b, w, alive = state.spring_particle_a, state.spring_particle_b, state.particle_inv_mass, state.spring_alive
        self._ensure_valid(state, prev_position_m)
        self.proximity_last, left = repel_close_pairs(self.contact_distance_m, self.friction, prev_position_m,
                                                      self._cand, a, b, alive, w, self._reach, x)
        self.proximity_total += self.proximity_last
        self.pairs_last = 0
        moved = None  # first pass: every candidate
        for it in range(self.iterations + 1):
            if left:  # a correction moved an end point out of its reach: candidates may change
                self._ensure_valid(state, prev_position_m)
                moved = None
            pairs, t = ccd_pairs(prev_position_m, x, self._cand, a, b, alive, moved)
            if it == 0:
                self.pairs_last = len(pairs)
                self.pairs_total += len(pairs)
            if len(pairs) == 0:
                return
            if it == self.iterations:
                break
            before = x.copy()
            _, left = respond_pairs(self.contact_distance_m, self.friction, prev_position_m, pairs, t, a, b, w,
                                    self._reach, x)
            moved = np.any(x != before, axis=1)  # later passes test only pairs these particles touch
        self.cap_hits += 1
        while len(pairs):  # each round returns more particles to where they started: it ends
            freeze_pairs(pairs, a, b, w, prev_position_m, x)
            self._ensure_valid(state, prev_position_m)
            pairs, _ = ccd_pairs(prev_position_m, x, self._cand, a, b, alive)

    def run(self, state, buffers, dt_s: float) -> None:
        self(state, buffers.prev_position_m, dt_s)

    def summary(self, state=None) -> dict:
        return {"self_collision_pairs": self.pairs_total, "self_collision_proximity_pushes": self.proximity_total,
                "self_collision_cap_hits": self.cap_hits}

"""The self-collision stage (docs/method.md §4.2): candidates kept across steps (fraytool.collision.candidates),
proximity pass, interval CCD passes with the inelastic response, and the failsafe
(fraytool.sim.kernels.self_collision). See docs/self-collision.md.

Results independent of the kept candidates
------------------------------------------
Every pass acts on the pairs in the sorted order of the candidate list (spring index pairs i < j),
and while every particle is within its reach the list holds every pair a pass can act on
(fraytool.collision.candidates). Which *extra* pairs it holds depends on when it was built, so the
stage makes sure that never matters: the proximity pass stops as soon as a correction moves a
particle out of its reach, the stage checks the candidates, and the pass goes on after the same
pair; the CCD passes run on checked candidates (a pass limited to the pairs touching moved particles
finds the same hits as a full one). A run resumed from a checkpoint, which builds its candidates
afresh, therefore gives the same frames, bit for bit, as an unbroken run.

Failsafe
--------
Pairs still crossing after the last response pass go back to their start-of-step positions, round
after round (``freeze_pairs``). It ends by itself: a round that moves no particle ends it (every free
end of the remaining pairs is already back), and otherwise it returns at least one more particle to
its start position for good, so it cannot run more rounds than there are particles. That bound is
thousands of full CCD passes, so the loop stops after FAILSAFE_ROUNDS rounds and the stage *gives
up* on the step: every free particle goes back to its start-of-step position. Then no segment of
free particles moves, so none passes through another (the CCD, conservative, could still report a
pair already touching at the step start); only segments with ends held by bodies can still pass
through something, which no reset of cloth particles can prevent (a give-up without progress
leaves the rest of the cloth alone: resetting it would not help). A give-up is counted
(``self_collision_failsafe_give_ups`` in the summary) and the first one of a run prints one line on
stderr.
"""
from __future__ import annotations

import sys

import numpy as np

from fraytool.collision.broadphase import candidate_pairs_of_segments_kernel
from fraytool.collision.candidates import (
    check_candidates,
    escaped_segments,
    inflate_boxes,
    merge_pairs,
    movable_pairs,
    pair_segments,
    particle_reach,
    reattached_pairs,
    reattached_segments,
    rebox_segments,
    segment_boxes,
    update_reach,
)
from fraytool.collision.narrow import ccd_pairs, ccd_pairs_all
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.kernels.self_collision import (LEVER_MAX, freeze_pairs, mark_close_pairs, repel_close_pairs,
                                                 respond_pairs)
from fraytool.sim.model import Model
from fraytool.sim.stages.base import POSITIONS, SELF_CONTACT, SLAVED, START_POSITIONS, TOPOLOGY

CONTACT_FRACTION = 0.5
"""d_c = CONTACT_FRACTION x thickness."""
SLACK_FRACTION = 0.15
"""Broad-phase slack = SLACK_FRACTION x spacing (fraytool.collision.candidates). Results do not depend
on it (module docstring); only the cost does: a larger slack keeps the candidates valid longer but
holds more pairs, which every pass of every step tests. Self-collision stage over the full shots
(ms per frame, 0.25 / 0.2 / 0.15): fig5_corner_grab 25 / 19 / 17, fig7_square_grab 46 / 36 / 35."""
LOOKAHEAD_STEPS = 3.0
"""A build sweeps every segment on to x + LOOKAHEAD_STEPS (x - x_prev) (fraytool.collision.candidates)."""
REBOX_LIMIT = 64
"""More segments out of their slack at once than this start a full build instead of re-boxing them."""
PATCH_LIMIT = 512
"""More segments touching re-attached end particles at once than this start a full build instead."""
FAILSAFE_ROUNDS = 16
"""Rounds of the failsafe per step before the stage gives up on the step (module docstring,
"Failsafe"). Each round returns the free ends of the still-crossing pairs to their start positions;
a new crossing in the next round needs a segment with one end returned and one still moving, so
the returned zone grows by about one segment along the yarns per round and the loop ends once it
reaches segments that cross nothing. Measured over the full shots with self-collision on: at most
4 rounds on fig5_corner_grab and fig7_square_grab (452 and 345 failsafe steps), also on fig7 with
`iterations = 1` (over 1300 failsafe steps); no failsafe step at all on fig6 (plain, twill) or
fold_pile. 16 is four times the worst seen, and bounds a step at 16 more full CCD passes plus
one for giving up."""


def yarn_segment_ids(model: Model) -> np.ndarray:
    """Yarn id of every spring slot: weft yarn j -> j, warp yarn i -> weft_yarns + i, others -1."""
    yarn = model.spring_yarn()
    assert ((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)).sum() == (yarn >= 0).sum()
    return yarn


class SelfCollision:
    """The self-collision stage: detect (broad + interval CCD), respond, repeat up to a cap."""

    name = "self_collision"
    kernel = "ccd_pairs"
    reads = frozenset({POSITIONS, START_POSITIONS, SLAVED, TOPOLOGY})
    writes = frozenset({POSITIONS})

    def __init__(self, model: Model):
        self.model = model
        self.contact_distance_m = CONTACT_FRACTION * model.thickness_m
        self.iterations = model.self_collision_iterations
        self.slack_m = SLACK_FRACTION * model.spacing_m
        """Extra broad-phase margin: candidates stay valid while no end point leaves its box by more."""
        self.margin_m = 0.5 * self.contact_distance_m + self.slack_m
        self.friction = model.self_collision_friction
        self._response = (self.friction, LEVER_MAX if model.coarse_factor > 1 else np.inf)
        """The corrections' (friction, lever bound) (fraytool.sim.kernels.self_collision.LEVER_MAX)."""
        self.yarn_segments = np.nonzero(yarn_segment_ids(model) >= 0)[0].astype(np.int32)
        self._box_row = np.full(model.spring_count, -1, np.int32)
        """Spring slot -> its row in ``_box`` (yarn segments only; the kernels' ``box_row``)."""
        self._box_row[self.yarn_segments] = np.arange(self.yarn_segments.shape[0], dtype=np.int32)
        self._cand = None
        self._box_lo = self._box_hi = None
        self._inflated = None
        """Build boxes inflated by the margin, (M, 6)."""
        self._reach = None
        """Per particle, the box it may stay in (``particle_reach``), (P, 6)."""
        self._reached = np.zeros(0, np.int64)
        """The particles whose reach may be bounded (a superset of those with a bounded reach): the check tests
        these only."""
        self._reached_mask = np.zeros(0, np.bool_)
        """``_reached`` as a mask over particle slots (a re-box adds to it without sorting the list again)."""
        self._segments_at = None
        """State.topology_epoch when the check's segment part last passed (``_ensure_valid``)."""
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
        self.failsafe_rounds_max = 0
        """Most failsafe rounds in one step."""
        self.failsafe_give_ups = 0
        """Steps on which the failsafe gave up (module docstring, "Failsafe")."""
        self.failsafe_crossing_left = 0
        """Pairs the CCD still finds crossing at the end of those steps, summed (ends held by bodies, or
        contact at the step start)."""
        self.warned = False
        """The first give-up of the run printed its warning."""
        self._box = self._dirty = self._changed = self._before = self._flag = None
        """Scratch of the kernels, kept across steps (``_scratch``); ``_box`` has a row per yarn segment."""
        self._segs = self._segs_of = None
        """The spring slots in the candidates ``self._segs_of`` (``_pair_segments``)."""
        self._coarse = model.coarse_factor > 1
        if self._coarse:
            self.writes = self.writes | {SELF_CONTACT}
        self._skip_fixed = self._coarse
        """The passes leave out the pairs nothing can move (``_worked``): a coarse model's slaved crossings
        have inverse mass 0, and most of a coarse garment's candidates join two slaved segments."""
        self._work = None
        self._work_of = (None, -1)
        """``_worked``'s list, and the candidates and topology epoch it was made from."""

    def _scratch(self, state) -> None:
        """(Re)allocate the kernels' scratch when the particle or spring slot count changed."""
        p, s = state.particle_position_m.shape[0], state.spring_particle_a.shape[0]
        if self._box is None or self._flag.shape[0] != s or self._dirty.shape[0] != p:
            self._box = np.empty((self.yarn_segments.shape[0], 6))
            self._dirty = np.zeros(p, np.bool_)
            self._changed = np.zeros(p, np.bool_)
            self._before = np.empty((p, 3))
            self._flag = np.zeros(s, np.bool_)

    def _worked(self, state) -> np.ndarray:
        """The candidates the passes look at: all of them, or in a coarse model those with an end particle of
        inverse mass > 0 (``movable_pairs``; a pair of two segments whose ends are all slaved or held moves in no
        pass, so leaving it out changes no position). Inverse masses change with the topology epoch only
        (fraytool.sim.kernels.work_split.ParticleLists)."""
        if not self._skip_fixed:
            return self._cand
        if self._work_of[0] is not self._cand or self._work_of[1] != state.topology_epoch:
            self._work = movable_pairs(self._cand, state.spring_particle_a, state.spring_particle_b,
                                       state.particle_inv_mass)
            self._work_of = (self._cand, state.topology_epoch)
        return self._work

    def _pair_segments(self, state) -> np.ndarray:
        """The spring slots in the candidates the passes look at, each once: the segments whose boxes they use."""
        work = self._worked(state)
        if self._segs_of is not work:
            self._segs = pair_segments(work, self._flag)
            self._segs_of = work
        return self._segs

    def _ccd(self, state, prev_position_m, moved=None):
        """CCD pass on the candidates (all of them, or those touching ``moved`` particles)."""
        x, a, b, alive = state.particle_position_m, state.spring_particle_a, state.spring_particle_b, state.spring_alive
        if moved is None:
            return ccd_pairs_all(prev_position_m, x, self._worked(state), a, b, alive, self._pair_segments(state),
                                 self._box_row, self._box)
        return ccd_pairs(prev_position_m, x, self._worked(state), a, b, alive, moved)

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
        """Keep, re-box, patch or build the candidates (module docstring, "Candidates"). The segments' part of
        the check (alive and end particles as at the build) runs only after a change of topology: every path
        below leaves it passing (the candidates then hold the segments as they are)."""
        self._renew(state, prev_position_m)
        self._segments_at = state.topology_epoch

    def _renew(self, state, prev_position_m) -> None:
        x = state.particle_position_m
        a, b, alive = state.spring_particle_a, state.spring_particle_b, state.spring_alive
        if self._cand is not None and check_candidates(prev_position_m, x, a, b, alive, self.yarn_segments,
                                                       self._reach, self._ends, self._alive, self._reached,
                                                       state.topology_epoch != self._segments_at):
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
                self._cand = rebox_segments(prev_position_m, x, (a, b, alive), self.yarn_segments, escaped,
                                            LOOKAHEAD_STEPS, self.margin_m,
                                            (self._box_lo, self._box_hi, self._inflated, self._alive), self._cand)
                touched[a[self.yarn_segments[escaped]]] = True
                touched[b[self.yarn_segments[escaped]]] = True
                self.broad_phase_reboxes += 1
            changed = reattached_segments(a, b, alive, self.yarn_segments, self._ends)
            if touched is not None and len(changed):
                ends = np.stack([a[self.yarn_segments], b[self.yarn_segments]], axis=1)
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
                if self._reached_mask.shape[0] < touched.shape[0]:
                    self._reached_mask = np.concatenate(
                        [self._reached_mask, np.zeros(touched.shape[0] - self._reached_mask.shape[0], np.bool_)])
                self._reached_mask[:touched.shape[0]] |= touched
                self._reached = np.flatnonzero(self._reached_mask).astype(np.int64)
                return
        self._reach = particle_reach(a, b, alive, self.yarn_segments, self._box_lo, self._box_hi, self.slack_m,
                                     x.shape[0])
        self._reached_mask = np.isfinite(self._reach).any(axis=1)
        self._reached = np.flatnonzero(self._reached_mask).astype(np.int64)

    def _proximity(self, state, prev_position_m) -> int:
        """The proximity pass over the candidates, in their order; when a correction moves a particle
        out of its reach, check the candidates and go on after the same pair (module docstring)."""
        x = state.particle_position_m
        a, b, w, alive = state.spring_particle_a, state.spring_particle_b, state.particle_inv_mass, state.spring_alive
        total, first = 0, 0
        while True:
            work = self._worked(state)
            moved, stop = repel_close_pairs(self.contact_distance_m, self._response, prev_position_m, work,
                                            first, (a, b, alive), w, self._reach, x,
                                            (self._pair_segments(state), self._box_row), (self._box, self._dirty))
            total += moved
            if stop < 0:
                return total
            n = np.int64(self.model.spring_count)
            last = np.int64(work[stop, 0]) * n + work[stop, 1]
            self._ensure_valid(state, prev_position_m)
            work = self._worked(state)
            keys = work[:, 0].astype(np.int64) * n + work[:, 1]
            first = int(np.searchsorted(keys, last, side="right"))

    def __call__(self, state, prev_position_m: np.ndarray, dt_s: float) -> None:
        x = state.particle_position_m
        a, b, w = state.spring_particle_a, state.spring_particle_b, state.particle_inv_mass
        self._scratch(state)
        self._ensure_valid(state, prev_position_m)
        self.proximity_last = self._proximity(state, prev_position_m)
        self.proximity_total += self.proximity_last
        self.pairs_last = 0
        left = False  # every particle is within its reach after the proximity pass
        moved = None  # first pass: every candidate
        for it in range(self.iterations + 1):
            if left:  # a correction moved an end point out of its reach: candidates may change
                self._ensure_valid(state, prev_position_m)
                moved = None
            pairs, t = self._ccd(state, prev_position_m, moved)
            if it == 0:
                self.pairs_last = len(pairs)
                self.pairs_total += len(pairs)
            if len(pairs) == 0:
                return
            if it == self.iterations:
                break
            _, left = respond_pairs(self.contact_distance_m, self._response, prev_position_m, pairs, t, a, b, w,
                                    self._reach, x, self._changed, self._before)
            moved = self._changed  # later passes test only pairs these particles touch
        self.cap_hits += 1
        self._failsafe(state, prev_position_m, dt_s, pairs)

    def _failsafe(self, state, prev_position_m, dt_s: float, pairs) -> None:
        """Return crossing pairs to their start positions, at most FAILSAFE_ROUNDS rounds; then give
        up: every free particle back to its start (module docstring, "Failsafe")."""
        x = state.particle_position_m
        a, b, w = state.spring_particle_a, state.spring_particle_b, state.particle_inv_mass
        rounds = 0
        progress = True
        while len(pairs) and rounds < FAILSAFE_ROUNDS:
            if not freeze_pairs(pairs, a, b, w, prev_position_m, x):
                progress = False  # every free end of these pairs is back already: nothing more to do here
                break
            rounds += 1
            self._ensure_valid(state, prev_position_m)
            pairs, _ = self._ccd(state, prev_position_m)
        self.failsafe_rounds_max = max(self.failsafe_rounds_max, rounds)
        if not len(pairs):
            return
        crossing = len(pairs)
        if progress:  # the cap: give up on the step
            free = w > 0.0
            x[free] = prev_position_m[free]
            self._ensure_valid(state, prev_position_m)
            pairs, _ = self._ccd(state, prev_position_m)
            action = (f"every free particle went back to its start-of-step position ({len(pairs)} pairs "
                      f"still cross: ends held by bodies, or contact at the step start)")
        else:
            action = ("their free ends are back at their start-of-step positions already, so ends held by "
                      "bodies (or contact at the step start) make them cross")
        self.failsafe_give_ups += 1
        self.failsafe_crossing_left += len(pairs)
        if not self.warned:
            self.warned = True
            print(f"fraytool: warning: self-collision failsafe gave up at step {state.step_index + 1} "
                  f"(t = {state.time_s + dt_s:.6g} s) with {crossing} pairs still crossing after {rounds} "
                  f"round{'' if rounds == 1 else 's'}; "
                  f"{action}; later give-ups are only counted (self_collision_failsafe_give_ups)", file=sys.stderr)

    def contact_particles(self, state) -> np.ndarray:
        """Particle slots at the ends of yarn segments lying closer than twice the contact distance to
        another segment (among the last candidate pairs): where the cloth touches itself, shape
        (particle_count,), bool."""
        out = np.zeros(state.particle_position_m.shape[0], np.bool_)
        if self._cand is not None and self._cand.shape[0]:
            mark_close_pairs(self._cand, (state.spring_particle_a, state.spring_particle_b, state.spring_alive),
                             state.particle_inv_mass, state.particle_position_m, 2.0 * self.contact_distance_m, False,
                             out)
        return out

    def run(self, state, ctx, dt_s: float) -> None:
        self(state, ctx.prev_position_m, dt_s)
        if self._coarse:
            self._mark_self_contact(state, ctx.coarse)

    def _mark_self_contact(self, state, coarse) -> None:
        """For the Refinement stage (docs/multires.md, "When a cell refines", self-contact): the particles of
        inverse mass 0 at the ends of candidate pairs closer than the contact distance at the end of the step, in
        coarse.self_contact (none once every cell is refined)."""
        n = state.particle_position_m.shape[0]
        if coarse.self_contact is None or coarse.self_contact.shape[0] != n:
            coarse.self_contact = np.zeros(n, np.bool_)
        else:
            coarse.self_contact[:] = False
        if self._cand is not None and self._cand.shape[0] and not state.coarse_cell_refined.all():
            mark_close_pairs(self._cand, (state.spring_particle_a, state.spring_particle_b, state.spring_alive),
                             state.particle_inv_mass, state.particle_position_m, self.contact_distance_m, True,
                             coarse.self_contact)

    def summary(self, state=None) -> dict:
        return {"self_collision_pairs": self.pairs_total, "self_collision_proximity_pushes": self.proximity_total,
                "self_collision_cap_hits": self.cap_hits,
                "self_collision_failsafe_rounds_max": self.failsafe_rounds_max,
                "self_collision_failsafe_give_ups": self.failsafe_give_ups,
                "self_collision_failsafe_crossings_left": self.failsafe_crossing_left}

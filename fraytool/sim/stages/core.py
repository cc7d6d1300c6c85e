"""The stages every cloth runs (docs/method.md §4): forces, velocity and position updates, damping,
attachments, strain limiting (§4.1), rigid-body contact (§4.3) and the velocity post-process.

Each stage unpacks the model's arrays once, at construction, and calls one numba kernel per run
(kernels take arrays only; fraytool.sim.kernels)."""
from __future__ import annotations

from typing import Optional

import numpy as np

from fraytool.kinds import MOTION_DYNAMIC, SHAPE_MESH
from fraytool.sim.kernels.attachments import apply_attachments
from fraytool.sim.kernels.bodies import bodies_in
from fraytool.sim.kernels.damping import pbd_damping, pbd_damping_pieces
from fraytool.sim.kernels.forces import accumulate_spring_forces
from fraytool.sim.kernels.integrate import (
    integrate_positions,
    integrate_velocities,
    velocities_from_positions,
)
from fraytool.sim.kernels.pieces import label_pieces
from fraytool.sim.kernels.rigid_contact import collide_rigid
from fraytool.sim.kernels.strain_limit import damp_overstretched, limit_strain_groups, limit_strain_lines
from fraytool.sim.model import Model
from fraytool.sim.rigid import advance_bodies, apply_cloth_impulse
from fraytool.sim.stages.base import (BODIES, FORCES, HANGING, POSITIONS, START_POSITIONS, TOPOLOGY, VELOCITIES,
                                      StepContext)
from fraytool.sim.state import State


def colour_ordered_structural_springs(model: Model) -> np.ndarray:
    """Slots of the structural springs grouped by colour: weft springs (i, i+1) with i even, then
    i odd, then warp springs (j, j+1) with j even, then j odd; ascending slots inside a group."""
    return colour_groups(model)[0]


def colour_groups(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """colour_ordered_structural_springs and the start of each colour group in it (+ the end)."""
    weft = model.weft_structural_spring
    warp = model.warp_structural_spring
    groups = [weft[:, 0::2], weft[:, 1::2], warp[:, 0::2], warp[:, 1::2]]
    groups = [g[g >= 0] for g in groups]  # (-1: no spring at that place of a shaped panel)
    springs = np.concatenate([np.sort(g.ravel()) for g in groups]).astype(np.int32)
    starts = np.concatenate([[0], np.cumsum([g.size for g in groups])]).astype(np.int64)
    return springs, starts


def yarn_line_springs(model: Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The structural springs yarn by yarn for `limit_strain_lines`: (springs in order along each
    yarn, weft yarns first; start of each yarn in that list (+ the end); start of each line group:
    [0, weft yarns, weft + warp yarns])."""
    weft = model.weft_structural_spring
    warp = model.warp_structural_spring
    springs = np.concatenate([weft.ravel(), warp.ravel()]).astype(np.int32)
    starts = np.concatenate([np.arange(weft.shape[0]) * weft.shape[1],
                             weft.size + np.arange(warp.shape[0] + 1) * warp.shape[1]]).astype(np.int64)
    groups = np.array([0, weft.shape[0], weft.shape[0] + warp.shape[0]], np.int64)
    if (springs < 0).any():  # a shaped panel: a yarn's runs between the gaps are lines of their own
        return _working_runs(springs, starts, groups, springs >= 0)
    return springs, starts, groups


def _working_runs(springs: np.ndarray, starts: np.ndarray, groups: np.ndarray,
                  keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lines of `yarn_line_springs` cut into maximal runs of consecutive kept springs."""
    line_of = np.repeat(np.arange(starts.shape[0] - 1), np.diff(starts))
    kept = np.flatnonzero(keep)
    first = np.ones(kept.shape[0], bool)
    first[1:] = (kept[1:] != kept[:-1] + 1) | (line_of[kept[1:]] != line_of[kept[:-1]])
    run_start = np.flatnonzero(first)
    run_line = line_of[kept[run_start]]
    new_groups = np.array([0, np.searchsorted(run_line, groups[1]), run_start.shape[0]], np.int64)
    return (springs[kept].astype(np.int32), np.append(run_start, kept.shape[0]).astype(np.int64), new_groups)


class _NoSummary:
    def summary(self, state: State) -> dict:
        return {}


class SpringForces(_NoSummary):
    """Step 1: spring forces (structural, bend, compression-only shear; §3.2) into ctx.force_n,
    on one thread (fraytool/threads.py says why)."""

    name = "forces"
    kernel = "accumulate_spring_forces"
    reads = frozenset({POSITIONS, TOPOLOGY})
    writes = frozenset({FORCES})

    def __init__(self, model: Model):
        self.model = model

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        m = self.model
        accumulate_spring_forces(m.spring_kind, state.spring_rest_length_m, state.particle_position_m,
                                 state.spring_particle_a, state.spring_particle_b, state.spring_alive,
                                 state.spring_stiffness_n_per_m, ctx.force_n)


class VelocityUpdate(_NoSummary):
    """Step 2: v += dt (g + f / m)."""

    name = "integration"
    kernel = "integrate_velocities"
    reads = frozenset({FORCES, VELOCITIES})
    writes = frozenset({VELOCITIES})

    def __init__(self, model: Model):
        self.model = model

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        integrate_velocities(*ctx.lists.free(state), state.particle_velocity_m_s, ctx.force_n,
                             state.particle_inv_mass, self.model.gravity_at_m_s2(state.time_s), dt_s)


class Damping(_NoSummary):
    """Step 3: PBD damping (Müller et al. 2007 §3.5), applied to each piece of the cloth on its own.

    Müller's damping keeps an object's linear and angular momentum; a torn cloth is several objects,
    so in a scene that tears every piece (fraytool.sim.pieces) is damped about its own centre of mass
    and two pieces moving apart keep their relative velocity. The pieces are relabelled when
    State.topology_epoch changed. An untorn cloth is one piece (the single-body kernel)."""

    name = "damping"
    kernel = "pbd_damping"
    reads = frozenset({POSITIONS, VELOCITIES, TOPOLOGY})
    writes = frozenset({VELOCITIES})

    def __init__(self, model: Model):
        self.model = model
        self.damping = model.damping
        self.per_piece = bool(model.tearing)
        self._labels = np.zeros(model.particle_count if self.per_piece else 0, np.int64)
        self._piece_count = 0
        self._labelled_at: Optional[int] = None
        """State.topology_epoch the piece labels were made at."""

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        if not self.per_piece:
            pbd_damping(*ctx.lists.free(state), state.particle_position_m, state.particle_velocity_m_s,
                        state.particle_mass_kg, state.particle_inv_mass, self.damping)
            return
        if state.topology_epoch != self._labelled_at:
            m = self.model
            self._piece_count = label_pieces(m.spring_kind, m.crossing_count, state.particle_active,
                                             state.crossing_yarn_level, state.couple_connected,
                                             state.spring_particle_a, state.spring_particle_b,
                                             state.spring_alive, self._labels)
            self._labelled_at = state.topology_epoch
        pbd_damping_pieces(*ctx.lists.free(state), state.particle_position_m, state.particle_velocity_m_s,
                           state.particle_mass_kg, state.particle_inv_mass, self._labels, self._piece_count,
                           self.damping)


class PositionUpdate(_NoSummary):
    """Step 4: x += dt v (keeping the start-of-step positions), and rigid bodies moved to t + dt."""

    name = "integration"
    kernel = "integrate_positions"
    reads = frozenset({POSITIONS, VELOCITIES, BODIES})
    writes = frozenset({POSITIONS, START_POSITIONS, BODIES})

    def __init__(self, model: Model):
        self.model = model
        self.has_bodies = model.body_count > 0

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        # the moving particles: slaved crossings (multi-resolution model) are their nodes' interpolation
        integrate_positions(*ctx.lists.moving(state), state.particle_position_m,
                            state.particle_velocity_m_s, state.particle_active, ctx.prev_position_m, dt_s)
        if self.has_bodies:
            advance_bodies(self.model, state, state.time_s + dt_s, dt_s)


class Attachments(_NoSummary):
    """Step 5 (first): masses held by a rigid body follow it exactly; those held by a mesh body's surface
    follow its animation (fraytool.sim.surface_pins); one whose force passes its release_force_n lets go."""

    name = "strain_limiting"
    kernel = "apply_attachments"
    reads = frozenset({BODIES, FORCES})
    writes = frozenset({POSITIONS, TOPOLOGY})

    def __init__(self, model: Model):
        self.model = model
        self.surface = None
        if (model.attachment_triangle >= 0).any():
            from fraytool.sim.surface_pins import SurfacePins  # only scenes that pin cloth to a mesh

            self.surface = SurfacePins(model)
        self.releasing = np.flatnonzero(model.attachment_release_force_n > 0.0)
        self.catching = np.flatnonzero(model.attachment_catch_s > 0.0)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        m = self.model
        if self.catching.size:
            self._catch(state, dt_s)
        if self.releasing.size:
            self._release(state, ctx)
        offset = state.attachment_offset_m if state.attachment_offset_m.size else m.attachment_offset_m
        apply_attachments(m.attachment_particle, m.attachment_body, offset, state.body_position_m,
                          state.body_rotation, state.particle_inv_mass, state.particle_position_m)
        if self.surface is not None:
            s = self.surface
            held = state.particle_inv_mass[s.particle] == 0.0
            x = s.positions_m(state.time_s + dt_s, state.body_position_m, state.body_rotation)
            state.particle_position_m[s.particle[held]] = x[held]

    def _catch(self, state: State, dt_s: float) -> None:
        """Hold the masses whose catch time falls in this step where they are relative to their body."""
        k = self.catching
        now = k[(self.model.attachment_catch_s[k] >= state.time_s) & (self.model.attachment_catch_s[k] < state.time_s + dt_s)]
        if not now.size:
            return
        p, b = self.model.attachment_particle[now], self.model.attachment_body[now]
        rel = state.particle_position_m[p] - state.body_position_m[b]
        state.attachment_offset_m[now] = np.einsum("kji,kj->ki", state.body_rotation[b], rel)  # R^T (x - c)
        state.particle_inv_mass[p] = 0.0
        state.bump_topology()

    def _release(self, state: State, ctx: StepContext) -> None:
        """Let go of the held masses whose pull (springs and weight) passed their release force."""
        k = self.releasing
        p = self.model.attachment_particle[k]
        held = state.particle_inv_mass[p] == 0.0
        pull = ctx.force_n[p] + state.particle_mass_kg[p, None] * self.model.gravity_at_m_s2(state.time_s)
        over = held & (np.linalg.norm(pull, axis=1) > self.model.attachment_release_force_n[k])
        if over.any():
            state.particle_inv_mass[p[over]] = 1.0 / state.particle_mass_kg[p[over]]
            state.bump_topology()


class StrainLimiting(_NoSummary):
    """Step 5: strain limiting by constraint projection (§4.1).

    With [cloth.strain] stiffness_n_per_m = 0 (the paper's hard projection, `limit_strain_groups`): point
    Gauss-Seidel over the structural springs in four colour groups (weft i even, weft i odd, warp j
    even, warp j odd): no two springs of a group share a mass, so a sweep is order-independent inside
    each group (its springs are projected in parallel; the groups run one after another) and has no
    spatial sweep direction.

    With stiffness_n_per_m > 0 the limit is a compliant constraint (XPBD, `limit_strain_lines`): where
    it cannot be met the yarn stretches by a definite amount, and every sweep solves each yarn whole
    (a tridiagonal system), weft yarns then warp yarns, so the sweeps converge to the tolerance
    instead of stopping at the cap with a residual that depends on the step. With [cloth.strain]
    damping_ratio > 0 a dashpot first resists the stretching of springs past the limit
    (`damp_overstretched`)."""

    name = "strain_limiting"
    kernel = "limit_strain_groups"
    reads = frozenset({POSITIONS, START_POSITIONS, HANGING, TOPOLOGY})
    writes = frozenset({POSITIONS})

    def __init__(self, model: Model):
        self.model = model
        self._moved_at = np.zeros(0, np.int64)
        """Per particle (sized on first use: the particle slots): the sweeps' record of moved masses."""
        self.compliant = model.strain_stiffness_n_per_m > 0.0
        self.kernel = "limit_strain_lines" if self.compliant else "limit_strain_groups"
        self._all_groups = colour_groups(model)
        self._all_lines = yarn_line_springs(model) if self.compliant else None
        """Every structural spring's colour groups and yarn lines, which `restrict` filters."""
        self.restrict(None)
        self._restricted_at = -1
        """The epoch of the working-spring mask the lists were restricted to (StepContext.working_springs)."""

    def restrict(self, working: Optional[np.ndarray]) -> None:
        """Limit only the structural springs where `working` (a mask over the spring slots) is True; None:
        all of them. The multi-resolution model limits the springs of its refined cells (the mask
        StepContext.working_springs gives, read at each run): a yarn's line then breaks into runs of consecutive working springs (runs of one
        yarn share no mass, so a group's lines stay independent)."""
        springs, starts = self._all_groups
        if working is not None:
            keep = working[springs]
            counts = [int(keep[starts[g]:starts[g + 1]].sum()) for g in range(starts.shape[0] - 1)]
            springs = springs[keep]
            starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.limited_springs, self.colour_start = springs, starts
        self._checked_at = np.zeros(self.limited_springs.shape[0], np.int64)
        if self.compliant:
            line_springs, line_start, line_groups = self._all_lines
            if working is not None:
                line_springs, line_start, line_groups = _working_runs(line_springs, line_start, line_groups,
                                                                      working[line_springs])
            self.line_springs, self.line_start, self.line_groups = line_springs, line_start, line_groups
            n = self.line_springs.shape[0]
            self._tension = np.zeros(n)
            self._diag = np.zeros(n)
            self._upper = np.zeros(n)
            self._rhs = np.zeros(n)
            self._unit = np.zeros((n, 3))
            self._line_worst = np.zeros(self.line_start.shape[0] - 1)
            self._line_status = np.zeros(self.line_start.shape[0] - 1, np.int64)

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        m = self.model
        working, made_at = ctx.working_springs(state)
        if made_at != self._restricted_at:
            self.restrict(working)
            self._restricted_at = made_at
        if m.strain_damping_n_s_per_m > 0.0:
            damp_overstretched(self.limited_springs, state.spring_rest_length_m, m.strain_limit,
                               m.strain_damping_n_s_per_m, dt_s, state.particle_inv_mass, state.spring_particle_a,
                               state.spring_particle_b, state.spring_alive, ctx.prev_position_m,
                               state.particle_position_m)
        if self._moved_at.shape[0] != state.particle_position_m.shape[0]:
            self._moved_at = np.zeros(state.particle_position_m.shape[0], np.int64)
        limit = (m.strain_limit, m.strain_tolerance, m.strain_max_iterations)
        springs = (state.spring_rest_length_m, state.particle_inv_mass, state.spring_particle_a,
                   state.spring_particle_b, state.spring_alive)
        if self.compliant:
            scratch = (self._tension, self._diag, self._upper, self._rhs, self._unit, self._line_worst,
                       self._line_status, self._moved_at)
            it, converged = limit_strain_lines(self.line_springs, self.line_start, self.line_groups, limit,
                                               1.0 / (m.strain_stiffness_n_per_m * dt_s * dt_s), springs, scratch,
                                               state.particle_position_m)
        else:
            it, converged = limit_strain_groups(self.limited_springs, self.colour_start, limit, springs,
                                                self._checked_at, self._moved_at, state.particle_position_m)
        counters = ctx.counters
        counters.strain_iterations_last = it
        counters.strain_iterations_max = max(counters.strain_iterations_max, it)
        counters.strain_cap_hits += 0 if converged else 1


class RigidContact(_NoSummary):
    """Step 6: masses against rigid surfaces (§4.3), the reaction given to dynamic bodies."""

    name = "collisions"
    kernel = "collide_rigid"
    reads = frozenset({POSITIONS, START_POSITIONS, BODIES})
    writes = frozenset({POSITIONS, BODIES})

    def __init__(self, model: Model):
        self.model = model
        self.body_dynamic = model.body_motion == MOTION_DYNAMIC
        self.any_dynamic = bool(self.body_dynamic.any())
        self.collide = model.body_collide & (model.body_shape != SHAPE_MESH)  # meshes: stages.mesh_contact

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        m = self.model
        ctx.counters.rigid_contacts_last = collide_rigid(
            *ctx.lists.free(state), bodies_in(m, state, self.collide), 0.5 * m.thickness_m, dt_s, state.particle_inv_mass,
            state.particle_mass_kg, ctx.prev_position_m, state.particle_position_m, ctx.body_impulse_n_s)
        if self.any_dynamic:
            apply_cloth_impulse(m, state, ctx.body_impulse_n_s)


class RigidContactBeforeLimit(RigidContact):
    """Step 5, before strain limiting, in scenes that tear and have colliding bodies: the rigid contact
    of step 6 run once more ahead of the constraints, so that the strain limit sees the push of a
    moving body before the strains are read for transitions and breaks (docs/tearing.md, "Contact
    with bodies before the strain limit").

    The paper's order (strain limiting, then collisions, then strains: docs/method.md §4) reads every
    strain right after the contact pass has moved the masses touching a body, by up to the body's
    speed x dt, while their neighbours have not followed yet: a strain spike that grows with the
    step. On the thrown-ball shot (fig6, ball at 5 m/s, 1 mm per step at the scene's step, more than
    the yarn's thickness) the scene's step broke 22.25 springs against 18.75 at an eighth of it (means
    over seeds 6-9, docs/study.md); with this pass, 21.0 against 18.75. Step 6 still runs after the
    constraints, so no mass ends a step inside a body; each pass gives its own reaction impulse to
    dynamic bodies, so momentum is exchanged as before."""

    name = "contact_before_limit"
    kernel = "collide_rigid (before strain limiting)"


class VelocityPostProcess(_NoSummary):
    """Step 8: v = (x - x_prev) / dt (PBD), with the guard's end-of-step check: the first particle
    non-finite or faster than speed_limit_m_s goes to ctx.bad_particle.

    In a multi-resolution model the crossings slaved to coarse nodes are left out of the step (their
    velocity is read by nothing in it: they are not integrated, and a crossing freed by a refinement
    is freed with its interpolated position and start-of-step position, so the step ends with its
    velocity); the solver's completion call (SolverExplicitPBD.complete) gives them theirs, by the
    same formula."""

    name = "integration"
    kernel = "velocities_from_positions"
    reads = frozenset({POSITIONS, START_POSITIONS})
    writes = frozenset({VELOCITIES})

    def __init__(self, model: Model, speed_limit_m_s: float):
        self.speed_limit_m_s = speed_limit_m_s

    def run(self, state: State, ctx: StepContext, dt_s: float) -> None:
        ctx.bad_particle = int(velocities_from_positions(
            *ctx.lists.moving(state), state.particle_position_m, ctx.prev_position_m,
            state.particle_active, state.particle_velocity_m_s, dt_s, self.speed_limit_m_s))

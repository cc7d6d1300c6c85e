"""SolverExplicitPBD: the time step of docs/method.md §4, as the list of stages its model needs.

Per step of size dt:
 1. forces: springs (+ gravity in 2);           2. velocities v += dt (g + f/m);
 3. PBD damping (Müller 2007 §3.5);              4. positions x += dt v;
 5. constraints: attachments, (a tearing scene with a colliding body: rigid contact once more), strain
    limiting (§4.1), yarn contact at connected couples (§3.3);
 6. collisions: rigid bodies (§4.3), self-collision (§4.2);
 7. strains: transitions to yarn level and cuts (§3.4);
 8. velocity post-process v = (x - x_prev) / dt, with the stability guard.
The solver builds its own stages from the model (fraytool.sim.stages.build_stages): a stage that a
scene does not use is not in the list (no rigid pass without bodies, no attachment pass without
attachments, no yarn-level pass without tearing) and its kernels are never compiled. What the stages
share lives in one StepContext (`solver.context`); what each reads and writes is declared on it, and the
syncs a coarse base model needs are inserted from those declarations (fraytool.sim.stages.plan_syncs).
"""
from __future__ import annotations

import time
from typing import Callable, Optional

import numpy as np

from fraytool.errors import RunError
from fraytool.kinds import MOTION_DYNAMIC
from fraytool.sim.diagnostic import unstable_diagnostic, unstable_message
from fraytool.sim.model import Model
from fraytool.sim.stages import STAGE_NAMES, StepContext, build_stages, plan_syncs
from fraytool.sim.stages.core import colour_ordered_structural_springs
from fraytool.sim.state import State

__all__ = ["STAGE_NAMES", "SimulationUnstable", "SolverExplicitPBD", "colour_ordered_structural_springs"]


class SimulationUnstable(RunError):
    """The stability guard found a non-finite or absurd value; nothing of that step is kept."""

    def __init__(self, message: str, diagnostic: dict):
        super().__init__(message)
        self.diagnostic = diagnostic


class SolverExplicitPBD:
    """Explicit Euler substeps with position-based constraints, as in docs/method.md §4."""

    def __init__(self, model: Model, speed_limit_m_s: float = 1.0e3):
        self.model = model
        self.speed_limit_m_s = speed_limit_m_s
        """Guard: a particle faster than this [m/s] (or non-finite) stops the run."""
        self.context = StepContext.for_model(model)
        """What the stages share (fraytool.sim.stages.base.StepContext)."""
        self._plan = build_stages(model, speed_limit_m_s, self.context)
        self.stages = plan_syncs(self._plan.stages, self.context)
        """The step's stages in order, with the coarse syncs the declarations call for (fraytool.sim.stages)."""
        if self.context.coarse is not None:  # a multi-resolution model: its slaved crossings are not moving
            self.context.lists.slaved_of = self.context.coarse.slaved_now
        self.stage_check: Optional[Callable[[object], None]] = None
        """Called after every stage as stage_check(stage) while fraytool.sim.guard replays a failed step
        to find the stage that went wrong; None (no cost) in normal runs."""
        self._guard_bodies = bool((model.body_motion == MOTION_DYNAMIC).any())

    # -- what tools read ---------------------------------------------------------------------------
    @property
    def tearing(self):
        """The yarn-level model (fraytool.sim.tearing.YarnTearing) of a tearing scene, else None."""
        return self.context.yarn_tearing

    @property
    def self_collision(self):
        """The self-collision stage of a scene with self-collision on, else None."""
        return self._plan.self_collision

    @property
    def stage_s(self) -> dict:
        """Wall time spent per stage since construction [s]."""
        return self.context.counters.stage_s

    @property
    def strain_iterations_last(self) -> int:
        return self.context.counters.strain_iterations_last

    @property
    def strain_iterations_max(self) -> int:
        return self.context.counters.strain_iterations_max

    @property
    def strain_cap_hits(self) -> int:
        """Steps where strain limiting stopped at the iteration cap without converging."""
        return self.context.counters.strain_cap_hits

    @property
    def rigid_contacts_last(self) -> int:
        return self.context.counters.rigid_contacts_last

    def counters(self):
        """The solver's running counters (timers, strain iterations, contacts), for save/restore."""
        return self.context.counters.copy()

    def restore_counters(self, saved) -> None:
        self.context.counters = saved.copy()

    def insert_stage(self, stage) -> None:
        """Add a stage (fraytool.sim.stages.Stage) after the last stage of the same or an earlier
        place in STAGE_NAMES (before the velocity post-process); the coarse syncs are planned again."""
        stages = self._plan.stages
        rank = STAGE_NAMES.index(stage.name)
        at = len(stages) - 1
        while at > 0 and STAGE_NAMES.index(stages[at - 1].name) > rank:
            at -= 1
        stages.insert(at, stage)
        self.stages = plan_syncs(stages, self.context)

    def summary(self, state: State) -> dict:
        """Figures of every stage that has some, and the tear's (merged into `fraytool simulate --json`)."""
        out: dict = {}
        for stage in self.stages:
            out.update(stage.summary(state))
        if self.context.yarn_tearing is not None:
            out.update(self.context.yarn_tearing.summary(state))
        return out

    # -- the step --------------------------------------------------------------------------------
    def step(self, state: State, dt_s: float) -> None:
        """Advance `state` by dt_s in place.

        The state a step leaves is complete for the step's own needs but not for a reader outside it:
        in a multi-resolution model the crossings slaved to coarse nodes are brought up to date only
        where a stage reads them. Before reading a state (a frame's record, a checkpoint, a check, your
        own code) call `complete(state, dt_s)` once: it is what `Simulation.advance_frame`, the run to
        disk, the guard and the study call. It does nothing for a model without a coarse grid."""
        ctx = self.context
        ctx.bad_particle = -1
        stage_s = ctx.counters.stage_s
        for stage in self.stages:
            t0 = time.perf_counter()
            stage.run(state, ctx, dt_s)
            stage_s[stage.name] += time.perf_counter() - t0
            if self.stage_check is not None:
                self.stage_check(stage)
        state.time_s = state.time_s + dt_s
        state.step_index += 1
        if ctx.bad_particle >= 0:
            self._unstable(state, ctx.bad_particle, dt_s)
        if self._guard_bodies and not np.isfinite(state.body_position_m).all():
            self._unstable(state, -1, dt_s)  # a thrown body received a non-finite impulse

    def complete(self, state: State, dt_s: float) -> None:
        """Bring what the steps leave out up to date (the slaved crossings of a multi-resolution model:
        positions on their interpolation, velocities of the last step), so that every field of `state`
        holds its value; call after your last step, before reading or saving the state."""
        if self.context.coarse is not None:
            self.context.coarse.complete(state, self.context, dt_s, self.speed_limit_m_s)

    def slaved_crossings(self, state: State) -> np.ndarray:
        """The crossings slaved to coarse nodes in `state` (multi-resolution model; else none)."""
        return self.context.slaved(state)

    def _unstable(self, state: State, particle: int, dt_s: float) -> None:
        """Stop the run: the end-of-step guard found `particle` (or, if -1, a rigid body) non-finite or
        too fast. The diagnostic says which mass and which springs; fraytool.sim.guard replays the
        step to add which stage."""
        diag = unstable_diagnostic(self.model, self.speed_limit_m_s, state, particle, "end of step",
                                   "velocities_from_positions", dt_s)
        if particle < 0:
            bad = np.nonzero(~np.isfinite(state.body_position_m).all(axis=1))[0]
            diag["body"] = self.model.body_names[int(bad[0])] if bad.size else "?"
        raise SimulationUnstable(unstable_message(diag), diag)

    def reset_timers(self) -> None:
        self.context.counters.stage_s = dict.fromkeys(STAGE_NAMES, 0.0)

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
attachments, no yarn-level pass without tearing) and its kernels are never compiled.
"""
from __future__ import annotations

import time
from typing import Callable, Optional

import numpy as np

from fraytool.errors import RunError
from fraytool.kinds import MOTION_DYNAMIC
from fraytool.sim.diagnostic import unstable_diagnostic, unstable_message
from fraytool.sim.model import Model
from fraytool.sim.stages import STAGE_NAMES, StepBuffers, build_stages
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
        self.buffers = StepBuffers.for_model(model)
        self.stages = build_stages(model, speed_limit_m_s)
        """The step's stages in order (fraytool.sim.stages)."""
        refinement = self._find("Refinement")
        if refinement is not None:  # a multi-resolution model: its slaved crossings are not moving particles
            self.buffers.lists.slaved_of = refinement.runtime.slaved_now
        self.stage_s = dict.fromkeys(STAGE_NAMES, 0.0)
        """Wall time spent per stage since construction [s]."""
        self.stage_check: Optional[Callable[[str, str], None]] = None
        """Called after every stage as stage_check(stage name, kernel name) while fraytool.sim.guard
        replays a failed step to find the stage that went wrong; None (no cost) in normal runs."""
        self._guard_bodies = bool((model.body_motion == MOTION_DYNAMIC).any())

    # -- the stages, by role ------------------------------------------------------------------
    def _find(self, cls_name: str):
        for stage in self.stages:
            if type(stage).__name__ == cls_name:
                return stage
        return None

    @property
    def tearing(self):
        """The yarn-level model (fraytool.sim.tearing.YarnTearing) of a tearing scene, else None."""
        stage = self._find("TearingStage")
        return stage.tearing if stage is not None else None

    @property
    def self_collision(self):
        """The self-collision stage of a scene with self-collision on, else None."""
        return self._find("SelfCollision")

    @property
    def yarn_contact(self):
        """The couple-contact stage (tearing with the yarn-level model), else None."""
        return self._find("YarnContactStage")

    @property
    def _strain(self):
        return self._find("StrainLimiting")

    @property
    def strain_iterations_last(self) -> int:
        return self._strain.iterations_last

    @property
    def strain_iterations_max(self) -> int:
        return self._strain.iterations_max

    @property
    def strain_cap_hits(self) -> int:
        """Steps where strain limiting stopped at the iteration cap without converging."""
        return self._strain.cap_hits

    @property
    def rigid_contacts_last(self) -> int:
        stage = self._find("RigidContact")
        return stage.contacts_last if stage is not None else 0

    def counters(self) -> tuple:
        """The solver's running counters (timers, strain iterations, contacts), for save/restore."""
        strain, rigid = self._strain, self._find("RigidContact")
        return (dict(self.stage_s), strain.iterations_last, strain.iterations_max, strain.cap_hits,
                rigid.contacts_last if rigid is not None else 0)

    def restore_counters(self, saved: tuple) -> None:
        strain, rigid = self._strain, self._find("RigidContact")
        self.stage_s, strain.iterations_last, strain.iterations_max, strain.cap_hits, contacts = saved
        if rigid is not None:
            rigid.contacts_last = contacts

    def insert_stage(self, stage) -> None:
        """Add a stage (fraytool.sim.stages.Stage) after the last stage of the same or an earlier
        place in STAGE_NAMES (before the velocity post-process)."""
        rank = STAGE_NAMES.index(stage.name)
        at = len(self.stages) - 1
        while at > 0 and STAGE_NAMES.index(self.stages[at - 1].name) > rank:
            at -= 1
        self.stages.insert(at, stage)

    def summary(self, state: State) -> dict:
        """Figures of every stage that has some (merged into `fraytool simulate --json`)."""
        out: dict = {}
        for stage in self.stages:
            out.update(stage.summary(state))
        return out

    # -- the step --------------------------------------------------------------------------------
    def step(self, state: State, dt_s: float) -> None:
        """Advance `state` by dt_s in place."""
        buffers = self.buffers
        buffers.bad_particle = -1
        for stage in self.stages:
            t0 = time.perf_counter()
            stage.run(state, buffers, dt_s)
            self.stage_s[stage.name] += time.perf_counter() - t0
            if self.stage_check is not None:
                self.stage_check(stage.name, stage.kernel)
        state.time_s = state.time_s + dt_s
        state.step_index += 1
        if buffers.bad_particle >= 0:
            self._unstable(state, buffers.bad_particle, dt_s)
        if self._guard_bodies and not np.isfinite(state.body_position_m).all():
            self._unstable(state, -1, dt_s)  # a thrown body received a non-finite impulse

    def slaved_crossings(self, state: State) -> np.ndarray:
        """The crossings slaved to coarse nodes in `state` (multi-resolution model; else none): their
        state is brought up to date where it is read and at the end of a frame (`end_frame`)."""
        return self.buffers.lists.slaved(state)

    def end_frame(self, state: State, dt_s: float) -> None:
        """Bring what the steps leave out up to date for the frame's record and checkpoint (the slaved
        crossings' velocities of a multi-resolution model); call after the last step of a frame."""
        for stage in self.stages:
            finish = getattr(stage, "end_frame", None)
            if finish is not None:
                finish(state, self.buffers, dt_s)

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
        self.stage_s = dict.fromkeys(STAGE_NAMES, 0.0)

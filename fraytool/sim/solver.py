"""SolverExplicitPBD: the time step of METHOD.md §4, as a fixed list of stages.

Per step of size dt:
 1. forces: springs (+ gravity in 2);           2. velocities v += dt (g + f/m);
 3. PBD damping (Müller 2007 §3.5);              4. positions x += dt v;
 5. constraints: attachments, strain limiting (§4.1), yarn contact at connected couples (§3.3);
 6. collisions: rigid bodies (§4.3), self-collision (§4.2);
 7. strains: transitions to yarn level and cuts (§3.4);
 8. velocity post-process v = (x - x_prev) / dt, with the stability guard.
A stage that a scene does not use is not in the list: no rigid pass without bodies, no attachment
pass without attachments, no yarn-level pass without tearing; their kernels are never compiled.
"""
from __future__ import annotations

import time
from typing import Callable, Optional, Protocol

import numpy as np

from fraytool.errors import RunError
from fraytool.sim.kernels.attachments import apply_attachments
from fraytool.sim.kernels.damping import pbd_damping
from fraytool.sim.kernels.forces import accumulate_spring_forces
from fraytool.sim.kernels.integrate import integrate_positions, integrate_velocities, velocities_from_positions
from fraytool.sim.kernels.rigid_contact import collide_rigid
from fraytool.sim.kernels.strain_limit import limit_strain
from fraytool.sim.model import MOTION_DYNAMIC, Model
from fraytool.sim.rigid import advance_bodies, apply_cloth_impulse
from fraytool.sim.state import State

STAGE_NAMES = ("forces", "integration", "damping", "strain_limiting", "yarn_contact", "collisions",
               "self_collision", "tearing")


class SimulationUnstable(RunError):
    """The stability guard found a non-finite or absurd value; nothing of that step is kept."""

    def __init__(self, message: str, diagnostic: dict):
        super().__init__(message)
        self.diagnostic = diagnostic


class StepHook(Protocol):
    """A pass plugged into the step (yarn-level model, self-collision)."""

    def __call__(self, state: State, prev_position_m: np.ndarray, dt_s: float) -> None: ...


def colour_ordered_structural_springs(model: Model) -> np.ndarray:
    """Slots of the structural springs grouped by colour: weft springs (i, i+1) with i even, then
    i odd, then warp springs (j, j+1) with j even, then j odd; ascending slots inside a group."""
    weft = model.weft_structural_spring
    warp = model.warp_structural_spring
    groups = [weft[:, 0::2], weft[:, 1::2], warp[:, 0::2], warp[:, 1::2]]
    return np.concatenate([np.sort(g.ravel()) for g in groups]).astype(np.int32)


class SolverExplicitPBD:
    """Explicit Euler substeps with position-based constraints, as in METHOD.md §4."""

    def __init__(self, model: Model, speed_limit_m_s: float = 1.0e3):
        self.model = model
        self.speed_limit_m_s = speed_limit_m_s
        """Guard: a particle faster than this [m/s] (or non-finite) stops the run."""
        self.limited_springs = colour_ordered_structural_springs(model)
        """Structural springs in four colour groups (weft i even, weft i odd, warp j even, warp j odd):
        no two springs of a group share a mass, so a sweep is order-independent inside each group
        and strain limiting has no spatial sweep direction (STYLE.md §7)."""
        self._force = np.zeros((model.particle_count, 3))
        self._prev = np.zeros((model.particle_count, 3))
        self._impulse = np.zeros((model.body_count, 3))
        self._body_dynamic = model.body_motion == MOTION_DYNAMIC
        self.has_bodies = model.body_count > 0
        self.has_rigid_contact = bool(model.body_collide.any()) if self.has_bodies else False
        self.has_attachments = model.attachment_count > 0
        self.stage_s = dict.fromkeys(STAGE_NAMES, 0.0)
        """Wall time spent per stage since construction [s]."""
        self.strain_iterations_last = 0
        self.strain_iterations_max = 0
        self.strain_cap_hits = 0
        """Steps where strain limiting stopped at the iteration cap without converging."""
        self.rigid_contacts_last = 0
        # Optional passes, plugged in by the yarn-level model and self-collision (see sim/__init__).
        self.yarn_contact: Optional[StepHook] = None
        self.self_collision: Optional[StepHook] = None
        self.tearing: Optional[StepHook] = None
        self.stage_check: Optional[Callable[[str, Callable], None]] = None
        """Called after every stage as stage_check(stage name, kernel) while fraytool.sim.guard replays a
        failed step to find the stage that went wrong; None (no cost) in normal runs."""
        self._guard_bodies = bool(self._body_dynamic.any())

    def _timed(self, name: str, fn: Callable, *args):
        t0 = time.perf_counter()
        out = fn(*args)
        self.stage_s[name] += time.perf_counter() - t0
        if self.stage_check is not None:
            self.stage_check(name, fn)
        return out

    def step(self, state: State, dt_s: float) -> None:
        """Advance `state` by dt_s in place."""
        m = self.model
        x, v = state.particle_position_m, state.particle_velocity_m_s
        self._timed("forces", accumulate_spring_forces, m.spring_kind, m.spring_rest_length_m, x,
                    state.spring_particle_a, state.spring_particle_b, state.spring_alive,
                    state.spring_stiffness_n_per_m, self._force)
        self._timed("integration", integrate_velocities, v, self._force, state.particle_inv_mass, m.gravity_m_s2, dt_s)
        if m.damping > 0.0:
            self._timed("damping", pbd_damping, x, v, state.particle_mass_kg, state.particle_inv_mass, m.damping)
        self._timed("integration", integrate_positions, x, v, state.particle_active, self._prev, dt_s)
        t_new = state.time_s + dt_s
        if self.has_bodies:
            advance_bodies(m, state, t_new, dt_s)
        if self.has_attachments:
            self._timed("strain_limiting", apply_attachments, m.attachment_particle, m.attachment_body,
                        m.attachment_offset_m, state.body_position_m, m.body_rotation, x)
        it, converged = self._timed("strain_limiting", limit_strain, self.limited_springs, m.spring_rest_length_m,
                                    m.strain_limit, m.strain_tolerance, m.strain_max_iterations,
                                    state.particle_inv_mass, state.spring_particle_a, state.spring_particle_b,
                                    state.spring_alive, x)
        self.strain_iterations_last = it
        self.strain_iterations_max = max(self.strain_iterations_max, it)
        self.strain_cap_hits += 0 if converged else 1
        if self.yarn_contact is not None:
            self._timed("yarn_contact", self.yarn_contact, state, self._prev, dt_s)
        if self.has_rigid_contact:
            self.rigid_contacts_last = self._timed(
                "collisions", collide_rigid, m.body_shape, m.body_rotation, m.body_radius_m, m.body_half_extents_m,
                m.body_normal, m.body_friction, m.body_collide, self._body_dynamic, 0.5 * m.thickness_m, dt_s,
                state.body_position_m, state.body_velocity_m_s, state.particle_inv_mass, state.particle_mass_kg,
                self._prev, x, self._impulse)
            if self._body_dynamic.any():
                apply_cloth_impulse(m, state, self._impulse)
        if self.self_collision is not None:
            self._timed("self_collision", self.self_collision, state, self._prev, dt_s)
        if self.tearing is not None:
            self._timed("tearing", self.tearing, state, self._prev, dt_s)
        bad = self._timed("integration", velocities_from_positions, x, self._prev, state.particle_active, v,
                          dt_s, self.speed_limit_m_s)
        state.time_s = t_new
        state.step_index += 1
        if bad >= 0:
            self._unstable(state, int(bad), dt_s)
        if self._guard_bodies and not np.isfinite(state.body_position_m).all():
            self._unstable(state, -1, dt_s)  # a thrown body received a non-finite impulse

    def _unstable(self, state: State, particle: int, dt_s: float) -> None:
        """Stop the run: the end-of-step guard found `particle` (or, if -1, a rigid body) non-finite or
        too fast. The diagnostic says which mass and which springs; fraytool.sim.guard replays the
        step to add which stage."""
        from fraytool.sim.guard import unstable_diagnostic, unstable_message

        diag = unstable_diagnostic(self, state, particle, "end of step", "velocities_from_positions", dt_s)
        if particle < 0:
            bad = np.nonzero(~np.isfinite(state.body_position_m).all(axis=1))[0]
            diag["body"] = self.model.body_names[int(bad[0])] if bad.size else "?"
        raise SimulationUnstable(unstable_message(diag), diag)

    def reset_timers(self) -> None:
        self.stage_s = dict.fromkeys(STAGE_NAMES, 0.0)

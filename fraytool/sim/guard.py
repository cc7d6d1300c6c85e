"""The stability guard: what went wrong when a step produced a non-finite or absurd value.

Every step ends with a cheap check (in the velocity post-process): a particle whose velocity
(x - x_prev) / dt is non-finite or faster than the solver's speed limit stops the run with
`SimulationUnstable`. Nothing else is checked in the normal path, so the guard costs nothing.

To say *which stage* produced the bad value, the failed step is replayed, on failure only, from a
saved copy of an earlier good state (the last complete frame's): the steps before the failed one
run as usual, then the failed step runs with a check after every stage (`SolverExplicitPBD.stage_check`):

- after the force stage: forces finite;
- after every stage: velocities finite and not faster than the limit (the velocity update may
  exceed it transiently; the first stage where any value goes bad is the one reported);
- from the position update on: positions finite, displacement over the step not faster than the
  limit, and rigid bodies' positions finite.

The replay reuses the solver that failed (its hooks included) and restores its counters after.
The steps are deterministic, so the replay reproduces the failure; if a plugged-in pass keeps state
outside `State` and the replay does not fail, the diagnostic says so.

The diagnostic names the mass (particle slot, crossing (i, j), base / weft / warp mass), its
springs with kind, stiffness and strain (the most strained first: "which spring"), the stage and
the kernel, the step and time, and the step's ratio to the stability bound.
"""
from __future__ import annotations

import math
from typing import Callable, Optional

import numpy as np

from fraytool.sim.diagnostic import unstable_diagnostic
from fraytool.sim.solver import SimulationUnstable, SolverExplicitPBD
from fraytool.sim.stages.base import FORCES, START_POSITIONS
from fraytool.sim.state import State

class StageFailure(Exception):
    """Raised by the stage check during a replay; carries the diagnostic."""

    def __init__(self, diagnostic: dict):
        super().__init__(diagnostic.get("stage"))
        self.diagnostic = diagnostic


def _first_bad_row(values: np.ndarray, rows: np.ndarray, limit: float = math.inf) -> int:
    """First row (among `rows`) that is non-finite or has a norm above `limit`; -1 if none."""
    v = values[rows]
    with np.errstate(invalid="ignore", over="ignore"):
        norm = np.sqrt((v * v).sum(axis=1))
    bad = ~np.isfinite(norm) | (norm > limit)
    return int(rows[np.argmax(bad)]) if bad.any() else -1


def make_stage_check(solver: SolverExplicitPBD, state: State, dt_s: float) -> Callable[[object], None]:
    """The check run after every stage of one replayed step; raises StageFailure at the first bad value.
    Slaved crossings (multi-resolution model) are left out: the step does not keep them current (they
    follow their nodes, which are checked)."""
    checked = state.particle_active.copy()
    checked[solver.slaved_crossings(state)] = False
    active = np.nonzero(checked)[0]
    moved = {"positions": False, "forces": False}

    def check(stage) -> None:
        # from the stage's declared writes: forces once written are checked; positions and their
        # velocities once the start-of-step positions are (the position update)
        if FORCES in stage.writes:
            moved["forces"] = True
        if START_POSITIONS in stage.writes:
            moved["positions"] = True
        bad = -1
        if moved["forces"]:
            bad = _first_bad_row(solver.context.force_n, active)
        if bad < 0:
            bad = _first_bad_row(state.particle_velocity_m_s, active, solver.speed_limit_m_s)
        if bad < 0 and moved["positions"]:
            bad = _first_bad_row(state.particle_position_m, active)
            if bad < 0:
                bad = _first_bad_row((state.particle_position_m - solver.context.prev_position_m) / dt_s, active, solver.speed_limit_m_s)
        body = -1
        if bad < 0 and state.body_position_m.size:
            body = _first_bad_row(state.body_position_m, np.arange(state.body_position_m.shape[0]))
        if bad >= 0 or body >= 0:
            diag = unstable_diagnostic(solver.model, solver.speed_limit_m_s, state, bad, stage.name, stage.kernel,
                                       dt_s)
            if body >= 0:
                diag["body"] = solver.model.body_names[body]
            raise StageFailure(diag)

    return check


def replay_failed_step(solver: SolverExplicitPBD, start: State, dt_s: float, failed_step: int
                       ) -> tuple[Optional[dict], Optional[State]]:
    """Replay from `start` (not modified) up to step `failed_step` (the State.step_index the failed
    step would have produced), checking every stage of the last step.

    Returns (stage diagnostic or None if the replay did not fail, State just before the failed step).
    """
    steps = failed_step - start.step_index
    if steps < 1:
        return None, None
    saved = solver.counters()
    state = start.copy()
    try:
        for _ in range(steps - 1):
            solver.step(state, dt_s)
        before = state.copy()
        solver.complete(before, dt_s)  # the last good state as a frame's record would hold it
        solver.stage_check = make_stage_check(solver, state, dt_s)
        try:
            solver.step(state, dt_s)
        except StageFailure as failure:
            diag = failure.diagnostic
            diag["step"] = int(before.step_index + 1)
            diag["time_s"] = float(before.time_s + dt_s)
            return diag, before
        return None, before
    except SimulationUnstable:
        return None, None  # failed earlier than the original run: not deterministic
    finally:
        solver.stage_check = None
        solver.restore_counters(saved)


def explain_failure(solver: SolverExplicitPBD, start: Optional[State], dt_s: float, diagnostic: dict) -> tuple[dict, Optional[State]]:
    """Merge the replay's stage diagnostic into the end-of-step one; returns (diagnostic, last good state)."""
    diag = dict(diagnostic)
    if start is None or diag.get("stage_located"):
        diag.setdefault("stage_located", False)
        return diag, start
    located, before = replay_failed_step(solver, start, dt_s, int(diagnostic["step"]))
    if located is None:
        diag["stage_located"] = False
        diag["replay"] = "the replay from the last good frame did not reproduce the failure"
        return diag, before
    end = {k: diagnostic[k] for k in ("particle", "velocity_m_s", "position_m") if k in diagnostic}
    diag.update(located)
    diag["end_of_step"] = end
    return diag, before


JITTER_LIMIT = 0.02
"""Jitter ratio above which a cloth oscillates step to step (see `jitter_ratio`)."""


def jitter_ratio(v0: np.ndarray, v1: np.ndarray, v2: np.ndarray, dt_s: float, spacing_m: float) -> float:
    """Amplitude of a step-to-step (period-2) oscillation as a fraction of the yarn spacing, from the
    velocities of three consecutive steps (free masses, same rows):

        h * rms_i |v_i(n+1) - 2 v_i(n) + v_i(n-1)| / (8 spacing)

    For x_i = x_i0 + A (-1)^n it is exactly A / spacing; smooth motion gives about
    h^3 |jerk| / (8 spacing). Symplectic Euler past its stability bound grows exactly this
    oscillation, and when strain limiting holds it bounded the speeds stay below the end-of-step
    speed limit: this is the measure that sees it (used by fraytool.study; not checked per step).
    """
    if v0.shape[0] == 0:
        return 0.0
    d2 = v2 - 2.0 * v1 + v0
    with np.errstate(over="ignore", invalid="ignore"):
        rms = math.sqrt(float((d2 * d2).sum(axis=1).mean()))
    return dt_s * rms / (8.0 * spacing_m)


def record_is_finite(record) -> bool:
    """True when every float array of a FrameRecord is finite (nothing with NaN/inf may be written)."""
    return bool(np.isfinite(record.particle_position_m).all() and np.isfinite(record.body_position_m).all()
                and np.isfinite(record.body_rotation).all() and math.isfinite(record.time_s))

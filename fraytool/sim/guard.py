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

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Optional

import numpy as np

from fraytool.sim.model import SPRING_KIND_NAMES, Model
from fraytool.sim.state import State

if TYPE_CHECKING:
    from fraytool.sim.solver import SolverExplicitPBD

UNSTABLE_JSON = "unstable.json"
"""Diagnostic written beside the frames of a run that became unstable."""
LAST_GOOD_STATE = "unstable_last_good_state.npz"
"""Full State just before the failed step (found by the replay), same layout as checkpoint.npz."""

KERNEL_DESCRIPTIONS = {
    "accumulate_spring_forces": "spring forces",
    "integrate_velocities": "velocity update v += dt f/m",
    "pbd_damping": "PBD damping",
    "integrate_positions": "position update x += dt v",
    "apply_attachments": "attachments",
    "limit_strain": "strain limiting",
    "collide_rigid": "rigid-body collisions",
    "velocities_from_positions": "velocity post-process v = (x - x_prev) / dt",
}


def _kernel_name(fn: Callable) -> str:
    return getattr(fn, "__name__", None) or type(fn).__name__


def particle_diagnostic(model: Model, state: State, particle: int, limit: int = 8) -> dict:
    """Where a particle sits and its springs, the most strained first (non-finite counts as most)."""
    n = model.crossing_count
    crossing = particle % n
    i, j = crossing % model.warp_yarns, crossing // model.warp_yarns
    if particle >= n:
        layer = "warp mass of a yarn-level couple"
    elif state.crossing_yarn_level[crossing]:
        layer = "weft mass of a yarn-level couple"
    else:
        layer = "base mass"
    at = np.nonzero((state.spring_particle_a == particle) | (state.spring_particle_b == particle))[0]
    x = state.particle_position_m
    with np.errstate(invalid="ignore", over="ignore"):
        length = np.linalg.norm(x[state.spring_particle_b[at]] - x[state.spring_particle_a[at]], axis=1)
        strain = length / model.spring_rest_length_m[at] - 1.0
    badness = np.where(np.isfinite(strain), np.abs(strain), np.inf)
    order = np.argsort(-badness, kind="stable")
    springs = []
    for k in order[:limit]:
        s = int(at[k])
        springs.append({
            "spring": s,
            "kind": SPRING_KIND_NAMES[int(model.spring_kind[s])],
            "alive": bool(state.spring_alive[s]),
            "other_particle": int(state.spring_particle_b[s] if state.spring_particle_a[s] == particle
                                  else state.spring_particle_a[s]),
            "stiffness_n_per_m": float(state.spring_stiffness_n_per_m[s]),
            "strain": float(strain[k]) if np.isfinite(strain[k]) else str(strain[k]),
        })
    return {
        "particle": int(particle),
        "crossing": [int(i), int(j)],
        "layer": layer,
        "mass_kg": float(state.particle_mass_kg[particle]),
        "position_m": [float(v) for v in x[particle]],
        "velocity_m_s": [float(v) for v in state.particle_velocity_m_s[particle]],
        "springs": springs,
        "spring": springs[0]["spring"] if springs else None,
    }


def unstable_diagnostic(solver: "SolverExplicitPBD", state: State, particle: int, stage: str,
                        kernel: str, dt_s: Optional[float] = None) -> dict:
    """The diagnostic dict of SimulationUnstable (JSON-ready)."""
    from fraytool.sim.stability import stable_step_bound_s

    diag = {
        "step": int(state.step_index),
        "time_s": float(state.time_s),
        "stage": stage,
        "kernel": kernel,
        "stage_located": stage != "end of step",
        "speed_limit_m_s": solver.speed_limit_m_s,
    }
    if particle >= 0:
        diag.update(particle_diagnostic(solver.model, state, particle))
    if dt_s is not None:
        bound = stable_step_bound_s(solver.model)
        diag["step_s"] = float(dt_s)
        diag["stability_bound_s"] = bound
        diag["step_over_bound"] = float(dt_s / bound) if bound > 0 else math.inf
    return diag


def unstable_message(diag: dict, where: str = "") -> str:
    """One line for the user: when, where, which mass and spring, what to change."""
    stage = diag.get("stage", "end of step")
    kernel = diag.get("kernel")
    if diag.get("stage_located"):
        stage_txt = f"in stage {stage} ({KERNEL_DESCRIPTIONS.get(kernel, kernel)})"
    else:
        stage_txt = "at the end of the step"
    parts = [f"simulation became unstable at step {diag['step']} (t = {diag['time_s']:.6g} s) {stage_txt}"]
    if "particle" in diag:
        v = diag.get("velocity_m_s") or [math.nan] * 3
        speed = math.sqrt(sum(c * c for c in v))
        what = "a non-finite value" if not all(math.isfinite(c) for c in v + diag.get("position_m", [])) \
            else f"speed {speed:.3g} m/s (limit {diag['speed_limit_m_s']:g} m/s)"
        i, j = diag["crossing"]
        parts.append(f"mass {diag['particle']} (warp yarn {i}, weft yarn {j}, {diag['layer']}) has {what}")
        if diag.get("springs"):
            s = diag["springs"][0]
            strain = s["strain"] if isinstance(s["strain"], str) else f"{s['strain']:.3g}"
            parts.append(f"its most strained spring is {s['spring']} ({s['kind']}, k = {s['stiffness_n_per_m']:g} N/m, "
                         f"strain {strain})")
    if "body" in diag:
        parts.append(f"rigid body {diag['body']} has a non-finite position")
    if "step_over_bound" in diag:
        parts.append(f"step {diag['step_s']:.3g} s is {diag['step_over_bound']:.2f} x the stability bound "
                     f"{diag['stability_bound_s']:.3g} s")
    if "last_good_frame" in diag:
        parts.append(f"frames up to {diag['last_good_frame']} are kept")
    if where:
        parts.append(f"diagnostic in {where}")
    return "; ".join(parts) + f". {_advice(diag)}"


def _advice(diag: dict) -> str:
    over = diag.get("step_over_bound", 0.0)
    if over > 1.0:
        return (f"To fix: use [time] step_s <= {diag['stability_bound_s']:.3g} s (more steps_per_frame), "
                "or lower the stiffness, or raise the masses.")
    if diag.get("stage_located") and diag.get("kernel") not in KERNEL_DESCRIPTIONS:
        return (f"The step is within the stability bound and the bad value came from the pass "
                f"{diag.get('kernel')!r}: report it with the diagnostic file.")
    return ("The step is within the linear stability bound, so a violent event (fast bodies, a hard pull, "
            "strain limiting that cannot keep up) did this: try a smaller [time] step_s, slower bodies, or more "
            "[cloth.strain] max_iterations.")


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


def make_stage_check(solver: "SolverExplicitPBD", state: State, dt_s: float) -> Callable[[str, Callable], None]:
    """The check run after every stage of one replayed step; raises StageFailure at the first bad value."""
    active = np.nonzero(state.particle_active)[0]
    moved = {"positions": False, "forces": False}

    def check(stage: str, fn: Callable) -> None:
        kernel = _kernel_name(fn)
        if kernel == "accumulate_spring_forces":
            moved["forces"] = True
        if kernel == "integrate_positions":
            moved["positions"] = True
        bad = -1
        if moved["forces"]:
            bad = _first_bad_row(solver._force, active)
        if bad < 0:
            bad = _first_bad_row(state.particle_velocity_m_s, active, solver.speed_limit_m_s)
        if bad < 0 and moved["positions"]:
            bad = _first_bad_row(state.particle_position_m, active)
            if bad < 0:
                bad = _first_bad_row((state.particle_position_m - solver._prev) / dt_s, active, solver.speed_limit_m_s)
        body = -1
        if bad < 0 and state.body_position_m.size:
            body = _first_bad_row(state.body_position_m, np.arange(state.body_position_m.shape[0]))
        if bad >= 0 or body >= 0:
            diag = unstable_diagnostic(solver, state, bad, stage, kernel, dt_s)
            if body >= 0:
                diag["body"] = solver.model.body_names[body]
            raise StageFailure(diag)

    return check


def replay_failed_step(solver: "SolverExplicitPBD", start: State, dt_s: float, failed_step: int
                       ) -> tuple[Optional[dict], Optional[State]]:
    """Replay from `start` (not modified) up to step `failed_step` (the State.step_index the failed
    step would have produced), checking every stage of the last step.

    Returns (stage diagnostic or None if the replay did not fail, State just before the failed step).
    """
    from fraytool.sim.solver import SimulationUnstable

    steps = failed_step - start.step_index
    if steps < 1:
        return None, None
    saved = (dict(solver.stage_s), solver.strain_iterations_last, solver.strain_iterations_max,
             solver.strain_cap_hits, solver.rigid_contacts_last)
    state = start.copy()
    try:
        for _ in range(steps - 1):
            solver.step(state, dt_s)
        before = state.copy()
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
        (solver.stage_s, solver.strain_iterations_last, solver.strain_iterations_max,
         solver.strain_cap_hits, solver.rigid_contacts_last) = saved


def explain_failure(solver: "SolverExplicitPBD", start: Optional[State], dt_s: float, diagnostic: dict) -> tuple[dict, Optional[State]]:
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


def write_failure(folder: Path, diagnostic: dict, last_good: Optional[State]) -> Path:
    """Write unstable.json (and the last good State, if known) into `folder`; returns the JSON path."""
    from fraytool.io.frame_record import atomic_save_npz, atomic_write_bytes

    folder = Path(folder)
    if last_good is not None:
        atomic_save_npz(folder / LAST_GOOD_STATE, last_good.arrays())
        diagnostic["last_good_state"] = LAST_GOOD_STATE
        diagnostic["last_good_state_step"] = int(last_good.step_index)
    text = json.dumps(_finite_json(diagnostic), indent=2, sort_keys=True, default=_json_default).encode()
    path = folder / UNSTABLE_JSON
    atomic_write_bytes(path, lambda f: f.write(text))
    return path


def _finite_json(obj):
    """JSON has no NaN or infinity: write them as the strings "nan", "inf", "-inf"."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    if isinstance(obj, dict):
        return {k: _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_json(v) for v in obj]
    return obj


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)


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

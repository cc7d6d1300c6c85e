"""What the stability guard says when a step produced a non-finite or absurd value: which mass, its
springs (the most strained first), the stage and kernel, and the step against the stability bound
(docs/study.md). Plain dicts, ready for JSON; fraytool.sim.guard adds the stage by replaying.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from fraytool.kinds import SPRING_KIND_NAMES
from fraytool.sim.model import Model
from fraytool.sim.stability import stable_step_bound_s
from fraytool.sim.state import State

KERNEL_DESCRIPTIONS = {
    "accumulate_spring_forces": "spring forces",
    "integrate_velocities": "velocity update v += dt f/m",
    "pbd_damping": "PBD damping",
    "integrate_positions": "position update x += dt v",
    "apply_attachments": "attachments",
    "limit_strain": "strain limiting",
    "limit_strain_groups": "strain limiting",
    "limit_strain_lines": "strain limiting, yarn by yarn",
    "collide_rigid": "rigid-body collisions",
    "collide_rigid (before strain limiting)": "rigid-body collisions, before strain limiting",
    "velocities_from_positions": "velocity post-process v = (x - x_prev) / dt",
}


def particle_diagnostic(model: Model, state: State, particle: int, limit: int = 8) -> dict:
    """Where a particle sits and its springs, the most strained first (non-finite counts as most)."""
    n = model.crossing_count
    crossing = particle % n
    i, j = int(model.crossing_grid_i[crossing]), int(model.crossing_grid_j[crossing])
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
        strain = length / state.spring_rest_length_m[at] - 1.0
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


def unstable_diagnostic(model: Model, speed_limit_m_s: float, state: State, particle: int, stage: str,
                        kernel: str, dt_s: Optional[float] = None) -> dict:
    """The diagnostic dict of SimulationUnstable (JSON-ready)."""
    diag = {
        "step": int(state.step_index),
        "time_s": float(state.time_s),
        "stage": stage,
        "kernel": kernel,
        "stage_located": stage != "end of step",
        "speed_limit_m_s": speed_limit_m_s,
    }
    if particle >= 0:
        diag.update(particle_diagnostic(model, state, particle))
    if dt_s is not None:
        bound = stable_step_bound_s(model)
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

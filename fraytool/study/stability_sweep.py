"""`fraytool study --stability SCENE`: stiff and extreme variants of a scene, each run and classified.

Each case changes one thing of the scene (all else as given) and runs a short stretch of time:
- stiffness: structural, bend and shear stiffness x 0.01 ... x 1000 at the scene's step;
- step: h = 0.5 ... 3 x the stability bound 2/ω_max (power iteration) of the scene;
- pull: a corner grabbed by a ball moving away in the cloth's plane at 1 ... 100 m/s;
- impact: a ball thrown through the middle of the cloth at 5 ... 50 m/s;
- mass: mass per crossing x 0.001 ... x 1000 (very light and very heavy cloth);
- thin: thickness x 0.1 and x 0.01 (very thin cloth: tiny contact margin).
The outcome of a case is, in this order:
- "unstable": the stability guard stopped it (non-finite, or faster than the speed limit); the
  stage, mass and spring come from replaying the failed step;
- "oscillating": it finished, but the cloth shook step to step by more than JITTER_LIMIT of the yarn
  spacing (fraytool.study.runner): the explicit instability, held bounded by strain limiting, which
  keeps speeds below the guard's limit;
- "strain_over_limit": it finished, but a structural strain passed the limit by more than
  STRAIN_SLACK x the limit (strain limiting could not keep up, e.g. under a fast pull);
- "stable".
The same classification checks the expectations of the scenes in scenes/stress/ (`classify`).
"""
from __future__ import annotations

import dataclasses as dc
import math
import sys
from dataclasses import dataclass, field
from typing import Optional, TextIO

import numpy as np

from fraytool.scene.spec import AttachmentSpec, BodySpec, SceneSpec
from fraytool.sim.builder import build_model
from fraytool.sim.stability import stability_report
from fraytool.sim.guard import JITTER_LIMIT
from fraytool.study.runner import RunResult, run_variant, warm_up

STRAIN_SLACK = 0.1
"""A strain above limit x (1 + STRAIN_SLACK) counts as over the limit (the solver stops at a tolerance)."""
OUTCOMES = ("stable", "strain_over_limit", "oscillating", "unstable")
SWEEP_TIME_S = 0.5
"""Simulated time of each case [s] (at most the scene's duration); half with --quick."""

_PLANE_NORMAL = {"xz": (0.0, 1.0, 0.0), "xy": (0.0, 0.0, 1.0), "yz": (1.0, 0.0, 0.0)}
_PLANE_AXES = {"xz": (0, 2), "xy": (0, 1), "yz": (2, 1)}


def classify(result: RunResult, strain_limit: float) -> str:
    """The outcome of a run (module docstring)."""
    if not result.ok:
        return "unstable"
    if result.max_jitter > JITTER_LIMIT:
        return "oscillating"
    if result.max_strain > strain_limit * (1.0 + STRAIN_SLACK):
        return "strain_over_limit"
    return "stable"


@dataclass
class SweepCase:
    name: str
    group: str
    value: float
    spec: SceneSpec
    result: RunResult
    outcome: str
    report: dict
    """fraytool.sim.stability.stability_report of the case's model and step."""
    body_speed_m_s: float = 0.0

    @property
    def step_over_bound_power(self) -> float:
        return self.report["step_over_bound_power"]

    def row(self) -> dict:
        d = self.result.diagnostic or {}
        s = self.spec
        return {
            "case": self.name, "group": self.group, "value": self.value, "outcome": self.outcome,
            "step_s": s.time.step_s, "step_over_bound_gershgorin": self.report["step_over_bound_gershgorin"],
            "step_over_bound_power": self.report["step_over_bound_power"],
            "structural_n_per_m": s.cloth.springs.structural_n_per_m,
            "mass_per_crossing_kg": s.cloth.mass_per_crossing_kg, "thickness_m": s.cloth.thickness_m,
            "body_speed_m_s": self.body_speed_m_s, "frames": self.result.frames, "steps": self.result.steps,
            "wall_s": self.result.wall_s, "max_strain": self.result.max_strain if self.result.ok else None,
            "strain_limit": s.cloth.strain.limit,
            "max_speed_m_s": self.result.max_speed_m_s if self.result.ok else None,
            "max_jitter": self.result.max_jitter if self.result.ok else None,
            "strain_cap_hits": self.result.strain_cap_hits,
            "guard_stage": d.get("stage") if d else None, "guard_particle": d.get("particle") if d else None,
            "guard_spring": d.get("spring") if d else None, "guard_step": d.get("step") if d else None,
            "expected": "stable" if self.report["step_over_bound_power"] <= 1.0 else "past the bound",
        }


@dataclass
class SweepResult:
    scene: str
    base_step_s: float
    base_bound_power_s: float
    base_bound_gershgorin_s: float
    frames: int
    frame_s: float
    strain_limit: float
    cases: list[SweepCase]
    notes: list[str] = field(default_factory=list)
    strain_slack: float = STRAIN_SLACK
    jitter_limit: float = JITTER_LIMIT


# --- variants ---------------------------------------------------------------------------------------

def scaled_stiffness(spec: SceneSpec, factor: float) -> SceneSpec:
    k = spec.cloth.springs
    springs = dc.replace(k, structural_n_per_m=k.structural_n_per_m * factor, bend_n_per_m=k.bend_n_per_m * factor,
                         shear_n_per_m=k.shear_n_per_m * factor)
    return dc.replace(spec, cloth=dc.replace(spec.cloth, springs=springs))


def with_step(spec: SceneSpec, step_s: float) -> SceneSpec:
    """Step `step_s` with about the same simulated time per frame."""
    t = spec.time
    spf = max(1, round(t.step_s * t.steps_per_frame / step_s))
    return dc.replace(spec, time=dc.replace(t, step_s=step_s, steps_per_frame=spf))


def scaled_mass(spec: SceneSpec, factor: float) -> SceneSpec:
    return dc.replace(spec, cloth=dc.replace(spec.cloth, mass_per_crossing_kg=spec.cloth.mass_per_crossing_kg * factor))


def scaled_thickness(spec: SceneSpec, factor: float) -> SceneSpec:
    return dc.replace(spec, cloth=dc.replace(spec.cloth, thickness_m=spec.cloth.thickness_m * factor))


def _cloth_geometry(spec: SceneSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rest positions of the crossings, centre, unit normal of the cloth's plane)."""
    model = build_model(spec)
    rest = model.crossing_rest_position_m
    return rest, rest.mean(axis=0), np.asarray(_PLANE_NORMAL[spec.cloth.plane])


def with_corner_pull(spec: SceneSpec, speed_m_s: float) -> SceneSpec:
    """A ball grabs a free corner (2 x 2 crossings) and moves away in the cloth's plane at speed_m_s."""
    c = spec.cloth
    model = build_model(spec)
    rest = model.crossing_rest_position_m
    nx, ny = c.warp_yarns, c.weft_yarns
    held = set(model.attachment_particle.tolist())
    corners = {"top_right": (nx - 1, ny - 1), "bottom_right": (nx - 1, 0), "top_left": (0, ny - 1), "bottom_left": (0, 0)}
    name, (i, j) = next(((k, v) for k, v in corners.items() if v[1] * nx + v[0] not in held), ("top_right", corners["top_right"]))
    p = rest[j * nx + i]
    direction = p - rest.mean(axis=0)
    direction /= max(np.linalg.norm(direction), 1e-12)
    body = BodySpec(name="stress_grip", shape="sphere", motion="kinematic", position_m=tuple(float(v) for v in p),
                    radius_m=0.5 * c.spacing_m, velocity_m_s=tuple(float(v) for v in speed_m_s * direction),
                    collide=False, gravity=False)
    att = AttachmentSpec(body="stress_grip", corner=name, corner_size=min(2, nx, ny))
    return dc.replace(spec, bodies=spec.bodies + (body,), attachments=spec.attachments + (att,))


def with_impact(spec: SceneSpec, speed_m_s: float) -> SceneSpec:
    """A ball (radius a sixth of the cloth's width) thrown through the cloth's middle at speed_m_s."""
    c = spec.cloth
    rest, centre, normal = _cloth_geometry(spec)
    width = c.spacing_m * (min(c.warp_yarns, c.weft_yarns) - 1)
    radius = max(width / 6.0, 2.0 * c.spacing_m)
    start = centre + normal * (radius + 2.0 * c.spacing_m)
    body = BodySpec(name="stress_ball", shape="sphere", motion="kinematic", position_m=tuple(float(v) for v in start),
                    radius_m=radius, velocity_m_s=tuple(float(v) for v in -speed_m_s * normal), collide=True,
                    gravity=False, friction=0.3)
    return dc.replace(spec, bodies=spec.bodies + (body,))


def sweep_cases(spec: SceneSpec, quick: bool = False) -> list[tuple[str, str, float, SceneSpec, float]]:
    """(name, group, value, scene, body speed) for every case."""
    bound = stability_report(build_model(spec), spec.time.step_s)["stability_bound_power_s"]
    out: list[tuple[str, str, float, SceneSpec, float]] = [("scene as given", "base", 1.0, spec, 0.0)]
    for f in ((0.1, 10, 1000) if quick else (0.01, 0.1, 10, 100, 1000)):
        out.append((f"stiffness x{f:g}", "stiffness", f, scaled_stiffness(spec, f), 0.0))
    if math.isfinite(bound):
        for f in ((0.9, 1.1, 2.0) if quick else (0.5, 0.9, 1.1, 1.5, 3.0)):
            out.append((f"step {f:g} x bound", "step", f, with_step(spec, f * bound), 0.0))
    for v in ((10.0, 100.0) if quick else (1.0, 10.0, 100.0)):
        out.append((f"pull {v:g} m/s", "pull", v, with_corner_pull(spec, v), v))
    for v in ((50.0,) if quick else (5.0, 50.0)):
        out.append((f"impact {v:g} m/s", "impact", v, with_impact(spec, v), v))
    for f in ((1e-3, 1e3) if quick else (1e-3, 1e-2, 1e2, 1e3)):
        out.append((f"mass x{f:g}", "mass", f, scaled_mass(spec, f), 0.0))
    for f in ((0.01,) if quick else (0.1, 0.01)):
        out.append((f"thickness x{f:g}", "thin", f, scaled_thickness(spec, f), 0.0))
    return out


def run_case(name: str, group: str, value: float, spec: SceneSpec, frames: int, body_speed: float = 0.0) -> SweepCase:
    result = run_variant(spec, frames, record=False)
    report = stability_report(build_model(spec), spec.time.step_s)
    return SweepCase(name, group, value, spec, result, classify(result, spec.cloth.strain.limit), report, body_speed)


def run_stability_sweep(spec: SceneSpec, quick: bool = False, stream: Optional[TextIO] = sys.stderr) -> SweepResult:
    frame_s = spec.time.step_s * spec.time.steps_per_frame
    duration = min(SWEEP_TIME_S * (0.5 if quick else 1.0), frame_s * (spec.time.frames - 1))
    frames = max(1, int(round(duration / frame_s)))
    base_report = stability_report(build_model(spec), spec.time.step_s)
    warm_up(spec)
    cases = []
    todo = sweep_cases(spec, quick)
    for k, (name, group, value, cspec, speed) in enumerate(todo, 1):
        if stream is not None:
            print(f"stability sweep {spec.name}: case {k}/{len(todo)} {name} ...", file=stream, flush=True)
        # the step cases keep the simulated time, not the frame count
        n = max(1, int(round(duration / (cspec.time.step_s * cspec.time.steps_per_frame))))
        cases.append(run_case(name, group, value, cspec, n, speed))
    notes = []
    past = [c for c in cases if c.step_over_bound_power > 1.0 and c.outcome == "stable"]
    if past:
        notes.append("Stable past the bound: " + ", ".join(f"{c.name} ({c.step_over_bound_power:.2f} x)" for c in past)
                     + ". The bound takes every spring at full stiffness in every direction (the worst case over "
                       "stretched states); at rest a spring is stiff only along itself and shear springs push only "
                       "in compression, so the cloth's real threshold can be higher (up to about sqrt 2 x for a "
                       "grid). The bound is exact for a straight chain.")
    held = [c for c in cases if c.outcome == "oscillating"]
    if held:
        notes.append("Oscillating: " + ", ".join(c.name for c in held) + ". Past the bound, strain limiting caps the "
                     "stretch, so speeds stay under the guard's limit and the guard does not stop the run; the cloth "
                     "shakes at the yarn spacing every step. Treat these as unstable.")
    return SweepResult(scene=spec.name, base_step_s=spec.time.step_s,
                       base_bound_power_s=base_report["stability_bound_power_s"],
                       base_bound_gershgorin_s=base_report["stability_bound_gershgorin_s"],
                       frames=frames, frame_s=frame_s, strain_limit=spec.cloth.strain.limit, cases=cases, notes=notes)

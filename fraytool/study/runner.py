"""One timed, guarded run of a scene variant, recording what the studies compare.

`run_variant` simulates a SceneSpec for a number of frames and returns a `RunResult`:
- wall time of the steps only (time.perf_counter around the step loop; building the model, numba
  compilation and copying the recorded positions are left out — call `warm_up` once first);
- the base-mass positions at every frame (for trajectory errors), if asked;
- the largest structural strain, speed and step-to-step jitter seen at the frame ends;
- tearing statistics when the scene tears: time of the first break (to the step), broken springs
  and torn length at every frame, and the tear at the last frame (`tear_figures`: the tear and fray
  figures of the `fraytool simulate --json` summary and the centroid of the broken structural springs);
- for a run the stability guard stopped: the guard's diagnostic, with the stage found by replaying
  the failed step from the state at the start of its frame (fraytool.sim.guard).

Jitter (fraytool.sim.guard.jitter_ratio, over the last three steps of each frame, carried across
frames when a frame has fewer steps): the amplitude of a step-to-step oscillation as a fraction of
the yarn spacing. Smooth motion, even violent, stays far below JITTER_LIMIT; past the stability
bound, or where constraints fight each other (strain limits against attachments or contacts), the
cloth shakes at the yarn spacing, and when strain limiting holds that bounded only this sees it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from fraytool.scene.spec import SceneSpec
from fraytool.sim.guard import explain_failure, jitter_ratio
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.simulation import Simulation
from fraytool.sim.solver import SimulationUnstable


@dataclass
class RunResult:
    spec: SceneSpec
    frames: int
    """Frames simulated after frame 0."""
    steps: int = 0
    """Steps completed."""
    wall_s: float = 0.0
    """Wall time of the steps [s] (perf_counter, compilation excluded)."""
    status: str = "ok"
    """"ok" or "unstable" (stopped by the stability guard)."""
    diagnostic: Optional[dict] = None
    """The guard's diagnostic (with the stage) when status == "unstable"."""
    positions: Optional[np.ndarray] = None
    """Base-mass positions at frames 0..frames [m], shape (frames + 1, crossing_count, 3), if recorded."""
    max_strain: float = 0.0
    """Largest structural strain at any frame end."""
    max_speed_m_s: float = 0.0
    """Largest particle speed at any frame end [m/s]."""
    max_jitter: float = 0.0
    """Largest jitter ratio over the frames (see the module docstring)."""
    strain_cap_hits: int = 0
    """Steps where strain limiting stopped at its iteration cap."""
    tearing: dict = field(default_factory=dict)
    """Tearing statistics: first_break_s [s] (None without a break), broken_springs and torn_length_m
    (lists, one value per frame from frame 0), final (`tear_figures` at the last frame simulated)."""

    final_state: Optional[object] = None
    """The State after the last step (run_variant with keep_state=True), else None."""
    final_model: Optional[object] = None
    """Its Model (with keep_state=True)."""

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def spec_frames(spec: SceneSpec) -> int:
    return spec.time.frames - 1


def warm_up(spec: SceneSpec) -> None:
    """Compile (or load from numba's cache) every kernel the scene uses, outside any timing."""
    sim = Simulation(spec)
    try:
        for _ in range(2):
            sim.step()
    except SimulationUnstable:
        pass


def structural_mask(sim: Simulation) -> np.ndarray:
    kinds = sim.model.spring_kind
    return (kinds == STRUCT_WEFT) | (kinds == STRUCT_WARP)


def torn_length_m(sim: Simulation, structural: np.ndarray) -> float:
    """Rest length of the broken structural springs [m]: each yarn cut across a tear counts its
    segment once, so a tear crossing N yarns measures about N spacings (a frayed edge adds more)."""
    broken = sim.state.spring_broken & structural
    return float(sim.model.spring_rest_length_m[broken].sum())


def tear_figures(sim: Simulation, structural: Optional[np.ndarray] = None) -> dict:
    """The tear of the current state, as the studies compare it:
    - broken_springs, yarn_level_crossings (torn crossings: crossings split into mass couples),
      fray_mean_free_end_m, pieces: the figures of `Simulation.summary` (`fraytool simulate --json`);
    - broken_structural_springs and torn_length_m (their rest length at build, `torn_length_m`);
    - centroid_m: the mean rest position of the midpoints of the broken structural springs [m]
      (None when none is broken): where the tear is in the cloth, independent of its motion."""
    structural = structural_mask(sim) if structural is None else structural
    summary = sim.summary()
    m = sim.model
    broken = sim.state.spring_broken & structural
    centroid = None
    if broken.any():
        rest = m.crossing_rest_position_m
        mid = 0.5 * (rest[m.spring_crossing_a[broken]] + rest[m.spring_crossing_b[broken]])
        centroid = [float(c) for c in mid.mean(axis=0)]
    return {
        "broken_springs": int(summary["broken_springs"]),
        "yarn_level_crossings": int(summary.get("yarn_level_crossings", 0)),
        "fray_mean_free_end_m": float(summary.get("fray_mean_free_end_m", 0.0)),
        "pieces": summary.get("pieces"),
        "broken_structural_springs": int(broken.sum()),
        "torn_length_m": torn_length_m(sim, structural),
        "centroid_m": centroid,
    }


def run_variant(spec: SceneSpec, frames: Optional[int] = None, record: bool = False,
                locate_stage: bool = True, keep_state: bool = False) -> RunResult:
    """Simulate `frames` frames (default: the scene's) of `spec`; never raises SimulationUnstable."""
    frames = spec_frames(spec) if frames is None else frames
    sim = Simulation(spec)
    n = sim.model.crossing_count
    h = sim.dt_s
    spf = sim.steps_per_frame
    out = RunResult(spec=spec, frames=frames)
    tears = sim.model.tearing
    structural = structural_mask(sim)
    if record:
        out.positions = np.empty((frames + 1, n, 3))
        out.positions[0] = sim.state.particle_position_m[:n]
    if tears:
        out.tearing = {"first_break_s": None, "broken_springs": [0], "torn_length_m": [0.0]}
    wall = 0.0
    frame_start = sim.state.copy()
    recent: list[tuple[int, np.ndarray]] = []

    def advance(steps: int) -> None:
        for _ in range(steps):
            sim.step()
            if tears and out.tearing["first_break_s"] is None and sim.state.spring_broken.any():
                out.tearing["first_break_s"] = sim.state.time_s  # to the step, not to the frame

    try:
        for f in range(1, frames + 1):
            if locate_stage:
                frame_start = sim.state.copy()
            tail = min(spf, 3)  # the last steps of the frame, with their velocities (for the jitter)
            t0 = time.perf_counter()
            advance(spf - tail)
            wall += time.perf_counter() - t0
            for _ in range(tail):
                t0 = time.perf_counter()
                advance(1)
                wall += time.perf_counter() - t0
                free = sim.state.particle_inv_mass > 0.0  # held masses follow their body
                recent.append((sim.state.step_index, sim.state.particle_velocity_m_s[free].copy()))
                del recent[:-3]
            sim.complete()  # the frame's record as advance_frame leaves it
            out.steps = sim.state.step_index
            v_after = recent[-1][1]
            (n0, v0), (n1, v1), (n2, v2) = recent if len(recent) == 3 else [(0, None)] * 3
            if n2 - n0 == 2 and v0.shape == v1.shape == v2.shape:  # three consecutive steps
                out.max_jitter = max(out.max_jitter, jitter_ratio(v0, v1, v2, h, spec.cloth.spacing_m))
            strain = sim.structural_strain()
            if strain.size:
                out.max_strain = max(out.max_strain, float(strain.max()))
            speed = np.sqrt((v_after * v_after).sum(axis=1))
            if speed.size:
                out.max_speed_m_s = max(out.max_speed_m_s, float(speed.max()))
            if record:
                out.positions[f] = sim.state.particle_position_m[:n]
            if tears:
                out.tearing["broken_springs"].append(sim.broken_springs())
                out.tearing["torn_length_m"].append(torn_length_m(sim, structural))
    except SimulationUnstable as exc:
        out.status = "unstable"
        out.steps = exc.diagnostic.get("step", sim.state.step_index)
        diag = exc.diagnostic
        if locate_stage:
            diag, _ = explain_failure(sim.solver, frame_start, h, exc.diagnostic)
        out.diagnostic = diag
        if record:
            out.positions = None
    out.wall_s = wall
    if tears:
        out.tearing["final"] = tear_figures(sim, structural)
    out.strain_cap_hits = sim.solver.strain_cap_hits
    if keep_state:
        out.final_state, out.final_model = sim.state, sim.model
    return out

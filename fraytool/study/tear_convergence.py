"""Convergence of the tear in the step: the tearing part of `fraytool study` (docs/study.md).

A tear is decided step by step (a spring breaks in the step its strain passes its limit), so the
trajectories of a tearing cloth do not converge like a smooth motion (the accuracy study compares
those with tearing off). What must converge is the tear itself. The scene runs with tearing on at
the steps h0, h0/2, h0/4, h0/8 and h0/16 (h0 the scene's step; steps per frame scaled so that every
run reaches the same simulated time, a whole number of frames; damping per second kept, as in the
accuracy study; everything else as in the scene), and the state at that time is compared by:
- broken springs (of every kind: `broken_springs` of `fraytool simulate --json`);
- the time of the first break [s], to the step;
- torn crossings: crossings split to the yarn level (`yarn_level_crossings`);
- the mean free-end length [m] (`fray_mean_free_end_m`, docs/tearing.md "Fray metric");
- the centroid of the broken structural springs: the mean rest position of their midpoints [m],
  compared by its distance in yarn spacings.
h0/8 is the reference and h0/16 checks it. Criterion, per quantity: the scene's step is within 15 %
of the reference, and the reference within 15 % of h0/16, so the reference itself is converged
(centroid: within 2 yarn spacings, both times).

Relative difference of a against b: |a - b| / |b|; 0 when both are 0 (or neither run broke anything,
for the time of the first break and the centroid); infinite when only b is 0 or only one run broke.
Each run is compared with the reference, and the reference with h0/16.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Optional, TextIO

import numpy as np

from fraytool.scene.spec import SceneSpec
from fraytool.sim.builder import build_model
from fraytool.study.steps import (TEAR_REFERENCE_FACTOR, TEAR_STEP_FACTORS, step_label, with_frames,
                                  with_step_factor)
from fraytool.study.runner import RunResult, run_variant, warm_up

TOLERANCE = 0.15
"""Relative difference allowed between the scene's step and the reference, and between the reference
and the check run (issue: "within 15 %")."""
CENTROID_TOLERANCE_SPACINGS = 2.0
"""Distance between centroids allowed, in yarn spacings."""

QUANTITIES = (
    ("broken_springs", "broken springs"),
    ("first_break_s", "time of the first break"),
    ("yarn_level_crossings", "torn crossings"),
    ("fray_mean_free_end_m", "mean free-end length"),
)
"""The counts compared by relative difference: (key in the figures and in runs.csv, label)."""
CENTROID = ("centroid", "centroid of the broken springs")
CENTROID_DISTANCE = "centroid_distance_spacings"


def relative_difference(a: Optional[float], b: Optional[float]) -> float:
    """|a - b| / |b|; 0 when both are 0 or both None (nothing broke); inf when only b is 0 or one is None."""
    if a is None and b is None:
        return 0.0
    if a is None or b is None:
        return math.inf
    if b == 0:
        return 0.0 if a == 0 else math.inf
    return abs(a - b) / abs(b)


def centroid_distance(a: Optional[list], b: Optional[list], spacing_m: float) -> float:
    """Distance between two centroids in yarn spacings (0 when neither exists, inf when one does)."""
    if a is None and b is None:
        return 0.0
    if a is None or b is None:
        return math.inf
    return float(np.linalg.norm(np.subtract(a, b))) / spacing_m


@dataclass
class TearRun:
    """One step of the tearing study."""

    name: str
    """Step label: "h0", "h0/2", ..."""
    factor: float
    """Step / the scene's step."""
    result: RunResult
    role: str = ""
    """"shipped" (the scene's step), "reference", "check" (the run that checks the reference) or ""."""
    compared_with: str = ""
    """The run the relative differences are taken against (the reference; for the reference, the check)."""
    rel_diff: dict = field(default_factory=dict)
    """Relative difference of each quantity against `compared_with`, and centroid_distance_spacings."""

    @property
    def step_s(self) -> float:
        return self.result.spec.time.step_s

    @property
    def figures(self) -> dict:
        """first_break_s and the tear at the last frame (fraytool.study.runner.tear_figures)."""
        t = self.result.tearing
        return {"first_break_s": t.get("first_break_s"), **t.get("final", {})}

    def row(self) -> dict:
        """The runs.csv row (fraytool.study.report.RUN_COLUMNS)."""
        s = self.result.spec
        fig = self.figures
        centroid = fig.get("centroid_m") or [None, None, None]
        row = {"run": f"step {self.name}, tearing on", "varied": "step, tearing on", "value": self.step_s,
               "role": self.role, "step_s": self.step_s, "steps_per_frame": s.time.steps_per_frame,
               "strain_max_iterations": s.cloth.strain.max_iterations, "strain_tolerance": s.cloth.strain.tolerance,
               "collision_iterations": s.self_collision.iterations if s.self_collision.enabled else None,
               "damping": s.cloth.springs.damping, "frames": self.result.frames,
               "simulated_s": self.result.frames * s.time.step_s * s.time.steps_per_frame,
               "steps": self.result.steps, "wall_s": self.result.wall_s, "status": self.result.status,
               "max_strain": self.result.max_strain, "strain_cap_hits": self.result.strain_cap_hits,
               "max_jitter": self.result.max_jitter, "compared_with": self.compared_with,
               "centroid_x_m": centroid[0], "centroid_y_m": centroid[1], "centroid_z_m": centroid[2],
               CENTROID_DISTANCE: self.rel_diff.get(CENTROID_DISTANCE),
               "broken_structural_springs": fig.get("broken_structural_springs"),
               "torn_length_m": fig.get("torn_length_m"), "pieces": fig.get("pieces")}
        for key, _ in QUANTITIES:
            row[key] = fig.get(key)
            row[f"{key}_rel_diff"] = self.rel_diff.get(key)
        return row


@dataclass
class Verdict:
    """PASS/FAIL of one quantity."""

    key: str
    label: str
    shipped: float
    """The scene's step against the reference (relative difference, or spacings for the centroid)."""
    reference: float
    """The reference against the check run."""
    tolerance: float
    unit: str
    """"relative" or "spacings"."""
    passed: bool
    reason: str = ""
    """Why it failed when not because of a difference (a run the guard stopped)."""


@dataclass
class TearingStudy:
    scene: str
    frames: int
    """Frames simulated after frame 0 (the same simulated time in every run)."""
    frame_s: float
    base_step_s: float
    spacing_m: float
    bounds_m: tuple[list, list]
    """The cloth's rest bounds (lowest and highest corner) [m]."""
    runs: list[TearRun]
    """Coarsest first."""
    shipped: str
    reference: str
    check: Optional[str]
    verdicts: list[Verdict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return self.frames * self.frame_s

    @property
    def passed(self) -> bool:
        return bool(self.verdicts) and all(v.passed for v in self.verdicts)

    def run(self, name: str) -> TearRun:
        return next(r for r in self.runs if r.name == name)

    def rows(self) -> list[dict]:
        return [r.row() for r in self.runs]


def _say(stream: Optional[TextIO], text: str) -> None:
    if stream is not None:
        print(text, file=stream, flush=True)


def compare(a: TearRun, b: TearRun, spacing_m: float) -> dict:
    """Relative differences of a's quantities against b's, and the distance of the centroids."""
    fa, fb = a.figures, b.figures
    out = {key: relative_difference(fa.get(key), fb.get(key)) for key, _ in QUANTITIES}
    out[CENTROID_DISTANCE] = centroid_distance(fa.get("centroid_m"), fb.get("centroid_m"), spacing_m)
    return out


def judge(shipped: TearRun, reference: TearRun, check: Optional[TearRun], spacing_m: float) -> list[Verdict]:
    """PASS/FAIL per quantity: shipped within the tolerance of the reference, the reference within it of check."""
    ship = compare(shipped, reference, spacing_m)
    ref = compare(reference, check, spacing_m) if check is not None else {}
    bad = [r.name for r in (shipped, reference, check) if r is not None and not r.result.ok]
    reason = f"stopped by the stability guard: {', '.join(bad)}" if bad else ""
    if check is None:
        reason = reason or "no finer run to check the reference"
    out = []
    for key, label, tol, unit in [(k, lab, TOLERANCE, "relative") for k, lab in QUANTITIES] + \
                                 [(CENTROID_DISTANCE, CENTROID[1], CENTROID_TOLERANCE_SPACINGS, "spacings")]:
        s, r = ship[key], ref.get(key, math.nan)
        passed = not reason and s <= tol and r <= tol
        out.append(Verdict(key, label, s, r, tol, unit, passed, reason))
    return out


def run_tearing_study(spec: SceneSpec, frames: int, factors: tuple[float, ...] = TEAR_STEP_FACTORS,
                      reference_factor: float = TEAR_REFERENCE_FACTOR,
                      stream: Optional[TextIO] = sys.stderr) -> TearingStudy:
    """Run the scene with tearing on at each step h0 * factor for `frames` frames and compare the tears."""
    if not spec.cloth.tearing.enabled:
        raise ValueError(f"scene {spec.name} does not tear")
    factors = tuple(sorted(set(factors), reverse=True))
    if reference_factor not in factors:
        raise ValueError(f"the reference step factor {reference_factor:g} is not among the steps {factors}")
    base = with_frames(spec, frames)
    model = build_model(base)
    rest = model.crossing_rest_position_m
    h0 = spec.time.step_s
    warm_up(base)
    # Some tearing kernels are first called once the cloth tears (the contact of mass couples): run the
    # coarsest step through untimed, so that no compilation lands in a timed run (about 3 % more work).
    run_variant(with_step_factor(base, factors[0]), frames, record=False, locate_stage=False)
    runs = []
    for f in factors:
        vspec = with_step_factor(base, f)
        name = step_label(f)
        _say(stream, f"study {spec.name}: tearing on, step {name} ({frames * vspec.time.steps_per_frame} steps) ...")
        runs.append(TearRun(name, f, run_variant(vspec, frames, record=False)))
    finer = [r for r in runs if r.factor < reference_factor]
    ref = next(r for r in runs if r.factor == reference_factor)
    check = finer[0] if finer else None  # the next finer step
    shipped = next((r for r in runs if r.factor == 1.0), runs[0])
    for r in runs:
        r.role = "reference" if r is ref else "check" if r is check else "shipped" if r is shipped else ""
        other = check if r is ref else ref
        if other is not None:
            r.compared_with = other.name
            r.rel_diff = compare(r, other, spec.cloth.spacing_m)
    study = TearingStudy(scene=spec.name, frames=frames, frame_s=h0 * spec.time.steps_per_frame, base_step_s=h0,
                         spacing_m=spec.cloth.spacing_m, bounds_m=(rest.min(axis=0).tolist(), rest.max(axis=0).tolist()),
                         runs=runs, shipped=shipped.name, reference=ref.name, check=check.name if check else None)
    study.verdicts = judge(shipped, ref, check, spec.cloth.spacing_m)
    study.notes = _notes(study)
    return study


def _notes(study: TearingStudy) -> list[str]:
    notes = []
    for r in study.runs:
        if not r.result.ok:
            d = r.result.diagnostic or {}
            notes.append(f"Tearing on, step {r.name}: stopped by the stability guard at step {d.get('step')} "
                         f"(stage {d.get('stage')}); its figures are those of the last state reached.")
    ref = study.run(study.reference)
    if ref.figures.get("first_break_s") is None:
        notes.append(f"Nothing broke within {study.duration_s:.4g} s at the reference step: the counts agree "
                     "trivially; use a longer --duration.")
    broke = [r.figures.get("first_break_s") for r in study.runs if r.figures.get("first_break_s") is not None]
    if broke and max(broke) > 0.9 * study.duration_s:
        notes.append("Some run first broke in the last tenth of the duration: its tear has barely started at the "
                     "time compared; a longer --duration compares developed tears.")
    return notes

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

Over seeds: the break limits are random (drawn from the scene's seed), and which yarn goes first
decides the details of a tear (which ends pull out how far, which way the tear wanders by a yarn or
two). One run per step compares two draws of that scatter as much as two steps; the study therefore
runs every step at the same few seeds and compares the means over the seeds (a weak-convergence
criterion: the step must not change the distribution of the tear). Each seed's figures are kept
(runs.csv rows with role "seed").

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
                                  with_seed, with_step_factor)
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
    """The run at the first seed (its spec, steps and status stand for the step's)."""
    role: str = ""
    """"shipped" (the scene's step), "reference", "check" (the run that checks the reference) or ""."""
    compared_with: str = ""
    """The run the relative differences are taken against (the reference; for the reference, the check)."""
    rel_diff: dict = field(default_factory=dict)
    """Relative difference of each quantity against `compared_with`, and centroid_distance_spacings."""
    more: list = field(default_factory=list)
    """The runs at the further seeds (RunResult), when the study runs several."""

    @property
    def results(self) -> list[RunResult]:
        """Every seed's run, the first seed first."""
        return [self.result] + list(self.more)

    @property
    def seeds(self) -> list[int]:
        return [r.spec.scene.seed for r in self.results]

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.results)

    @property
    def status(self) -> str:
        bad = [r.status for r in self.results if not r.ok]
        return bad[0] if bad else self.result.status

    @property
    def steps(self) -> int:
        """Steps of one seed's run."""
        return self.result.steps

    @property
    def wall_s(self) -> float:
        """Wall time of all seeds' runs."""
        return float(sum(r.wall_s for r in self.results))

    @property
    def step_s(self) -> float:
        return self.result.spec.time.step_s

    @property
    def per_seed_figures(self) -> list[dict]:
        return [run_figures(r) for r in self.results]

    @property
    def figures(self) -> dict:
        """The tear at the last frame (fraytool.study.runner.tear_figures) and first_break_s: one seed's, or
        the mean over the seeds (ensemble_figures)."""
        return ensemble_figures(self.per_seed_figures)

    def _row(self, result: RunResult, fig: dict, role: str, seeds: str) -> dict:
        s = result.spec
        centroid = fig.get("centroid_m") or [None, None, None]
        return {"varied": "step, tearing on", "value": self.step_s, "role": role, "seeds": seeds,
                "step_s": self.step_s, "steps_per_frame": s.time.steps_per_frame,
                "strain_max_iterations": s.cloth.strain.max_iterations, "strain_tolerance": s.cloth.strain.tolerance,
                "collision_iterations": s.self_collision.iterations if s.self_collision.enabled else None,
                "damping": s.cloth.springs.damping, "frames": result.frames,
                "simulated_s": result.frames * s.time.step_s * s.time.steps_per_frame,
                "steps": result.steps, "max_strain": result.max_strain, "max_jitter": result.max_jitter,
                "centroid_x_m": centroid[0], "centroid_y_m": centroid[1], "centroid_z_m": centroid[2],
                "broken_structural_springs": fig.get("broken_structural_springs"),
                "torn_length_m": fig.get("torn_length_m"), "pieces": fig.get("pieces"),
                **{key: fig.get(key) for key, _ in QUANTITIES}}

    def rows(self) -> list[dict]:
        """The runs.csv rows (fraytool.study.report.RUN_COLUMNS): the step's row (the mean over the seeds,
        compared), then with several seeds one row per seed (role "seed", not compared)."""
        seeds = self.seeds
        row = self._row(self.result, self.figures, self.role, ",".join(str(s) for s in seeds))
        row.update({"run": f"step {self.name}, tearing on", "wall_s": self.wall_s, "status": self.status,
                    "strain_cap_hits": sum(r.strain_cap_hits for r in self.results),
                    "max_strain": max(r.max_strain for r in self.results),
                    "max_jitter": max(r.max_jitter for r in self.results),
                    BROKE_SEEDS: self.figures.get(BROKE_SEEDS),
                    "compared_with": self.compared_with, CENTROID_DISTANCE: self.rel_diff.get(CENTROID_DISTANCE)})
        for key, _ in QUANTITIES:
            row[f"{key}_rel_diff"] = self.rel_diff.get(key)
        out = [row]
        if len(seeds) > 1:
            for seed, result, fig in zip(seeds, self.results, self.per_seed_figures):
                r = self._row(result, fig, "seed", str(seed))
                r.update({BROKE_SEEDS: int(fig.get("first_break_s") is not None),
                          "run": f"step {self.name}, tearing on, seed {seed}", "wall_s": result.wall_s,
                          "status": result.status, "strain_cap_hits": result.strain_cap_hits})
                out.append(r)
        return out


def run_figures(result: RunResult) -> dict:
    """first_break_s and the tear at the last frame of one run."""
    t = result.tearing
    return {"first_break_s": t.get("first_break_s"), **t.get("final", {})}


BROKE_SEEDS = "seeds_broken"
"""Figures key (and runs.csv column): how many of the seeds' runs broke a spring."""
WHEN_BROKEN = ("first_break_s", "fray_mean_free_end_m")
"""Quantities that exist only for a run that broke something: averaged over those runs, and not
comparable between two steps where different numbers of seeds broke (compare)."""


def ensemble_figures(figures: list[dict]) -> dict:
    """The mean of each compared quantity over runs at different seeds (one run: its own figures),
    with BROKE_SEEDS, the number of runs that broke a spring.

    Counts become means (floats), over every run. The time of the first break, the mean free end and
    the centroid are means over the runs that broke something (None when none did): a run that never
    broke has no first break and no cut ends. Also averaged: broken structural springs and torn length;
    pieces is the mean count."""
    broke = [f for f in figures if f.get("first_break_s") is not None]
    if len(figures) == 1:
        return {**figures[0], BROKE_SEEDS: len(broke)}
    out: dict = {BROKE_SEEDS: len(broke)}
    for key in [k for k, _ in QUANTITIES] + ["broken_structural_springs", "torn_length_m", "pieces"]:
        pool = broke if key in WHEN_BROKEN else figures
        values = [f.get(key) for f in pool if f.get(key) is not None]
        out[key] = float(np.mean(values)) if values else None
    cents = [f["centroid_m"] for f in broke if f.get("centroid_m") is not None]
    out["centroid_m"] = [float(c) for c in np.mean(cents, axis=0)] if cents else None
    return out


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
    seeds: list[int] = field(default_factory=list)
    """The seeds every step ran at (one: the scene's)."""

    @property
    def duration_s(self) -> float:
        return self.frames * self.frame_s

    @property
    def passed(self) -> bool:
        return bool(self.verdicts) and all(v.passed for v in self.verdicts)

    def run(self, name: str) -> TearRun:
        return next(r for r in self.runs if r.name == name)

    def rows(self) -> list[dict]:
        return [row for r in self.runs for row in r.rows()]


def _say(stream: Optional[TextIO], text: str) -> None:
    if stream is not None:
        print(text, file=stream, flush=True)


def compare(a: TearRun, b: TearRun, spacing_m: float) -> dict:
    """Relative differences of a's quantities against b's, and the distance of the centroids. When a
    different number of seeds broke something in the two steps, the quantities that exist only for a
    run that broke (WHEN_BROKEN, the centroid) differ infinitely: their means cover different runs."""
    return compare_figures(a.figures, b.figures, spacing_m)


def compare_figures(fa: dict, fb: dict, spacing_m: float) -> dict:
    """compare on two figures dicts (ensemble_figures)."""
    out = {key: relative_difference(fa.get(key), fb.get(key)) for key, _ in QUANTITIES}
    out[CENTROID_DISTANCE] = centroid_distance(fa.get("centroid_m"), fb.get("centroid_m"), spacing_m)
    if fa.get(BROKE_SEEDS) != fb.get(BROKE_SEEDS):
        for key in WHEN_BROKEN + (CENTROID_DISTANCE,):
            out[key] = math.inf
    return out


def judge(shipped: TearRun, reference: TearRun, check: Optional[TearRun], spacing_m: float) -> list[Verdict]:
    """PASS/FAIL per quantity: shipped within the tolerance of the reference, the reference within it of check."""
    ship = compare(shipped, reference, spacing_m)
    ref = compare(reference, check, spacing_m) if check is not None else {}
    bad = [r.name for r in (shipped, reference, check) if r is not None and not r.ok]
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
                      stream: Optional[TextIO] = sys.stderr, seeds: tuple[int, ...] = ()) -> TearingStudy:
    """Run the scene with tearing on at each step h0 * factor for `frames` frames and compare the tears;
    with `seeds`, every step at each seed, compared by the means over the seeds (default: the scene's seed)."""
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
    seeds = tuple(seeds) or (spec.scene.seed,)
    runs = []
    for f in factors:
        vspec = with_step_factor(base, f)
        name = step_label(f)
        results = []
        for seed in seeds:
            at = f", seed {seed}" if len(seeds) > 1 else ""
            _say(stream, f"study {spec.name}: tearing on, step {name}{at} ({frames * vspec.time.steps_per_frame} "
                         "steps) ...")
            results.append(run_variant(with_seed(vspec, seed), frames, record=False))
        runs.append(TearRun(name, f, results[0], more=results[1:]))
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
                         runs=runs, shipped=shipped.name, reference=ref.name, check=check.name if check else None,
                         seeds=list(seeds))
    study.verdicts = judge(shipped, ref, check, spec.cloth.spacing_m)
    study.notes = _notes(study)
    return study


def _notes(study: TearingStudy) -> list[str]:
    notes = []
    for r in study.runs:
        for result in r.results:
            if not result.ok:
                d = result.diagnostic or {}
                at = f", seed {result.spec.scene.seed}" if len(r.results) > 1 else ""
                notes.append(f"Tearing on, step {r.name}{at}: stopped by the stability guard at step {d.get('step')} "
                             f"(stage {d.get('stage')}); its figures are those of the last state reached.")
    for r in study.runs:
        broke = r.figures.get(BROKE_SEEDS, 0)
        if 0 < broke < len(r.results):
            notes.append(f"Tearing on, step {r.name}: only {broke} of {len(r.results)} seeds broke a spring; the first "
                         "break, mean free end and centroid are means over those, and differ infinitely from a step "
                         "where another number of seeds broke.")
    ref = study.run(study.reference)
    if ref.figures.get("first_break_s") is None:
        notes.append(f"Nothing broke within {study.duration_s:.4g} s at the reference step: the counts agree "
                     "trivially; use a longer --duration.")
    broke = [r.figures.get("first_break_s") for r in study.runs if r.figures.get("first_break_s") is not None]
    if broke and max(broke) > 0.9 * study.duration_s:
        notes.append("Some run first broke in the last tenth of the duration: its tear has barely started at the "
                     "time compared; a longer --duration compares developed tears.")
    return notes

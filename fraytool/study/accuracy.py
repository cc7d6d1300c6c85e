"""Error against run time: the accuracy study behind `fraytool study SCENE`.

The scene runs over a sweep of settings that trade accuracy for speed, one setting varied at a time
around the scene's own values:
- the step h (steps per frame scaled so that a frame holds the same simulated time; the step
  factors are powers of two so every run samples exactly the same frame times);
- the strain-limiting iteration cap ([cloth.strain] max_iterations), at the scene's step;
- the self-collision iteration cap, when the scene has self-collision.
A reference run is much finer than the finest setting: its step is the finest step / 8, with
4 x the largest iteration caps and a strain tolerance of 1e-6. --quick runs fewer settings (steps
h0, h0/2, h0/4; reference h0/32) over at most 12 frames.

A tearing scene is studied by the convergence of its tear instead (fraytool.study.tear_convergence:
tearing on, steps h0 to h0/16, the tear compared at a fixed simulated time against the reference
h0/8); its trajectories with tearing off are compared as well only when asked (trajectories=True,
`fraytool study --trajectories`). The simulated time is the scene's shot for the tearing study and
at most FULL_FRAMES (QUICK_FRAMES) frames for the trajectories, or `duration_s` for both.

Choices (stated in the report):
- Trajectory errors need trajectories that can converge. A tear makes them diverge (a spring that
  breaks one step later sends its yarn elsewhere), so for errors every run and the reference have
  tearing off; the tear itself is compared by its own figures (above).
- PBD damping (docs/method.md §4, Müller et al. 2007 §3.5) is a fraction k removed per *step*; at a fixed
  k a smaller step would damp more per second and the runs would not converge to one motion. The
  study keeps the damping per second of the scene: k(h) = 1 - (1 - k0)^(h / h0).
- Errors are over all masses (base model, tearing off), against the reference at every frame:
  RMS at the final frame, RMS over all frames and masses, and the maximum over both.
- The observed order p is the least-squares slope of log(error) against log(h) over the step runs
  (RMS over time as the headline), with pairwise orders between neighbours and a reference-free
  Richardson estimate log2(|x_h - x_h/2| / |x_h/2 - x_h/4|). Symplectic Euler is first order:
  p is about 1 while the motion is smooth; contacts, buckling and friction can cap the error at a
  floor that a smaller step does not lower (the report says when it sees one).
Wall time is that of the steps only (time.perf_counter, after a warm-up run that compiles the
kernels). Runs are deterministic: the same scene gives the same errors, bit for bit.
"""
from __future__ import annotations

import dataclasses as dc
import math
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Optional, TextIO

import numpy as np

from fraytool.errors import InputError, RunError
from fraytool.scene.spec import SceneSpec
from fraytool.sim.builder import build_model
from fraytool.sim.guard import JITTER_LIMIT
from fraytool.sim.stability import power_iteration_omega_max
from fraytool.study.runner import RunResult, run_variant, warm_up
from fraytool.study.steps import TEAR_REFERENCE_FACTOR, TEAR_STEP_FACTORS, step_label, with_frames, with_step_factor  # noqa: F401

if TYPE_CHECKING:
    from fraytool.study.tear_convergence import TearingStudy

EXPECTED_ORDER = 1.0
"""Symplectic Euler (and the first-order PBD projections) converge at order 1 in the step."""
QUICK_FRAMES = 12
"""--quick simulates at most this many frames."""
FULL_FRAMES = 48
"""The full study simulates at most this many frames (the scene's count if fewer)."""
REFERENCE_STRAIN_TOLERANCE = 1e-6


@dataclass(frozen=True)
class StudyPlan:
    frames: int
    """Frames compared (after frame 0)."""
    step_factors: tuple[float, ...]
    """Steps as multiples of the scene's step, coarsest first (powers of two)."""
    reference_divisor: int
    """The reference step is the finest step / this."""
    strain_iterations: tuple[int, ...]
    collision_iterations: tuple[int, ...]
    reference_strain_iterations: int
    reference_collision_iterations: int
    tearing_frames: Optional[int] = None
    """Frames of the tearing study (tearing scenes); None: `frames`."""
    tearing_step_factors: tuple[float, ...] = TEAR_STEP_FACTORS
    """Steps of the tearing study as multiples of the scene's step; empty: no tearing study."""
    tearing_reference_factor: float = TEAR_REFERENCE_FACTOR
    tearing_seeds: tuple[int, ...] = ()
    """Seeds every step of the tearing study runs at (compared by their means); empty: the scene's seed."""
    trajectories: bool = True
    """Run the trajectory study (tearing off). plan_study leaves it out for a tearing scene unless asked."""


@dataclass
class StudyRun:
    name: str
    """Row label, e.g. "step h0/4" or "strain_iterations 5"."""
    varied: str
    """"step", "strain_iterations", "collision_iterations" or "reference"."""
    value: float
    """The varied setting's value (step [s] or iteration cap)."""
    result: RunResult
    errors: dict = field(default_factory=dict)
    """rms_final_m, rms_time_m, max_m, and rms_per_frame_m (list) against the reference."""

    @property
    def spec(self) -> SceneSpec:
        return self.result.spec


@dataclass
class StudyResult:
    scene: str
    plan: StudyPlan
    base_step_s: float
    stability_bound_s: float
    """Sharp bound 2 / ω_max (power iteration) of the scene."""
    reference: Optional[StudyRun]
    """The trajectory reference; None when only the tear was studied."""
    runs: list[StudyRun]
    order: dict
    """observed_order (headline), per-measure fits, pairwise and Richardson orders, monotonic flags."""
    tearing: Optional["TearingStudy"] = None
    """The convergence of the tear (tearing scenes; fraytool.study.tear_convergence)."""
    notes: list[str] = field(default_factory=list)
    quick: bool = False
    tears: bool = False
    """The scene itself tears (trajectories, if any, were compared with tearing off)."""

    @property
    def trajectories(self) -> bool:
        """The trajectory study ran (reference, runs and order are filled)."""
        return self.reference is not None


# --- scene variants ---------------------------------------------------------------------------

def without_tearing(spec: SceneSpec) -> SceneSpec:
    """Tearing off (break limits at infinity) so that trajectories can converge; without scissors either
    ([[cuts]] path_m: they cut in the tearing stage). Snips made before the shot stay."""
    off = dc.replace(spec.cloth.tearing, enabled=False)
    return dc.replace(spec, cloth=dc.replace(spec.cloth, tearing=off),
                      panels=tuple(dc.replace(p, tearing=off) for p in spec.panels),
                      cuts=tuple(c for c in spec.cuts if not c.path_m))


def with_strain(spec: SceneSpec, iterations: int, tolerance: Optional[float] = None) -> SceneSpec:
    strain = dc.replace(spec.cloth.strain, max_iterations=iterations,
                        tolerance=spec.cloth.strain.tolerance if tolerance is None else tolerance)
    return dc.replace(spec, cloth=dc.replace(spec.cloth, strain=strain))


def with_collision_iterations(spec: SceneSpec, iterations: int) -> SceneSpec:
    return dc.replace(spec, self_collision=dc.replace(spec.self_collision, iterations=iterations))


def frames_for(spec: SceneSpec, duration_s: float) -> int:
    """Whole frames that cover `duration_s` of simulated time (at least one)."""
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
        raise InputError(f"--duration must be a positive number of simulated seconds, not {duration_s!r}")
    frame_s = spec.time.step_s * spec.time.steps_per_frame
    return max(1, math.ceil(duration_s / frame_s - 1e-9))


TEAR_SEEDS = 4
"""The full tearing study runs every step at this many seeds (the scene's and the next ones); --quick at
one, and so does a scene whose break limits are not random (break_strain_spread = 0: every seed gives
the same run)."""


def default_seed_count(spec: SceneSpec, quick: bool) -> int:
    """Seeds of the tearing study without --seeds (TEAR_SEEDS)."""
    random = spec.cloth.tearing.break_strain_spread > 0.0
    return TEAR_SEEDS if random and not quick else 1


def plan_study(spec: SceneSpec, quick: bool = False, duration_s: Optional[float] = None,
               trajectories: Optional[bool] = None, seeds: Optional[tuple[int, ...]] = None) -> StudyPlan:
    """The default sweep: steps h0 (2 h0 if stable) down to h0/8 (h0/4 with --quick), over at most
    FULL_FRAMES (QUICK_FRAMES) frames. A tearing scene: the tearing study over the scene's shot (at most
    QUICK_FRAMES with --quick), and the trajectories only if `trajectories`. `duration_s` [simulated s]
    sets the frames of both (rounded up to whole frames). `seeds`: the tearing study's seeds (default
    TEAR_SEEDS seeds from the scene's, one with --quick)."""
    tears = spec.cloth.tearing.enabled
    trajectories = (not tears) if trajectories is None else (trajectories or not tears)
    shot = max(spec.time.frames - 1, 1)
    if duration_s is not None:
        frames = tear_frames = frames_for(spec, duration_s)
    else:
        frames = min(shot, QUICK_FRAMES if quick else FULL_FRAMES)
        tear_frames = min(shot, QUICK_FRAMES) if quick else shot
    factors = [1.0, 0.5, 0.25] if quick else [1.0, 0.5, 0.25, 0.125]
    if trajectories and not quick and spec.time.steps_per_frame % 2 == 0:
        model = build_model(spec)
        w = power_iteration_omega_max(model)
        if w == 0.0 or 2.0 * spec.time.step_s <= 0.9 * 2.0 / w:
            factors.insert(0, 2.0)  # a coarser step is still well within the bound
    cap = spec.cloth.strain.max_iterations
    strain = sorted({1, 3, 10, cap} if quick else {1, 2, 5, 10, 20, cap})
    collision: list[int] = []
    if spec.self_collision.enabled:
        c = spec.self_collision.iterations
        collision = sorted({1, 2, c} if quick else {1, 2, 4, 8, c})
    return StudyPlan(frames=max(frames, 1), step_factors=tuple(factors), reference_divisor=8,
                     strain_iterations=tuple(strain), collision_iterations=tuple(collision),
                     reference_strain_iterations=4 * max(strain + [1]),
                     reference_collision_iterations=4 * max(collision + [1]),
                     tearing_frames=tear_frames if tears else None,
                     tearing_step_factors=TEAR_STEP_FACTORS if tears else (), trajectories=trajectories,
                     tearing_seeds=tuple(seeds) if seeds else
                     tuple(spec.scene.seed + i for i in range(default_seed_count(spec, quick))))


# --- error measures and orders --------------------------------------------------------------------

def trajectory_errors(x: np.ndarray, ref: np.ndarray) -> dict:
    """Errors of positions x against ref, both (frames + 1, masses, 3); frame 0 is the common start."""
    d = np.linalg.norm(x[1:] - ref[1:], axis=2)  # (frames, masses)
    per_frame = np.sqrt((d * d).mean(axis=1))
    return {
        "rms_final_m": float(per_frame[-1]),
        "rms_time_m": float(math.sqrt(float((d * d).mean()))),
        "max_m": float(d.max()),
        "rms_per_frame_m": per_frame.tolist(),
    }


def fitted_order(h: list[float], e: list[float]) -> float:
    """Least-squares slope of log e against log h (nan with fewer than two usable points)."""
    pts = [(math.log(a), math.log(b)) for a, b in zip(h, e) if a > 0 and b > 0 and math.isfinite(b)]
    if len(pts) < 2:
        return math.nan
    lh, le = np.array(pts).T
    return float(np.polyfit(lh, le, 1)[0])


def pairwise_orders(h: list[float], e: list[float]) -> list[float]:
    """Order between neighbouring steps: log(e_i / e_i+1) / log(h_i / h_i+1)."""
    out = []
    for (h1, e1), (h2, e2) in zip(zip(h, e), zip(h[1:], e[1:])):
        ok = e1 > 0 and e2 > 0 and math.isfinite(e1) and math.isfinite(e2)
        out.append(math.log(e1 / e2) / math.log(h1 / h2) if ok else math.nan)
    return out


def richardson_orders(h: list[float], positions: list[np.ndarray]) -> list[float]:
    """Reference-free orders from three runs with a constant step ratio r:
    p = log(|x_h - x_h/r| / |x_h/r - x_h/r^2|) / log r, with RMS over all frames and masses."""
    out = []
    for k in range(len(h) - 2):
        r1, r2 = h[k] / h[k + 1], h[k + 1] / h[k + 2]
        if abs(r1 - r2) > 1e-9 * r1:
            out.append(math.nan)
            continue
        a = trajectory_errors(positions[k], positions[k + 1])["rms_time_m"]
        b = trajectory_errors(positions[k + 1], positions[k + 2])["rms_time_m"]
        out.append(math.log(a / b) / math.log(r1) if a > 0 and b > 0 else math.nan)
    return out


def monotonic_decrease(e: list[float]) -> bool:
    return all(b < a for a, b in zip(e, e[1:]))


MEASURES = ("rms_time_m", "rms_final_m", "max_m")


def convergence_summary(step_runs: list[StudyRun]) -> dict:
    """Orders and monotonicity of the step runs (coarsest first)."""
    ok = [r for r in step_runs if r.result.ok]
    h = [r.value for r in ok]
    out: dict = {"expected_order": EXPECTED_ORDER, "steps_s": h}
    for m in MEASURES:
        e = [r.errors[m] for r in ok]
        out[f"order_{m}"] = fitted_order(h, e)
        out[f"pairwise_{m}"] = pairwise_orders(h, e)
        out[f"monotonic_{m}"] = monotonic_decrease(e) and len(ok) == len(step_runs)
    out["richardson"] = richardson_orders(h, [r.result.positions for r in ok])
    per_frame = np.array([r.errors["rms_per_frame_m"] for r in ok]) if ok else np.zeros((0, 0))
    out["order_per_frame"] = [fitted_order(h, per_frame[:, f].tolist()) for f in range(per_frame.shape[1])] \
        if len(ok) >= 2 else []
    out["observed_order"] = out["order_rms_time_m"]
    out["monotonic"] = out["monotonic_rms_time_m"]
    return out


# --- the study --------------------------------------------------------------------------------------

def _say(stream: Optional[TextIO], text: str) -> None:
    if stream is not None:
        print(text, file=stream, flush=True)


def run_accuracy_study(spec: SceneSpec, quick: bool = False, plan: Optional[StudyPlan] = None,
                       stream: Optional[TextIO] = sys.stderr, duration_s: Optional[float] = None,
                       trajectories: Optional[bool] = None, seeds: Optional[tuple[int, ...]] = None) -> StudyResult:
    """Run the study (nothing is written here): the trajectory sweep and its reference, with errors
    and orders (plan.trajectories), and for a tearing scene the convergence of the tear.
    `duration_s`, `trajectories` and `seeds` go to plan_study when no plan is given."""
    plan = plan or plan_study(spec, quick, duration_s=duration_s, trajectories=trajectories, seeds=seeds)
    tears = spec.cloth.tearing.enabled
    h0 = spec.time.step_s
    model = build_model(without_tearing(spec))
    w = power_iteration_omega_max(model)
    bound = math.inf if w == 0.0 else 2.0 / w
    result = StudyResult(scene=spec.name, plan=plan, base_step_s=h0, stability_bound_s=bound, reference=None,
                         runs=[], order={}, quick=quick, tears=tears)
    if plan.trajectories or not tears:
        _trajectory_study(spec, plan, result, stream)
    if tears and plan.tearing_step_factors:
        from fraytool.study.tear_convergence import run_tearing_study

        frames = plan.tearing_frames if plan.tearing_frames is not None else plan.frames
        result.tearing = run_tearing_study(spec, frames, plan.tearing_step_factors, plan.tearing_reference_factor,
                                           stream=stream, seeds=plan.tearing_seeds)
        result.notes += result.tearing.notes
    return result


def _trajectory_study(spec: SceneSpec, plan: StudyPlan, out: StudyResult, stream: Optional[TextIO]) -> None:
    """Tearing off: the sweep and its reference, errors and orders, into `out`."""
    base = with_frames(without_tearing(spec), plan.frames)
    h0 = spec.time.step_s
    notes = out.notes
    warm_up(base)

    finest = min(plan.step_factors)
    ref_spec = with_step_factor(base, finest / plan.reference_divisor)
    ref_spec = with_strain(ref_spec, plan.reference_strain_iterations, REFERENCE_STRAIN_TOLERANCE)
    if spec.self_collision.enabled:
        ref_spec = with_collision_iterations(ref_spec, plan.reference_collision_iterations)
    steps_ref = plan.frames * ref_spec.time.steps_per_frame
    _say(stream, f"study {spec.name}: reference run, step h0/{round(1 / (finest / plan.reference_divisor))} "
                 f"({steps_ref} steps) ...")
    ref_result = run_variant(ref_spec, plan.frames, record=True)
    if not ref_result.ok:
        d = ref_result.diagnostic or {}
        raise RunError(f"study {spec.name}: the reference run became unstable at step {d.get('step')} "
                       f"(stage {d.get('stage')}); the scene cannot be studied as it is")
    reference = StudyRun("reference", "reference", ref_spec.time.step_s, ref_result)
    reference.errors = {m: 0.0 for m in MEASURES}

    variants: list[tuple[str, str, float, SceneSpec]] = []
    for f in plan.step_factors:
        variants.append((f"step {step_label(f)}", "step", h0 * f, with_step_factor(base, f)))
    for n in plan.strain_iterations:
        variants.append((f"strain_iterations {n}", "strain_iterations", n, with_strain(base, n)))
    for n in plan.collision_iterations:
        variants.append((f"collision_iterations {n}", "collision_iterations", n, with_collision_iterations(base, n)))

    runs: list[StudyRun] = []
    done: list[tuple[SceneSpec, RunResult]] = []
    for k, (name, varied, value, vspec) in enumerate(variants, 1):
        same = [r for s, r in done if s == vspec]  # the scene's own settings appear in every sweep
        if same:
            result = same[0]
        else:
            _say(stream, f"study {spec.name}: run {k}/{len(variants)} {name} "
                         f"({plan.frames * vspec.time.steps_per_frame} steps) ...")
            result = run_variant(vspec, plan.frames, record=True)
            done.append((vspec, result))
        run = StudyRun(name, varied, value, result)
        if result.ok:
            run.errors = trajectory_errors(result.positions, ref_result.positions)
        else:
            run.errors = {m: math.inf for m in MEASURES}
            notes.append(f"{name} became unstable (step {result.diagnostic.get('step')}, stage "
                         f"{result.diagnostic.get('stage')}); it is left out of the orders.")
        runs.append(run)

    step_runs = sorted((r for r in runs if r.varied == "step"), key=lambda r: -r.value)
    order = convergence_summary(step_runs)
    notes += _convergence_notes(order, step_runs)
    for r in runs:
        if r.result.ok and r.result.max_jitter > JITTER_LIMIT:
            notes.append(f"{r.name}: step-to-step oscillation (jitter {r.result.max_jitter:.2g} of the spacing): "
                         "an instability held by strain limiting.")

    out.reference, out.runs, out.order = reference, runs, order


def _convergence_notes(order: dict, step_runs: list[StudyRun]) -> list[str]:
    """Say where the error does not fall like h^1 (an error floor) and when in the run that happens."""
    notes = []
    p = order["observed_order"]
    if not math.isfinite(p):
        return ["Too few stable step runs to estimate an order."]
    off = [m for m in MEASURES if not (abs(order[f"order_{m}"] - EXPECTED_ORDER) <= 0.3) or not order[f"monotonic_{m}"]]
    ok = [r for r in step_runs if r.result.ok]
    if not off or len(ok) < 2:
        return notes
    per_frame = np.array([r.errors["rms_per_frame_m"] for r in ok])
    step_ratio = ok[0].value / ok[-1].value
    ratio = per_frame[0] / np.maximum(per_frame[-1], 1e-300)
    slow = np.nonzero(ratio < math.sqrt(step_ratio))[0]  # observed order below 1/2 at that frame
    text = ", ".join(f"{m} (order {order[f'order_{m}']:.2f}{'' if order[f'monotonic_{m}'] else ', not monotonic'})"
                     for m in off)
    where = (f" Frame by frame, the coarsest-to-finest error ratio is below sqrt({step_ratio:g}) (order < 1/2) at "
             f"{slow.size} of {ratio.size} frames, first at frame {slow[0] + 1}." if slow.size else "")
    notes.append(f"Not first order in: {text}.{where} Where the motion is not smooth in time (contact and friction, "
                 "buckling of the compression-only shear springs, strain limits switching on and off) the error "
                 "reaches a floor that a smaller step does not lower; the per-frame curves in convergence.png show when.")
    return notes

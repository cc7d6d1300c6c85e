"""Tables and reports of the studies: runs.csv + report.md (accuracy), stability.csv + stability.md.

Everything is written atomically (fraytool.io.frame_record.atomic_write_bytes), in plain text that
diffs well: CSV with a header row, Markdown with one table per sweep.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import TYPE_CHECKING, Iterable, Optional

from fraytool.io.frame_record import atomic_write_bytes

if TYPE_CHECKING:
    from fraytool.study.accuracy import StudyResult
    from fraytool.study.stability_sweep import SweepResult
    from fraytool.study.tear_convergence import TearingStudy

RUN_COLUMNS = ("run", "varied", "value", "role", "seeds", "seeds_broken", "step_s", "steps_per_frame", "strain_max_iterations",
               "strain_tolerance", "collision_iterations", "damping", "frames", "simulated_s", "steps", "wall_s",
               "status", "rms_final_m", "rms_time_m", "max_m", "max_strain", "strain_cap_hits", "max_jitter",
               "compared_with", "broken_springs", "broken_springs_rel_diff", "first_break_s",
               "first_break_s_rel_diff", "yarn_level_crossings", "yarn_level_crossings_rel_diff",
               "fray_mean_free_end_m", "fray_mean_free_end_m_rel_diff", "centroid_x_m", "centroid_y_m",
               "centroid_z_m", "centroid_distance_spacings", "broken_structural_springs", "torn_length_m", "pieces")
"""runs.csv columns. Trajectory runs (tearing off; varied = "step", "strain_iterations",
"collision_iterations" or "reference") fill the errors. The tearing study of a tearing scene has one row
per step (varied = "step, tearing on"; role shipped / reference / check): the tear at the time compared
(broken springs, first break [s], torn crossings = yarn_level_crossings, mean free-end length [m],
centroid of the broken structural springs [m]) and each quantity's relative difference against the run
named in compared_with (the reference h0/8; for the reference, h0/16); centroid_distance_spacings is
the centroids' distance in yarn spacings. Run at several seeds, a step's row holds the means over the
seeds (seeds lists them; seeds_broken counts those that broke a spring; wall_s is their sum, max_strain
and max_jitter their largest) and is followed by one row per seed (role "seed", seeds the one seed),
which is not compared. First break, mean free end and centroid are means over the seeds that broke."""


def write_text(path: Path, text: str) -> None:
    data = text.encode("utf-8")
    atomic_write_bytes(Path(path), lambda f: f.write(data))


def csv_text(columns: Iterable[str], rows: Iterable[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: _cell(v) for k, v in row.items()})
    return buf.getvalue()


def _cell(v):
    if isinstance(v, float):
        return "inf" if v == math.inf else ("nan" if math.isnan(v) else repr(v))
    return "" if v is None else v


def _g(v, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        if math.isnan(v):
            return "-"
        if math.isinf(v):
            return "inf"
        return f"{v:.{digits}g}"
    return str(v)


def md_table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_g(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


# --- accuracy study ------------------------------------------------------------------------------

def run_rows(study: "StudyResult") -> list[dict]:
    rows = []
    for run in study.runs + ([study.reference] if study.reference is not None else []):
        s = run.spec
        r = run.result
        rows.append({
            "run": run.name, "varied": run.varied, "value": run.value, "step_s": s.time.step_s,
            "steps_per_frame": s.time.steps_per_frame, "strain_max_iterations": s.cloth.strain.max_iterations,
            "strain_tolerance": s.cloth.strain.tolerance,
            "collision_iterations": s.self_collision.iterations if s.self_collision.enabled else None,
            "damping": s.cloth.springs.damping, "frames": r.frames, "steps": r.steps, "wall_s": r.wall_s,
            "status": r.status, "rms_final_m": run.errors.get("rms_final_m"),
            "rms_time_m": run.errors.get("rms_time_m"), "max_m": run.errors.get("max_m"),
            "max_strain": r.max_strain, "strain_cap_hits": r.strain_cap_hits, "max_jitter": r.max_jitter,
        })
    if study.tearing is not None:
        rows += study.tearing.rows()
    return rows


def write_runs_csv(study: "StudyResult", path: Path) -> None:
    write_text(path, csv_text(RUN_COLUMNS, run_rows(study)))


def accuracy_report(study: "StudyResult", plot_note: str) -> str:
    """report.md of the accuracy study: the trajectory study (tearing off) and/or the tearing study."""
    if study.trajectories:
        out = _trajectory_report(study)
    else:
        tear = study.tearing
        out = [f"# Convergence of the tear in the step: `{study.scene}`", ""]
        out.append(f"{'Quick study' if study.quick else 'Study'} of the tear: {tear.frames} frames "
                   f"({tear.duration_s:.4g} s simulated). Scene step h0 = {study.base_step_s:.6g} s; stability bound "
                   f"2/ω_max = {study.stability_bound_s:.4g} s (power iteration), h0 = "
                   f"{study.base_step_s / study.stability_bound_s:.2f} x the bound. The trajectories (tearing off) "
                   "were not compared (`fraytool study --trajectories` adds them).")
    if study.tearing is not None:
        out += [""] + tearing_section(study.tearing)
    if study.notes:
        out += ["", "## Notes", ""] + [f"- {n}" for n in study.notes]
    out += ["", "## Files", "", "- `runs.csv`: one row per run (settings, wall time, errors; tearing figures and "
            "their relative differences for the tearing study).", f"- {plot_note}", ""]
    return "\n".join(out)


def _trajectory_report(study: "StudyResult") -> list[str]:
    p = study.plan
    o = study.order
    ref = study.reference
    h0 = study.base_step_s
    spf0 = next(r.spec.time.steps_per_frame for r in study.runs if r.varied == "step" and r.value == h0) \
        if any(r.varied == "step" and r.value == h0 for r in study.runs) else None
    frame_s = ref.spec.time.step_s * ref.spec.time.steps_per_frame
    out = [f"# Error against run time: `{study.scene}`", ""]
    out.append(f"{'Quick study' if study.quick else 'Study'} over the first {p.frames} frames "
               f"({p.frames * frame_s:.4g} s simulated). Scene step h0 = {h0:.6g} s"
               + (f" ({spf0} steps per frame)" if spf0 else "")
               + f"; stability bound 2/ω_max = {study.stability_bound_s:.4g} s (power iteration), "
                 f"h0 = {h0 / study.stability_bound_s:.2f} x the bound.")
    out += ["", "## Method", ""]
    out.append(f"- **Reference**: step h0/{round(h0 / ref.value)} ({ref.value:.4g} s), strain-limiting cap "
               f"{ref.spec.cloth.strain.max_iterations} iterations, tolerance {ref.spec.cloth.strain.tolerance:g}"
               + (f", self-collision cap {ref.spec.self_collision.iterations}" if ref.spec.self_collision.enabled else "")
               + f"; {ref.result.steps} steps in {ref.result.wall_s:.3g} s.")
    out.append("- **Varied, one at a time** around the scene's settings: the step (steps per frame scaled to keep "
               "the time per frame), the strain-limiting iteration cap"
               + (", the self-collision iteration cap" if p.collision_iterations else "") + ".")
    if study.tears:
        tear_txt = ("This scene tears: the tear itself is studied with tearing on (see \"Convergence of the tear\" "
                    "below)." if study.tearing is not None else "This scene tears; its tear was not studied here.")
    else:
        tear_txt = "This scene does not tear."
    out.append("- **Tearing off** for every trajectory comparison (break limits at infinity): a tear makes "
               "trajectories diverge. " + tear_txt)
    out.append("- **Damping per second kept**: PBD damping removes a fraction k per step, so each run uses "
               "k(h) = 1 - (1 - k0)^(h/h0) with the scene's k0; otherwise a smaller step would damp more per "
               "second and the runs would not converge to one motion.")
    out.append("- **Errors**, over all masses against the reference at every frame: RMS at the final frame, RMS "
               "over all frames and masses, and the maximum distance.")
    out.append("- **Wall time**: the steps only, time.perf_counter after a warm-up run (numba compilation "
               "excluded); recording positions is not timed.")
    out += ["", "## Observed order of convergence in the step", ""]
    out.append(f"**Observed order p = {_g(o['observed_order'], 3)}** (least-squares slope of log RMS-over-time "
               f"error against log h; expected {o['expected_order']:g} for symplectic Euler). "
               f"Error falls monotonically as the step shrinks: **{'yes' if o['monotonic'] else 'no'}**.")
    out.append("")
    out.append(md_table(["measure", "fitted order", "pairwise orders (coarse to fine)", "monotonic"],
                        [[m, o[f"order_{m}"], ", ".join(_g(v) for v in o[f"pairwise_{m}"]) or "-",
                          "yes" if o[f"monotonic_{m}"] else "no"] for m in ("rms_time_m", "rms_final_m", "max_m")]))
    out.append("")
    out.append("Richardson (reference-free, RMS over time of the differences between consecutive steps): "
               + (", ".join(_g(v) for v in o["richardson"]) or "-") + ".")
    per_frame = o.get("order_per_frame", [])
    if per_frame:
        out += ["", "Observed order frame by frame (slope of the RMS error at that frame against h):", ""]
        cols = list(range(0, len(per_frame), max(1, len(per_frame) // 12)))
        if cols[-1] != len(per_frame) - 1:
            cols.append(len(per_frame) - 1)
        out.append(md_table(["frame"] + [str(f + 1) for f in cols], [["order"] + [per_frame[f] for f in cols]]))
    out += ["", "## Runs", ""]
    rows = []
    for r in study.runs + [ref]:
        s = r.spec
        rows.append([r.name, s.time.step_s, s.time.steps_per_frame, s.cloth.strain.max_iterations,
                     r.result.wall_s, r.result.status, r.errors.get("rms_final_m"), r.errors.get("rms_time_m"),
                     r.errors.get("max_m"), r.result.max_strain])
    out.append(md_table(["run", "step [s]", "steps/frame", "strain its", "wall [s]", "status", "RMS final [m]",
                         "RMS time [m]", "max [m]", "max strain"], rows))
    return out


def _pct(d: Optional[float]) -> str:
    if d is None or (isinstance(d, float) and math.isnan(d)):
        return "-"
    return "inf" if math.isinf(d) else f"{100 * d:.0f} %"


def tearing_section(tear: "TearingStudy") -> list[str]:
    """The "Convergence of the tear" section: one row per step, then PASS/FAIL per quantity."""
    from fraytool.study.tear_convergence import CENTROID_DISTANCE, CENTROID_TOLERANCE_SPACINGS, QUANTITIES, TOLERANCE

    out = ["## Convergence of the tear (tearing on)", ""]
    out.append(f"Tearing on at steps {', '.join(r.name for r in tear.runs)}, everything else as in the scene "
               f"(damping per second kept); the tear compared at t = {tear.duration_s:.4g} s ({tear.frames} frames). "
               f"Reference {tear.reference}"
               + (f", checked against {tear.check}" if tear.check else "")
               + f". Criterion: {tear.shipped} (the scene's step) within {100 * TOLERANCE:.0f} % of the reference "
                 f"and the reference within {100 * TOLERANCE:.0f} % of {tear.check or 'a finer step'} on each count; "
                 f"centroid of the broken structural springs within {CENTROID_TOLERANCE_SPACINGS:g} yarn spacings "
                 f"({tear.spacing_m:g} m). In brackets: the relative difference against the reference (for the "
                 f"reference, against {tear.check or '-'}); the centroid's distance in spacings.")
    if len(tear.seeds) == 1:
        out.append("")
        out.append(f"One seed ({tear.seeds[0]}): a single run per step also differs from the reference by the scatter "
                   "between seeds (which yarn breaks first), so a FAIL here may be that scatter rather than the step; "
                   "the full study runs every step at 4 seeds and compares their means (`--seeds LIST` chooses them).")
    if len(tear.seeds) > 1:
        out.append("")
        out.append(f"Every step ran at seeds {', '.join(str(s) for s in tear.seeds)} (the break limits' draws): the "
                   "figures are means over the seeds, and the criterion compares the means (which yarn breaks first "
                   "decides a tear's details, so single runs scatter as much between seeds as between steps). "
                   "runs.csv has each seed's figures; wall times are summed over the seeds.")
        spread = _seed_spread(tear)
        if spread:
            out += ["", spread]
    out.append("")
    out.append("Torn crossings: crossings split into mass couples (`yarn_level_crossings`); mean free end: mean "
               "length of the yarn ends that stick out of the weave (`fray_mean_free_end_m`); centroid: mean rest "
               "position of the midpoints of the broken structural springs.")
    out.append("")
    rows = []
    for r in tear.runs:
        fig = r.figures
        cells = [r.name + (f" ({r.role})" if r.role else ""), r.step_s, r.steps, r.wall_s, r.status]
        for key, _ in QUANTITIES:
            cells.append(f"{_g(fig.get(key), 4)} ({_pct(r.rel_diff.get(key))})")
        c = fig.get("centroid_m")
        dist = r.rel_diff.get(CENTROID_DISTANCE)
        cells.append(("(" + ", ".join(f"{v:.4f}" for v in c) + ")" if c is not None else "-")
                     + f" ({_g(dist, 2)} sp.)")
        cells.append(fig.get("torn_length_m"))
        rows.append(cells)
    out.append(md_table(["step", "step [s]", "steps", "wall [s]", "status", "broken springs", "first break [s]",
                         "torn crossings", "mean free end [m]", "centroid [m] (distance)", "torn length [m]"], rows))
    out += ["", f"Against the criterion ({tear.shipped} vs {tear.reference}; {tear.reference} vs "
                f"{tear.check or '-'}):", ""]
    for v in tear.verdicts:
        if v.unit == "spacings":
            diffs = f"{_g(v.shipped, 2)} and {_g(v.reference, 2)} spacings (limit {v.tolerance:g})"
        else:
            diffs = f"{_pct(v.shipped)} and {_pct(v.reference)} (limit {100 * v.tolerance:.0f} %)"
        out.append(f"- **{'PASS' if v.passed else 'FAIL'}** {v.label}: {diffs}" + (f"; {v.reason}" if v.reason else ""))
    n = sum(v.passed for v in tear.verdicts)
    out += ["", f"Tear converged on {n} of {len(tear.verdicts)} quantities"
                + (": **PASS**." if tear.passed else ": **FAIL**.")]
    return out


def _seed_spread(tear: "TearingStudy") -> str:
    """One line: the scatter between seeds at the scene's step (the noise the means average out)."""
    from fraytool.study.tear_convergence import QUANTITIES

    run = next((r for r in tear.runs if r.name == tear.shipped), None)
    if run is None:
        return ""
    figs = run.per_seed_figures
    parts = []
    for key, label in QUANTITIES:
        values = [f.get(key) for f in figs if f.get(key) is not None]
        if len(values) > 1:
            parts.append(f"{label} {_g(float(min(values)), 4)}-{_g(float(max(values)), 4)}")
    return f"Scatter between the seeds at {tear.shipped} (lowest-highest): " + "; ".join(parts) + "." if parts else ""


# --- stability sweep -------------------------------------------------------------------------------

SWEEP_COLUMNS = ("case", "group", "value", "outcome", "step_s", "step_over_bound_gershgorin",
                 "step_over_bound_power", "structural_n_per_m", "mass_per_crossing_kg", "thickness_m",
                 "body_speed_m_s", "frames", "steps", "wall_s", "max_strain", "strain_limit", "max_speed_m_s",
                 "max_jitter", "strain_cap_hits", "guard_stage", "guard_particle", "guard_spring", "guard_step",
                 "expected")


def write_sweep_csv(sweep: "SweepResult", path: Path) -> None:
    write_text(path, csv_text(SWEEP_COLUMNS, [c.row() for c in sweep.cases]))


def sweep_report(sweep: "SweepResult", plot_note: Optional[str]) -> str:
    out = [f"# Stability sweep: `{sweep.scene}`", ""]
    out.append(f"Base step {sweep.base_step_s:.4g} s; stability bound 2/ω_max of the base scene "
               f"{sweep.base_bound_power_s:.4g} s by power iteration (sharp) and {sweep.base_bound_gershgorin_s:.4g} s "
               f"by Gershgorin (safe). Each case changes one thing and runs {sweep.frames} frames "
               f"({sweep.frames * sweep.frame_s:.3g} s simulated).")
    out += ["", "Outcomes:", "",
            "- **stable**: finished, strain within the limit, no step-to-step oscillation;",
            "- **strain_over_limit**: finished, but some structural strain went past the limit by more than "
            f"{sweep.strain_slack:g} (strain limiting could not keep up);",
            "- **oscillating**: finished without tripping the guard, but the cloth shook step to step by more than "
            f"{sweep.jitter_limit:g} of the yarn spacing: the explicit instability, held bounded by strain limiting;",
            "- **unstable**: stopped by the stability guard (non-finite or faster than the speed limit); the stage, "
            "mass and spring come from replaying the failed step.", ""]
    rows = []
    for c in sweep.cases:
        r = c.row()
        guard = f"{r['guard_stage']} / mass {r['guard_particle']}" if r["guard_stage"] else ""
        rows.append([c.name, c.outcome, r["step_over_bound_power"], r["step_over_bound_gershgorin"], r["max_strain"],
                     r["max_speed_m_s"], r["max_jitter"], r["steps"], guard])
    out.append(md_table(["case", "outcome", "h / bound (power)", "h / bound (Gershgorin)", "max strain",
                         "max speed [m/s]", "jitter", "steps", "guard: stage / mass"], rows))
    counts = {}
    for c in sweep.cases:
        counts[c.outcome] = counts.get(c.outcome, 0) + 1
    out += ["", "Totals: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + "."]
    if sweep.notes:
        out += ["", "## Notes", ""] + [f"- {n}" for n in sweep.notes]
    out += ["", "## Files", "", "- `stability.csv`: one row per case."]
    if plot_note:
        out.append(f"- {plot_note}")
    out.append("")
    return "\n".join(out)

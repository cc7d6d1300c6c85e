"""Plots of the studies (matplotlib, an optional extra: `pip install fraytool[plot]`).

- error_vs_time.png: the work-precision diagram, error against wall time, log-log, one line per
  varied setting (step, strain-limiting iterations, collision iterations);
- convergence.png: error against the step with a slope-1 guide, the per-frame error of each step
  run over simulated time, and the observed order frame by frame (where the error stops falling
  with the step, these show when);
- tearing_convergence.png (tearing scenes): each quantity of the tear against the step, as its
  relative difference from the reference h0/8 (the reference itself against h0/16, hollow marker),
  with the 15 % line; the centroid's distance in yarn spacings with the 2-spacing line;
- stability.png: the stability sweep's cases, step-to-step jitter and largest strain against
  h / bound, marked by outcome.
Every function returns the path written, or None when matplotlib is missing (`have_matplotlib`).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Optional

if TYPE_CHECKING:
    from fraytool.study.accuracy import StudyResult
    from fraytool.study.stability_sweep import SweepResult

INSTALL_HINT = "install matplotlib (pip install 'fraytool[plot]' or pip install matplotlib) to get the plots"

_LABELS = {"step": "step h", "strain_iterations": "strain-limiting iterations",
           "collision_iterations": "self-collision iterations"}
_MARKERS = {"step": "o", "strain_iterations": "s", "collision_iterations": "^"}


def have_matplotlib() -> bool:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    """Save through a temporary name, then rename (atomic like every other output)."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    fig.savefig(tmp, dpi=120)
    tmp.replace(path)
    return path


def plot_error_vs_time(study: "StudyResult", path: Path, measure: str = "rms_time_m") -> Optional[Path]:
    if not have_matplotlib():
        return None
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 5))
    for varied in ("step", "strain_iterations", "collision_iterations"):
        runs = [r for r in study.runs if r.varied == varied and r.result.ok and r.errors.get(measure, 0) > 0]
        if not runs:
            continue
        runs.sort(key=lambda r: r.result.wall_s)
        x = [max(r.result.wall_s, 1e-6) for r in runs]
        y = [r.errors[measure] for r in runs]
        ax.plot(x, y, marker=_MARKERS[varied], label=_LABELS[varied])
        for r, xi, yi in zip(runs, x, y):
            text = r.name.split(" ", 1)[1] if " " in r.name else r.name
            ax.annotate(text, (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the steps [s]")
    ax.set_ylabel({"rms_time_m": "RMS position error over time [m]", "rms_final_m": "RMS error, final frame [m]",
                   "max_m": "max position error [m]"}[measure])
    p = study.order.get("observed_order", math.nan)
    ax.set_title(f"{study.scene}: error against run time (observed order in h: {p:.2f})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out


def plot_convergence(study: "StudyResult", path: Path) -> Optional[Path]:
    if not have_matplotlib():
        return None
    plt = _pyplot()
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 4.5))
    steps = sorted((r for r in study.runs if r.varied == "step" and r.result.ok), key=lambda r: -r.value)
    if steps:
        h = [r.value for r in steps]
        for m, lab in (("rms_time_m", "RMS over time"), ("rms_final_m", "RMS final frame"), ("max_m", "max")):
            a1.plot(h, [r.errors[m] for r in steps], marker="o", label=lab)
        e0 = steps[0].errors["rms_time_m"]
        a1.plot(h, [e0 * hi / h[0] for hi in h], "k--", lw=0.8, label="slope 1")
        a1.set_xscale("log")
        a1.set_yscale("log")
        a1.set_xlabel("step h [s]")
        a1.set_ylabel("position error [m]")
        a1.set_title("error against the step")
        a1.grid(True, which="both", alpha=0.3)
        a1.legend(fontsize=8)
        frame_s = study.reference.spec.time.step_s * study.reference.spec.time.steps_per_frame
        for r in steps:
            e = r.errors["rms_per_frame_m"]
            a2.plot([frame_s * (k + 1) for k in range(len(e))], e, label=r.name)
        a2.set_yscale("log")
        a2.set_xlabel("simulated time [s]")
        a2.set_ylabel("RMS position error [m]")
        a2.set_title("error per frame")
        a2.grid(True, which="both", alpha=0.3)
        a2.legend(fontsize=8)
        orders = study.order.get("order_per_frame", [])
        if orders:
            a3.plot([frame_s * (k + 1) for k in range(len(orders))], orders, marker=".")
            a3.axhline(study.order["expected_order"], color="k", ls="--", lw=0.8, label="expected")
            a3.set_xlabel("simulated time [s]")
            a3.set_ylabel("observed order at that frame")
            a3.set_title("order of the per-frame error in h")
            a3.grid(True, alpha=0.3)
            a3.legend(fontsize=8)
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out


def plot_tearing(study: "StudyResult", path: Path) -> Optional[Path]:
    """The convergence of the tear (study.tearing): differences against the step, with the criterion."""
    tear = study.tearing
    if tear is None or not have_matplotlib():
        return None
    from fraytool.study.tear_convergence import CENTROID_DISTANCE, CENTROID_TOLERANCE_SPACINGS, QUANTITIES, TOLERANCE

    plt = _pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    panels = ((a1, [(k, lab) for k, lab in QUANTITIES], 100.0, 100.0 * TOLERANCE,
               f"relative difference [%] (vs {tear.reference}; {tear.reference} vs {tear.check or '-'} hollow)"),
              (a2, [(CENTROID_DISTANCE, "centroid of the broken springs")], 1.0, CENTROID_TOLERANCE_SPACINGS,
               "centroid distance [yarn spacings]"))
    for ax, quantities, scale, limit, ylabel in panels:
        finite = [scale * r.rel_diff[k] for r in tear.runs for k, _ in quantities
                  if k in r.rel_diff and math.isfinite(r.rel_diff[k])]
        top = 1.3 * max(finite + [limit])
        for k, lab in quantities:
            runs = [r for r in tear.runs if k in r.rel_diff]
            others = [r for r in runs if r.name != tear.reference]
            y = lambda r: min(scale * r.rel_diff[k], top)  # noqa: E731  (infinite: drawn at the top)
            line, = ax.plot([r.step_s for r in others], [y(r) for r in others], marker="o", label=lab)
            ref = [r for r in runs if r.name == tear.reference]
            if ref:
                ax.plot([ref[0].step_s], [y(ref[0])], marker="o", mfc="none", color=line.get_color(), ls="none")
        ax.axhline(limit, color="k", ls="--", lw=0.8)
        ax.text(0.01, limit, " criterion", transform=ax.get_yaxis_transform(), fontsize=8, va="bottom")
        ax.set_xscale("log")
        ax.set_xticks([r.step_s for r in tear.runs], [r.name for r in tear.runs])
        ax.minorticks_off()
        ax.set_ylim(0, top * 1.05)
        ax.set_xlabel(f"step (h0 = {tear.base_step_s:.4g} s)")
        ax.set_ylabel(ylabel, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"{tear.scene}: convergence of the tear at t = {tear.duration_s:.3g} s "
                 f"({sum(v.passed for v in tear.verdicts)} of {len(tear.verdicts)} quantities pass)")
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out


_OUTCOME_STYLE = {"stable": ("tab:green", "o"), "strain_over_limit": ("tab:orange", "s"),
                  "oscillating": ("tab:purple", "D"), "unstable": ("tab:red", "X")}


def plot_stability(sweep: "SweepResult", path: Path) -> Optional[Path]:
    """Two panels against step / bound: step-to-step jitter and largest strain, marked by outcome.
    Runs the guard stopped are drawn at the top edge; only the cases that are not stable are labelled."""
    if not have_matplotlib():
        return None
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    panels = ((axes[0], lambda c: c.result.max_jitter, "step-to-step jitter / yarn spacing", sweep.jitter_limit),
              (axes[1], lambda c: c.result.max_strain, "largest structural strain",
               sweep.strain_limit * (1.0 + sweep.strain_slack)))
    for ax, value, label, limit in panels:
        finite = [value(c) for c in sweep.cases if c.result.ok and value(c) > 0]
        top = 3.0 * max(finite + [limit])
        for outcome, (color, marker) in _OUTCOME_STYLE.items():
            cases = [c for c in sweep.cases if c.outcome == outcome]
            if not cases:
                continue
            x = [max(c.step_over_bound_power, 1e-3) for c in cases]
            y = [max(value(c), 1e-6) if c.result.ok else top for c in cases]
            ax.scatter(x, y, c=color, marker=marker, s=50, label=outcome, zorder=3)
            if outcome != "stable":
                for c, xi, yi in zip(cases, x, y):
                    ax.annotate(c.name, (xi, yi), textcoords="offset points", xytext=(4, 3), fontsize=7)
        ax.axvline(1.0, color="k", lw=0.8, ls="--")
        ax.text(1.03, 0.02, "h = 2/ω_max", transform=ax.get_xaxis_transform(), fontsize=8)
        ax.axhline(limit, color="grey", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("step / stability bound (power iteration)")
        ax.set_ylabel(label + " (guard-stopped runs at the top)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{sweep.scene}: stability sweep")
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out

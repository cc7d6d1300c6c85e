"""`fraytool study SCENE [-o DIR] [--stability] [--quick] [--duration S] [--trajectories] [--seeds LIST]`: run a study
and write its files.

Accuracy (default): DIR/study/runs.csv, report.md, error_vs_time.png, convergence.png. A tearing scene:
the convergence of the tear (steps h0 to h0/16, tearing on, compared at one simulated time: the scene's
shot or --duration S; every step at 4 seeds, compared by their means, one seed with --quick, or --seeds
LIST), tearing_convergence.png instead of the trajectory plots; --trajectories adds the
trajectory study with tearing off. --duration S sets the simulated time of the accuracy study (whole frames).
Stability (--stability): DIR/study/stability.csv, stability.md, stability.png.
DIR defaults to outputs/<scene name>/. Without matplotlib the tables and reports are still written
and the closing message says how to get the plots. Exit code 0; an unusable scene or a reference
run that the guard stops is a FraytoolError (exit 2 or 1, one line, from the CLI).
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional, TextIO

from fraytool.errors import InputError, RunError
from fraytool.scene import load_scene
from fraytool.scene.spec import SceneSpec
from fraytool.study import plot, report

STUDY_DIR = "study"


def study_dir(spec: SceneSpec, out: Optional[Path]) -> Path:
    base = Path(out) if out is not None else Path("outputs") / spec.name
    return base / STUDY_DIR


MAX_SEEDS = 64
"""Most seeds one study may run (each runs every step: 5 runs per seed)."""
SEED_MAX = 2 ** 63 - 1
"""Largest seed (as [scene] seed)."""


def parse_seeds(text: str) -> tuple[int, ...]:
    """--seeds: "1-4", "3,7,9" or a mix ("1-3,8"): whole numbers 0..SEED_MAX, at most MAX_SEEDS of them,
    none twice."""
    import re

    seeds: list[int] = []
    for part in text.split(","):
        m = re.fullmatch(r"\s*([0-9]+)(?:-([0-9]+))?\s*", part)
        if m is None:
            raise InputError(f"--seeds {text!r}: {part.strip()!r} is not a seed or a range; expected e.g. 1-4 or "
                             "1,3,7 (whole numbers >= 0)")
        first = int(m.group(1))
        last = int(m.group(2)) if m.group(2) is not None else first
        if last < first:
            raise InputError(f"--seeds {text!r}: the range {part.strip()} runs backwards")
        if last > SEED_MAX:
            raise InputError(f"--seeds {text!r}: {last} is above the largest seed, {SEED_MAX} (as [scene] seed)")
        if len(seeds) + last - first + 1 > MAX_SEEDS:
            raise InputError(f"--seeds {text!r}: more than {MAX_SEEDS} seeds (each runs every step of the study)")
        seeds += range(first, last + 1)
    twice = sorted({s for s in seeds if seeds.count(s) > 1})
    if twice:
        raise InputError(f"--seeds {text!r}: seed {twice[0]} is listed twice")
    return tuple(seeds)


def write_accuracy_study(spec: SceneSpec, folder: Path, quick: bool = False, stream: Optional[TextIO] = sys.stderr,
                         plan=None, duration_s: Optional[float] = None, trajectories: Optional[bool] = None,
                         seeds: Optional[tuple[int, ...]] = None):
    """Run the accuracy study and write its files into `folder`; returns (StudyResult, written paths)."""
    from fraytool.study.accuracy import run_accuracy_study

    result = run_accuracy_study(spec, quick=quick, plan=plan, stream=stream, duration_s=duration_s,
                                trajectories=trajectories, seeds=seeds)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / "runs.csv"]
    report.write_runs_csv(result, written[0])
    notes = []
    if plot.have_matplotlib():
        if result.trajectories:
            written.append(plot.plot_error_vs_time(result, folder / "error_vs_time.png"))
            written.append(plot.plot_convergence(result, folder / "convergence.png"))
            notes.append("`error_vs_time.png`: error against wall time (log-log), one line per varied setting; "
                         "`convergence.png`: error against the step, and the error per frame of each step run.")
        if result.tearing is not None:
            written.append(plot.plot_tearing(result, folder / "tearing_convergence.png"))
            notes.append("`tearing_convergence.png`: each quantity of the tear against the step, as its difference "
                         "from the reference, with the criterion.")
        note = " ".join(notes)
    else:
        note = f"No plots: matplotlib is not installed; {plot.INSTALL_HINT}."
    written.append(folder / "report.md")
    report.write_text(written[-1], report.accuracy_report(result, note))
    return result, written


def _write_files(folder: Path, result, table: tuple, figure: tuple, text: tuple) -> list[Path]:
    """Write a study's table, its plot (when matplotlib is there) and its report into `folder`:
    table = (file name, writer(result, path)); figure = (file name, plotter(result, path) -> path or None,
    what the plot shows); text = (file name, report(result, note) -> str)."""
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / table[0]]
    table[1](result, written[0])
    drawn = figure[1](result, folder / figure[0])
    if drawn is not None:
        written.append(drawn)
        note = figure[2]
    else:
        note = f"No plot: matplotlib is not installed; {plot.INSTALL_HINT}."
    written.append(folder / text[0])
    report.write_text(written[-1], text[1](result, note))
    return written


def write_stability_sweep(spec: SceneSpec, folder: Path, quick: bool = False, stream: Optional[TextIO] = sys.stderr):
    """Run the stability sweep and write its files into `folder`; returns (SweepResult, written paths)."""
    from fraytool.study.stability_sweep import run_stability_sweep

    result = run_stability_sweep(spec, quick=quick, stream=stream)
    return result, _write_files(folder, result, ("stability.csv", report.write_sweep_csv),
                                ("stability.png", plot.plot_stability, "`stability.png`: each case at its step / "
                                 "bound and largest strain, coloured by outcome."),
                                ("stability.md", report.sweep_report))


def parse_factors(text: str) -> tuple[int, ...]:
    """--factors: a comma list of 1, 2, 4 and 8."""
    out = []
    for part in text.split(","):
        part = part.strip()
        if part not in ("1", "2", "4", "8"):
            raise InputError(f"--factors {text!r}: {part!r} is not a factor; each is 1, 2, 4 or 8 (as "
                             "[cloth.multires] factor), e.g. --factors 1,2,4")
        if int(part) in out:
            raise InputError(f"--factors {text!r}: {part} is listed twice")
        out.append(int(part))
    return tuple(out)


def write_multires_study(spec: SceneSpec, folder: Path, factors: tuple[int, ...], frames: Optional[int],
                         stream: Optional[TextIO] = sys.stderr):
    """Run the multi-resolution study and write DIR/study/multires/: runs.csv, report.md, multires.png."""
    from fraytool.study import multires_study as ms

    result = ms.run_multires_study(spec, factors, frames, stream)
    return result, _write_files(folder, result, ("runs.csv", ms.write_runs_csv),
                                ("multires.png", ms.plot, "`multires.png`: the untorn shape's distance from k = 1 "
                                 "(left) and each tear figure's difference from k = 1 (right), against wall time."),
                                ("report.md", ms.report))


def study_command(args) -> int:
    from fraytool.scene.overrides import parse_assignment

    spec = load_scene(args.scene, [parse_assignment(a) for a in getattr(args, "sets", [])])
    from fraytool.commands.bench import _refuse_what_will_not_fit

    _refuse_what_will_not_fit(spec)
    folder = study_dir(spec, args.out)
    try:
        return _study(spec, folder, args)
    except ImportError as exc:  # a pass the scene needs (tearing, self-collision) is not installed
        raise RunError(f"{spec.source}: cannot run the scene: {exc}") from None


def _study(spec: SceneSpec, folder: Path, args) -> int:
    err = sys.stderr
    if getattr(args, "multires", False):
        if args.stability or getattr(args, "seeds", None) or getattr(args, "trajectories", False):
            raise InputError("--multires runs its own comparison: not with --stability, --seeds or --trajectories")
        factors = parse_factors(args.factors) if getattr(args, "factors", None) else (1, 2, 4)
        duration = getattr(args, "duration", None)
        frames = None if duration is None else max(1, round(duration / (spec.time.steps_per_frame * spec.time.step_s)))
        result, written = write_multires_study(spec, folder / "multires", factors, frames, err)
        parts = [f"k={r.factor}: {r.wall_s:.1f} s ({r.speedup:.1f}x), shape mean "
                 f"{r.shape_mean_m / spec.cloth.spacing_m:.2f} spacings" for r in result.runs]
        print(f"study --multires of {spec.name}: " + "; ".join(parts) + f"; wrote {folder / 'multires'}", file=err)
        for path in written:
            print(f"  {path}", file=err)
        return 0
    if getattr(args, "factors", None):
        raise InputError("--factors goes with --multires")
    duration = getattr(args, "duration", None)
    trajectories = getattr(args, "trajectories", False)
    seeds_text = getattr(args, "seeds", None)
    seeds = parse_seeds(seeds_text) if seeds_text is not None else None
    if args.stability and (duration is not None or trajectories or seeds):
        raise InputError("--duration, --trajectories and --seeds apply to the accuracy study, not to --stability")
    if seeds and not spec.cloth.tearing.enabled:
        raise InputError(f"--seeds: {spec.name} does not tear (the seeds are those of the tearing study)")
    if args.stability:
        result, written = write_stability_sweep(spec, folder, quick=args.quick, stream=err)
        counts = {}
        for c in result.cases:
            counts[c.outcome] = counts.get(c.outcome, 0) + 1
        print(f"stability sweep of {spec.name}: {len(result.cases)} cases ("
              + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + f"); wrote {folder}", file=err)
    else:
        result, written = write_accuracy_study(spec, folder, quick=args.quick, stream=err, duration_s=duration,
                                               trajectories=True if trajectories else None, seeds=seeds)
        if result.trajectories:
            o = result.order
            print(f"study of {spec.name}: observed order in the step {o['observed_order']:.2f} (expected "
                  f"{o['expected_order']:g}), error falls monotonically: {'yes' if o['monotonic'] else 'no'}; "
                  f"wrote {folder}", file=err)
        if result.tearing is not None:
            tear = result.tearing
            over = f" (means over seeds {', '.join(map(str, tear.seeds))})" if len(tear.seeds) > 1 else ""
            print(f"study of {spec.name}: tear at t = {tear.duration_s:.4g} s against the reference {tear.reference}{over}: "
                  + ", ".join(f"{v.label} {'PASS' if v.passed else 'FAIL'}" for v in tear.verdicts)
                  + f"; wrote {folder}", file=err)
    if not plot.have_matplotlib():
        print(f"fraytool: note: no plot written: {plot.INSTALL_HINT}", file=err)
    for path in written:
        print(f"  {path}", file=err)
    return 0

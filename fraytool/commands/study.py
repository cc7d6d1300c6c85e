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


def write_stability_sweep(spec: SceneSpec, folder: Path, quick: bool = False, stream: Optional[TextIO] = sys.stderr):
    """Run the stability sweep and write its files into `folder`; returns (SweepResult, written paths)."""
    from fraytool.study.stability_sweep import run_stability_sweep

    result = run_stability_sweep(spec, quick=quick, stream=stream)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / "stability.csv"]
    report.write_sweep_csv(result, written[0])
    figure = plot.plot_stability(result, folder / "stability.png")
    if figure is not None:
        written.append(figure)
        note = "`stability.png`: each case at its step / bound and largest strain, coloured by outcome."
    else:
        note = f"No plot: matplotlib is not installed; {plot.INSTALL_HINT}."
    written.append(folder / "stability.md")
    report.write_text(written[-1], report.sweep_report(result, note))
    return result, written


def study_command(args) -> int:
    spec = load_scene(args.scene)
    from fraytool.commands.bench import _refuse_what_will_not_fit

    _refuse_what_will_not_fit(spec)
    folder = study_dir(spec, args.out)
    try:
        return _study(spec, folder, args)
    except ImportError as exc:  # a pass the scene needs (tearing, self-collision) is not installed
        raise RunError(f"{spec.source}: cannot run the scene: {exc}") from None


def _study(spec: SceneSpec, folder: Path, args) -> int:
    err = sys.stderr
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

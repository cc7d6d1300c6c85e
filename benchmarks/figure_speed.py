#!/usr/bin/env python
"""Simulation speed of the figure scenes against the targets of docs/tearing.md ("Speed"), repeated:
this machine's speed varies by up to a quarter from one minute to the next (shared host), so one
`fraytool bench` says little. Each scene's whole shot is benched REPEATS times, each run in its own
process (`fraytool bench SCENE --frames <shot frames - 1> --json`); the best, median and worst of
the runs' medians are printed with the target.

    python benchmarks/figure_speed.py [--repeats 3] [--scenes fig7_square_grab,fig5_corner_grab] [--threads N]

--threads N passes `--threads N` to every bench (default: numba's default, every core).
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS_MS = {"fig5_corner_grab": 30.0, "fig6_thrown_ball_plain": 30.0, "fig6_thrown_ball_twill": 30.0,
              "fig7_square_grab": 50.0}
"""Median simulation ms per frame over the whole shot, self-collision on (issue 10)."""


def bench(scene: str, threads: int | None = None) -> dict:
    from fraytool.scene import load_scene

    frames = load_scene(scene).time.frames - 1
    extra = ["--threads", str(threads)] if threads is not None else []
    r = subprocess.run([sys.executable, "-m", "fraytool", "bench", scene, "--frames", str(frames), "--json", *extra],
                       capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f"{scene}: fraytool bench failed: {r.stderr.strip().splitlines()[-1:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenes", default=",".join(TARGETS_MS))
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args()
    print("| scene | target [ms] | best | median | worst | runs | stages of the best run [ms] |")
    print("|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        runs = [bench(scene, args.threads) for _ in range(args.repeats)]
        ms = sorted(r["ms_per_frame"] for r in runs)
        best = min(runs, key=lambda r: r["ms_per_frame"])
        stages = ", ".join(f"{k} {v:.1f}" for k, v in best["stages_ms_per_frame"].items())
        print(f"| {scene} | {TARGETS_MS.get(scene, float('nan')):.0f} | {ms[0]:.1f} | {statistics.median(ms):.1f} | "
              f"{ms[-1]:.1f} | {len(ms)} | {stages} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

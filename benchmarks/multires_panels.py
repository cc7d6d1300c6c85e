"""The coarse base model on shaped panels, garments and cloth resting on a mesh (issue 53, item 1).

For each shot and factor k: `fraytool study --multires` at k against k = 1 (fraytool.study.multires_study:
wall time of the steps, the speed-up, and the tear figures with the study's tolerances), then one more run
at k that records, every frame, how much of the cloth is coarse: the share of the crossings that are
slaved (not simulated, interpolated from their cell's nodes) and the share of whole cells still coarse.

    python benchmarks/multires_panels.py [--shots round_tablecloth:4,shirt_snag:2,mannequin_drape:2]
                                         [--frames N]

Shots: the shipped scenes by name, and `mannequin_drape` (benchmarks/mesh_share.py: a 72 x 72 cloth, no
tearing, dropped on the static mannequin) to show cloth at rest on a detailed mesh.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

DEFAULT_SHOTS = "round_tablecloth:4,shirt_snag:2,mannequin_drape:2"


def _spec(shot: str, scratch: Path):
    from fraytool.scene import load_scene

    if shot == "mannequin_drape":
        from mesh_share import DRAPE

        path = scratch / "mannequin_drape.toml"
        path.write_text(DRAPE.format(asset=(ROOT / "scenes" / "assets" / "mannequin.obj").as_posix()))
        return load_scene(path)
    return load_scene(ROOT / "scenes" / f"{shot}.toml")


def coarse_share(spec, factor: int, frames: int) -> dict:
    """Per frame at `factor`: the share of crossings slaved and of whole cells coarse; their means."""
    from fraytool.sim import multires
    from fraytool.sim.simulation import Simulation
    from fraytool.study.multires_study import _with_factor

    sim = Simulation(_with_factor(spec, factor))
    lay = multires.coarse_layout(sim.model)
    slaved, coarse = [], []
    for _ in range(frames + 1):
        refined = sim.state.coarse_cell_refined
        slaved.append(1.0 - float(multires.free_crossings(lay, refined).mean()))
        coarse.append(float((~refined[lay.cell_whole]).sum() / max(lay.cell_whole.sum(), 1)))
        if len(slaved) <= frames:
            sim.advance_frame()
    return {"slaved_mean": float(np.mean(slaved)), "slaved_start": slaved[0], "slaved_end": slaved[-1],
            "coarse_cells_mean": float(np.mean(coarse)), "coarse_cells_end": coarse[-1],
            "whole_cells": int(lay.cell_whole.sum()), "cells": lay.cell_count}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shots", default=DEFAULT_SHOTS, help="shot:factor,... (default %(default)s)")
    parser.add_argument("--frames", type=int, default=None, help="frames of each shot (default: all but frame 0)")
    args = parser.parse_args()
    from fraytool.study.multires_study import CENTROID_TOLERANCE_SPACINGS, TEAR_TOLERANCE, run_multires_study

    with tempfile.TemporaryDirectory() as scratch:
        for item in args.shots.split(","):
            shot, factor = item.split(":")
            spec = _spec(shot, Path(scratch))
            frames = spec.time.frames - 1 if args.frames is None else args.frames
            t0 = time.perf_counter()
            study = run_multires_study(spec, factors=(1, int(factor)), frames=frames)
            ref, run = study.runs
            share = coarse_share(spec, int(factor), frames)
            print(f"{shot} at factor {factor}, {study.crossings} crossings, {frames} frames "
                  f"({time.perf_counter() - t0:.0f} s of benchmark):")
            print(f"  steps' wall time: k=1 {ref.wall_s:.2f} s, k={factor} {run.wall_s:.2f} s: "
                  f"{run.speedup:.2f}x")
            print(f"  crossings slaved (coarse): {share['slaved_start']:.0%} at the start, "
                  f"{share['slaved_mean']:.0%} over the shot, {share['slaved_end']:.0%} at the end; whole cells "
                  f"coarse: {share['coarse_cells_mean']:.0%} over the shot, {share['coarse_cells_end']:.0%} at the "
                  f"end ({share['whole_cells']} whole cells of {share['cells']})")
            print(f"  shape at the end: mean {run.shape_mean_m / study.spacing_m:.2f}, max "
                  f"{run.shape_max_m / study.spacing_m:.2f} yarn spacings from k=1")
            if study.tears:
                figures = ", ".join(f"{key} {ref.tear.get(key)} -> {run.tear.get(key)}"
                                    + ("" if run.relative.get(key) is None else f" ({run.relative[key]:+.0%})")
                                    for key in ref.tear)
                centroid = "-" if run.centroid_distance_spacings is None else f"{run.centroid_distance_spacings:.2f}"
                print(f"  tear: {figures}; centroid {centroid} spacings apart")
                print(f"  within the study's tolerances ({TEAR_TOLERANCE:.0%}, {CENTROID_TOLERANCE_SPACINGS:g} "
                      f"spacings): {'yes' if run.within() else 'no'}")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Where the memory of a simulation goes: bytes per crossing by phase and by array.

    python benchmarks/memory_profile.py SCENE [--set KEY=VALUE ...] [--frames N] [--top K]
    python benchmarks/memory_profile.py scenes/fig7_square_grab.toml \
        --set cloth.warp_yarns=256 --set cloth.weft_yarns=256 --frames 10

The run is the one `fraytool bench` measures (fraytool.commands.bench): an empty run first (the scene
built, stepped and written once, then dropped: numba's kernels and every module are loaded; the freed
memory goes back to the system), the resident set size then is the baseline; then the model is built, the Simulation made, the frames stepped and
written to a temporary FrameStore. Linux only: it resets the high-water mark of the resident size at
the start of every phase (fraytool.resident_memory).

Printed, in bytes per crossing over the baseline:
1. per phase, the resident size at its end and its peak (the high-water mark during the phase),
   the peaks of the step's stages over the frames (read after each stage through
   SolverExplicitPBD.stage_check, so a stage's peak includes what the stages before it left);
2. the largest numpy arrays held by the Model, the State, the step buffers, the stages and the
   objects they hold (each buffer counted once, under the first owner found), with dtype and shape.
"""
from __future__ import annotations

import argparse
import gc
import sys
import tempfile
from pathlib import Path

import numpy as np

from fraytool.commands.bench import empty_run
from fraytool.io.frame_store import FrameStore
from fraytool.resident_memory import peak_rss_bytes, release_freed_memory, reset_peak, rss_bytes
from fraytool.scene import load_scene, scene_hash
from fraytool.scene.overrides import parse_assignment
from fraytool.sim.builder import build_model
from fraytool.sim.simulation import Simulation

MAX_DEPTH = 6
"""How deep the array inventory follows attributes, tuples, lists and dicts from its roots."""


class PhaseTable:
    """Rows (phase, resident size at its end, peak during it), in bytes per crossing over a baseline."""

    def __init__(self, baseline_bytes: int, crossings: int):
        self.baseline_bytes = baseline_bytes
        self.crossings = crossings
        self.rows: list[tuple[str, float, float]] = []

    def per_crossing(self, nbytes: int) -> float:
        return (nbytes - self.baseline_bytes) / self.crossings

    def mark(self, phase: str) -> None:
        self.rows.append((phase, self.per_crossing(rss_bytes()), self.per_crossing(peak_rss_bytes())))
        reset_peak()

    def print(self) -> None:
        print(f"{'phase':40s} {'end B/crossing':>15s} {'peak B/crossing':>16s}")
        for phase, end, peak in self.rows:
            print(f"{phase:40s} {end:15.0f} {peak:16.0f}")


def held_arrays(roots: dict[str, object]) -> list[tuple[str, np.ndarray]]:
    """(path, array) of every numpy array reachable from `roots` through attributes, tuples, lists
    and dicts (MAX_DEPTH levels), each memory buffer once (views count under their base's first owner)."""
    seen_objects: set[int] = set()
    seen_buffers: set[int] = set()
    out: list[tuple[str, np.ndarray]] = []

    def visit(path: str, obj, depth: int) -> None:
        if isinstance(obj, np.ndarray):
            base = obj if obj.base is None else obj.base
            key = id(base)
            if key not in seen_buffers:
                seen_buffers.add(key)
                out.append((path, obj if obj.base is None else np.asarray(base)))
            return
        if depth >= MAX_DEPTH or id(obj) in seen_objects or isinstance(obj, (str, bytes, int, float, type)):
            return
        seen_objects.add(id(obj))
        if isinstance(obj, dict):
            items = obj.items()
        elif isinstance(obj, (list, tuple)):
            items = enumerate(obj)
        elif hasattr(obj, "__dict__"):
            items = vars(obj).items()
        else:
            return
        for k, v in items:
            visit(f"{path}.{k}", v, depth + 1)

    for name, root in roots.items():
        visit(name, root, 0)
    return out


def print_arrays(arrays: list[tuple[str, np.ndarray]], crossings: int, top: int) -> None:
    arrays = sorted(arrays, key=lambda pa: -pa[1].nbytes)
    total = sum(a.nbytes for _, a in arrays)
    print(f"\nheld arrays: {total / crossings:.0f} B/crossing in {len(arrays)} arrays; the {top} largest:")
    for path, a in arrays[:top]:
        print(f"  {a.nbytes / crossings:7.1f}  {path:60s} {str(a.dtype):8s} {a.shape}")
    by_root: dict[str, int] = {}
    for path, a in arrays:
        root = path.split(".")[0] if not path.startswith("solver.stages") else ".".join(path.split(".")[:3])
        by_root[root] = by_root.get(root, 0) + a.nbytes
    print("by owner:")
    for root, nbytes in sorted(by_root.items(), key=lambda kv: -kv[1]):
        print(f"  {nbytes / crossings:7.1f}  {root}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--top", type=int, default=25, help="largest arrays listed")
    args = ap.parse_args(argv)
    spec = load_scene(args.scene, [parse_assignment(a) for a in args.sets])

    with tempfile.TemporaryDirectory() as tmp:
        empty_run(spec, Path(tmp))  # as fraytool bench: kernels and modules loaded, then dropped
    gc.collect()
    release_freed_memory()
    if not reset_peak():
        sys.exit("memory_profile.py: cannot reset the peak RSS (/proc/self/clear_refs): Linux only")
    baseline = rss_bytes()
    crossings = spec.cloth.warp_yarns * spec.cloth.weft_yarns
    table = PhaseTable(baseline, crossings)
    print(f"{spec.name}: {crossings} crossings, baseline RSS {baseline / 2**20:.0f} MiB after an empty run")

    model = build_model(spec)
    table.mark("build_model")
    state = model.state()
    table.mark("Model.state")
    sim = Simulation(spec, model=model, state=state)
    table.mark("Simulation (solver, stages, observe)")
    stage_peaks: dict[str, float] = {}

    def stage_check(stage) -> None:
        key = f"  step stage {stage.name} ({stage.kernel})"
        stage_peaks[key] = max(stage_peaks.get(key, -1e30), table.per_crossing(peak_rss_bytes()))
        reset_peak()

    with tempfile.TemporaryDirectory() as tmp:
        store = FrameStore(Path(tmp))
        store.start(model.arrays(), scene_hash(spec), {"scene": spec.name})
        table.mark("FrameStore.start (topology.npz)")
        sim.solver.stage_check = stage_check
        record = sim.advance_frame()
        table.mark("first frame (steps, observe, record)")
        store.write_frame(record, sim.checkpoint_arrays())
        table.mark("first frame written (record, checkpoint)")
        for _ in range(args.frames - 1):
            record = sim.advance_frame()
            store.write_frame(record, sim.checkpoint_arrays())
        table.mark(f"frames 2-{args.frames} (steps + writes)")
    table.print()
    print("step stages, peak over every step of every frame:")
    for key, peak in stage_peaks.items():
        print(f"{key:40s} {'':15s} {peak:16.0f}")
    print_arrays(held_arrays({"model": sim.model, "state": sim.state, "solver": sim.solver, "sim": sim}),
                 crossings, args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Profile of the self-collision pass on the Fig. 7 tearing scene (scenes/fig7_square_grab.toml).

1. Broad phase: milliseconds per ``find_candidate_pairs_kernel`` call on the state after
   ``--frames`` frames (swept from the previous step's positions), with the candidate count.
2. Per-step split of ``SelfCollision.__call__`` over the next frames: broad-phase builds and
   patches per frame and time per part (build, validity check, patch, proximity, CCD, response).

Run: ``python benchmarks/self_collision_profile.py [--frames 12] [--measure 8]``. Single-threaded;
the first run after an edit of fraytool/collision compiles the kernels (~30 s).
"""
from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from fraytool.sim.stages import self_collision as resp  # the stage module: wrapping its names times its calls
from fraytool.collision.broadphase import candidate_pairs_of_segments_kernel, find_candidate_pairs_kernel
from fraytool.scene import load_scene
from fraytool.sim import Simulation

ROOT = Path(__file__).resolve().parents[1]


def time_call(fn, repeats: int) -> float:
    """Median milliseconds per call."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "fig7_square_grab.toml"))
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--measure", type=int, default=8, help="frames of the per-step split")
    ap.add_argument("--repeats", type=int, default=50)
    args = ap.parse_args()

    spec = load_scene(args.scene)
    spec = replace(spec, self_collision=replace(spec.self_collision, enabled=True))
    sim = Simulation(spec)
    for _ in range(args.frames):
        sim.advance_frame()
    sc = sim.solver.self_collision
    state = sim.state
    x_prev = sim.solver.context.prev_position_m.copy()
    x = state.particle_position_m.copy()
    margin = 0.5 * sc.contact_distance_m + sc.slack_m
    spring_yarn = sim.model.spring_yarn()

    def build():
        return find_candidate_pairs_kernel(x_prev, x, state.spring_particle_a, state.spring_particle_b,
                                           state.spring_alive, spring_yarn, margin, 0.0)

    def build_listed():
        return candidate_pairs_of_segments_kernel(x_prev, x, state.spring_particle_a, state.spring_particle_b,
                                                  state.spring_alive, sc.yarn_segments, margin, 0.0)

    pairs = build()  # warm-up (cache load)
    assert np.array_equal(build_listed(), pairs)
    live = int((state.spring_alive & (spring_yarn >= 0)).sum())
    print(f"state after {args.frames} frames: {state.spring_particle_a.shape[0]} spring slots, "
          f"{live} live yarn segments, {len(pairs)} candidate pairs (margin {margin:.3g} m, swept x_prev -> x)")
    print(f"find_candidate_pairs_kernel:        {time_call(build, args.repeats):.3f} ms per call")
    print(f"candidate_pairs_of_segments_kernel: {time_call(build_listed, args.repeats):.3f} ms per call")
    print(f"segment_boxes:               "
          f"{time_call(lambda: resp.segment_boxes(x_prev, x, state.spring_particle_a, state.spring_particle_b, sc.yarn_segments), args.repeats):.3f} ms per call")

    # per-part split of the next frames
    parts = {"build": 0.0, "check": 0.0, "rebox": 0.0, "patch": 0.0, "proximity": 0.0, "ccd": 0.0, "respond": 0.0, "freeze": 0.0}
    wrapped = {}

    def wrap(obj, name, part):
        fn = getattr(obj, name)
        wrapped[(obj, name)] = fn

        def timed(*a, **k):
            t = time.perf_counter()
            out = fn(*a, **k)
            parts[part] += time.perf_counter() - t
            return out

        setattr(obj, name, timed)

    wrap(sc, "_build", "build")
    wrap(resp, "check_candidates", "check")
    wrap(resp, "reattached_pairs", "patch")
    wrap(resp, "rebox_segments", "rebox")
    wrap(resp, "escaped_segments", "check")
    wrap(resp, "particle_reach", "check")
    wrap(resp, "repel_close_pairs", "proximity")
    wrap(resp, "ccd_pairs", "ccd")
    wrap(resp, "ccd_pairs_all", "ccd")
    wrap(resp, "respond_pairs", "respond")
    wrap(resp, "freeze_pairs", "freeze")
    builds0 = sc.broad_phase_builds
    patches0 = sc.broad_phase_patches
    reboxes0 = sc.broad_phase_reboxes
    sim.solver.reset_timers()
    t = time.perf_counter()
    for _ in range(args.measure):
        sim.advance_frame()
    total = time.perf_counter() - t
    for (obj, name), fn in wrapped.items():
        setattr(obj, name, fn)
    m = args.measure
    stage = 1e3 * sim.solver.stage_s["self_collision"] / m
    print(f"frames {args.frames}-{args.frames + m}: {1e3 * total / m:.2f} ms per frame, self_collision {stage:.2f} "
          f"ms per frame, {(sc.broad_phase_builds - builds0) / m:.2f} builds, {(sc.broad_phase_reboxes - reboxes0) / m:.2f} re-boxes and "
          f"{(sc.broad_phase_patches - patches0) / m:.2f} patches per frame, {len(sc._cand)} candidates now")
    for part, s in parts.items():
        print(f"  {part:10s} {1e3 * s / m:7.2f} ms per frame")
    print(f"  cap hits so far {sc.cap_hits}, pairs {sc.pairs_total}, proximity pushes {sc.proximity_total}")


if __name__ == "__main__":
    main()

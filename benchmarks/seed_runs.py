"""What the seed benchmarks share (benchmarks/shirt_snag_seeds.py, benchmarks/flag_tear_seeds.py): a shot run
frame by frame with its figures kept at every frame, and the command line over a range of seeds."""
from __future__ import annotations

import argparse
import time
from typing import Callable, Optional

import numpy as np

from fraytool.sim.pieces import piece_figures


def run_shot(sim, frames: Optional[int], each_frame: Callable[[object], None] = lambda sim: None) -> dict:
    """Advance `sim` to its last frame (or `frames`), calling each_frame(sim) after every frame. Returns the
    frames run, whether every position stayed finite, the most pieces under 5 masses at any frame, and the mean
    time a frame simulated [s] (the figures' own time left out)."""
    n = (frames or sim.spec.time.frames) - 1
    finite, small, simulated = True, 0, 0.0
    for _ in range(n):
        t0 = time.perf_counter()
        sim.advance_frame()
        simulated += time.perf_counter() - t0
        finite &= bool(np.isfinite(sim.state.particle_position_m).all())
        small = max(small, piece_figures(sim.model, sim.state)["small_pieces"])
        each_frame(sim)
    return dict(frames=n, finite=finite, small_pieces_max=small, s_per_frame=simulated / max(n, 1))


def seeds_main(doc: str, run_seed: Callable[[int, Optional[int]], dict], holds: Callable[[dict], bool],
               line: Callable[[dict], str]) -> int:
    """`--seeds A-B` (default 1-8) and `--frames N`: one line per seed (`line`), marked ok where `holds`, and a
    verdict; exit 1 when a seed fails."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--seeds", default="1-8")
    ap.add_argument("--frames", type=int, default=None)
    args = ap.parse_args()
    lo, _, hi = args.seeds.partition("-")
    ok = True
    for seed in range(int(lo), int(hi or lo) + 1):
        r = run_seed(seed, args.frames)
        good = holds(r)
        ok &= good
        print(f"seed {seed}: {'ok  ' if good else 'FAIL'} {line(r)}", flush=True)
    print("RESULT:", "all seeds hold" if ok else "some seeds fail")
    return 0 if ok else 1

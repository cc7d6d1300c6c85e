"""scenes/flag_tear.toml over seeds: does the shot hold for every seed? Per seed, over every frame: positions
finite, no piece under 5 masses, the cloth in the picture (fraytool.render.framing); at the end: broken springs,
free yarn ends (cut ends whose yarn sticks out of the weave, docs/tearing.md "Fray metric") and how many of
them lie in the fly half, and the time per frame simulated. Prints one line per seed and a verdict.

    python benchmarks/flag_tear_seeds.py [--seeds 1-8] [--frames N]"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fraytool.render.framing import framing  # noqa: E402
from fraytool.scene import load_scene  # noqa: E402
from fraytool.scene.overrides import parse_assignment  # noqa: E402
from fraytool.sim.pieces import piece_figures  # noqa: E402
from fraytool.sim.simulation import Simulation  # noqa: E402
from fraytool.sim.tearing.fray import fray_lengths  # noqa: E402


def run_seed(seed: int, frames: int | None) -> dict:
    spec = load_scene("flag_tear", [parse_assignment(f"scene.seed={seed}")])
    sim = Simulation(spec)
    w, h = spec.render.resolution
    n = (frames or spec.time.frames) - 1
    small, finite, outside, simulated = 0, True, 0, 0.0
    for _ in range(n):
        t0 = time.perf_counter()
        sim.advance_frame()
        simulated += time.perf_counter() - t0
        s = sim.state
        finite &= bool(np.isfinite(s.particle_position_m).all())
        small = max(small, piece_figures(sim.model, s)["small_pieces"])
        outside += framing(spec.camera, w / h, s.time_s, s.particle_position_m, s.particle_active).outside > 0
    m, s = sim.model, sim.state
    lengths, crossings = fray_lengths(m, sim.solver.tearing.topology, s)
    free = lengths > 0.0
    fly = m.crossing_grid_i[crossings] >= m.warp_yarns // 2
    return dict(finite=finite, small=small, outside=outside, broken=sim.solver.tearing.summary(s)["broken_springs"],
                free_ends=int(free.sum()), fly_free_ends=int((free & fly).sum()), s_per_frame=simulated / max(n, 1))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1-8")
    ap.add_argument("--frames", type=int, default=None)
    args = ap.parse_args()
    lo, _, hi = args.seeds.partition("-")
    ok = True
    for seed in range(int(lo), int(hi or lo) + 1):
        r = run_seed(seed, args.frames)
        good = r["finite"] and r["small"] == 0 and r["outside"] == 0 and r["fly_free_ends"] > 0
        ok &= good
        print(f"seed {seed}: {'ok  ' if good else 'FAIL'} finite={r['finite']} small_pieces_max={r['small']} "
              f"frames_with_cloth_outside={r['outside']} broken_springs={r['broken']} free_yarn_ends={r['free_ends']} "
              f"in_fly_half={r['fly_free_ends']} {1e3 * r['s_per_frame']:.0f} ms/frame simulated", flush=True)
    print("RESULT:", "all seeds hold" if ok else "some seeds fail")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

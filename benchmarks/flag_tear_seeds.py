"""scenes/flag_tear.toml over seeds: does the shot hold for every seed? Per seed, over every frame: positions
finite, no piece under 5 masses, the cloth in the picture (fraytool.render.framing); at the end: broken springs,
free yarn ends (cut ends whose yarn sticks out of the weave, docs/tearing.md "Fray metric") and how many of
them lie in the fly half, and the time per frame simulated. Prints one line per seed and a verdict.

    python benchmarks/flag_tear_seeds.py [--seeds 1-8] [--frames N]"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fraytool.render.framing import framing  # noqa: E402
from fraytool.scene import load_scene  # noqa: E402
from fraytool.scene.overrides import parse_assignment  # noqa: E402
from fraytool.sim.simulation import Simulation  # noqa: E402
from fraytool.sim.tearing.fray import fray_lengths  # noqa: E402
from seed_runs import run_shot, seeds_main  # noqa: E402


def run_seed(seed: int, frames: int | None) -> dict:
    spec = load_scene("flag_tear", [parse_assignment(f"scene.seed={seed}")])
    sim = Simulation(spec)
    w, h = spec.render.resolution
    outside = [0]

    def count_outside(sim) -> None:
        s = sim.state
        outside[0] += framing(spec.camera, w / h, s.time_s, s.particle_position_m, s.particle_active).outside > 0

    r = run_shot(sim, frames, count_outside)
    m, s = sim.model, sim.state
    lengths, crossings = fray_lengths(m, sim.solver.tearing.topology, s)
    free = lengths > 0.0
    fly = m.crossing_grid_i[crossings] >= m.warp_yarns // 2
    return dict(r, outside=outside[0], broken=sim.solver.tearing.summary(s)["broken_springs"],
                free_ends=int(free.sum()), fly_free_ends=int((free & fly).sum()))


def holds(r: dict) -> bool:
    return r["finite"] and r["small_pieces_max"] == 0 and r["outside"] == 0 and r["fly_free_ends"] > 0


def line(r: dict) -> str:
    return (f"finite={r['finite']} small_pieces_max={r['small_pieces_max']} frames_with_cloth_outside={r['outside']} "
            f"broken_springs={r['broken']} free_yarn_ends={r['free_ends']} in_fly_half={r['fly_free_ends']} "
            f"{1e3 * r['s_per_frame']:.0f} ms/frame simulated")


if __name__ == "__main__":
    raise SystemExit(seeds_main(__doc__, run_seed, holds, line))

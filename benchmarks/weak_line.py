"""How closely a tear follows a weak line ([[weak_lines]], docs/panels.md "Tear control"): for each seed, the
distance of every broken yarn spring's middle (at rest, in the cloth's plane) to the nearest weak line, in
yarn spacings, at the end of the shot.

    python benchmarks/weak_line.py                                   # perforated_tear, seeds 1-8
    python benchmarks/weak_line.py --scene scenes/perforated_tear.toml --seeds 1-3
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys

RUN = """
import json, sys
from dataclasses import replace
import numpy as np
from fraytool.scene import load_scene
from fraytool.sim import Simulation
from fraytool.sim.pieces import tear_distance_to_weak_lines
spec = load_scene(sys.argv[1])
spec = replace(spec, scene=replace(spec.scene, seed=int(sys.argv[2])))
sim = Simulation(spec)
for _ in range(spec.time.frames - 1):
    sim.advance_frame()
d = tear_distance_to_weak_lines(sim.model, sim.state, spec.weak_lines) / spec.cloth.spacing_m
s = sim.summary()
print(json.dumps({"seed": int(sys.argv[2]), "broken": int(d.size), "max_spacings": float(d.max()) if d.size else None,
                  "p90_spacings": float(np.percentile(d, 90)) if d.size else None,
                  "small_pieces": s["small_pieces"], "all_finite": s["all_finite"], "pieces": s["pieces"]}))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="perforated_tear")
    ap.add_argument("--seeds", default="1-8")
    args = ap.parse_args()
    lo, _, hi = args.seeds.partition("-")
    worst = 0.0
    for seed in range(int(lo), int(hi or lo) + 1):
        out = subprocess.run([sys.executable, "-c", RUN, args.scene, str(seed)], capture_output=True, text=True)
        if out.returncode:
            print(out.stderr, file=sys.stderr)
            return 1
        row = json.loads(out.stdout)
        worst = max(worst, row["max_spacings"] or 0.0)
        print(json.dumps(row), flush=True)
    print(f"worst distance of a broken spring from the weak line: {worst:.2f} yarn spacings")
    return 0


if __name__ == "__main__":
    sys.exit(main())

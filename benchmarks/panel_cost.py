"""What a shaped panel costs per crossing, against a rectangle (issue: "a panel costs in proportion to its
crossings: the round tablecloth no slower per crossing than fig6"). Runs `fraytool bench` on each scene
(the whole shot by default: the tear is where the cost is) and prints milliseconds per frame and
microseconds per crossing per frame.

    python benchmarks/panel_cost.py                       # round_tablecloth against fig6_thrown_ball_plain
    python benchmarks/panel_cost.py --frames 40 --scenes round_tablecloth,fig6_thrown_ball_plain,seam_rip
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys


def bench(scene: str, frames: int) -> dict:
    out = subprocess.run([sys.executable, "-m", "fraytool", "bench", scene, "--frames", str(frames), "--json"],
                         capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(out.stderr)
    return json.loads(out.stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="round_tablecloth,fig6_thrown_ball_plain")
    ap.add_argument("--frames", type=int, default=71)
    args = ap.parse_args()
    rows = []
    for scene in args.scenes.split(","):
        from fraytool.scene import load_scene
        from fraytool.sim.memory import crossing_count

        spec = load_scene(scene)
        crossings = sum(crossing_count(p, spec.source_file) for p in spec.all_panels)
        figures = bench(scene, min(args.frames, spec.time.frames - 1))
        ms = float(figures["ms_per_frame"])
        rows.append((scene, crossings, ms, 1e3 * ms / crossings))
    print(f"{'scene':28s} {'crossings':>9s} {'ms/frame':>9s} {'us/crossing/frame':>18s}")
    for scene, crossings, ms, us in rows:
        print(f"{scene:28s} {crossings:9d} {ms:9.1f} {us:18.2f}")
    if len(rows) >= 2:
        print(f"{rows[0][0]} per crossing: {rows[0][3] / rows[1][3]:.2f} x {rows[1][0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

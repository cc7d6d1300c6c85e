"""Does every shipped scene keep its cloth in frame? Simulates each shot and prints, per scene, the frames
where an active mass projects outside the image (fraytool.render.framing) and how much of the picture the
cloth reaches at most and at least.

    python benchmarks/framing.py [--scenes a,b] [--frames N]

A scene whose description says its cloth leaves the picture is listed but not counted as a failure."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fraytool.render.framing import shot_framing  # noqa: E402
from fraytool.scene import load_scene  # noqa: E402
from fraytool.sim import Simulation  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="", help="comma-separated scene names (default: every shipped scene)")
    ap.add_argument("--frames", type=int, default=0, help="at most this many frames per scene (default: all)")
    args = ap.parse_args()
    names = args.scenes.split(",") if args.scenes else sorted(p.stem for p in (ROOT / "scenes").glob("*.toml"))
    bad = 0
    for name in names:
        spec = load_scene(str(ROOT / "scenes" / f"{name}.toml"))
        t0 = time.perf_counter()
        sim = Simulation(spec)
        figures = shot_framing(spec, sim.frames(args.frames or None))
        out = [f for f in figures if f.outside]
        reach = [max(f.reach_x, f.reach_y) for f in figures]
        frame_s = spec.time.step_s * spec.time.steps_per_frame
        where = ", ".join(f"{round(f.time_s / frame_s)} ({f.outside})" for f in out[:12]) + (" ..." if len(out) > 12 else "")
        print(f"{name}: {len(figures)} frames, {len(out)} with masses outside{': ' + where if out else ''}; "
              f"reach {min(reach):.2f} to {max(reach):.2f} [{time.perf_counter() - t0:.0f} s]", flush=True)
        bad += bool(out)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())

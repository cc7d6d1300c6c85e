"""What a golden check costs (docs/golden.md "Speed"): `fraytool golden check` of a scene's frames from
nothing (a fresh work folder: it simulates) against `fraytool simulate` plus `fraytool render` of the same
frames. The target: the check costs at most the simulation plus 1.2 x the render.

    python benchmarks/golden_cost.py                      # fig7_square_grab, frames 0, 47, 94
    python benchmarks/golden_cost.py --scene fig5_corner_grab --frames 0,30,60
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(*args: str) -> float:
    t = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "fraytool", *args], capture_output=True, text=True)
    if run.returncode not in (0, 1):
        raise SystemExit(run.stderr)
    return time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="fig7_square_grab")
    ap.add_argument("--frames", default="0,47,94")
    args = ap.parse_args()
    frames = [int(f) for f in args.frames.split(",")]
    with tempfile.TemporaryDirectory(prefix="fraytool-golden-cost-") as tmp:
        tmp = Path(tmp)
        timed("simulate", args.scene, "-o", str(tmp / "warm"), "--frames", "2", "--progress", "none")  # compile
        sim = timed("simulate", args.scene, "-o", str(tmp / "plain"), "--frames", str(max(frames) + 1),
                    "--progress", "none")
        # render only (the frames are on disk), all the frames in one process: START:END:STEP through them
        step = frames[1] - frames[0] if len(frames) > 1 else 1
        if any(b - a != step for a, b in zip(frames, frames[1:])):
            raise SystemExit("--frames: give evenly spaced frames (one render process draws them as a range)")
        render = timed("render", args.scene, "-o", str(tmp / "plain"), "--frames",
                       f"{frames[0]}:{frames[-1] + 1}:{step}", "--png", "--no-mp4", "--progress", "none")
        timed("golden", "update", args.scene, "--dir", str(tmp / "g"), "--work", str(tmp / "w1"),
              "--frames", args.frames)
        check = timed("golden", "check", args.scene, "--dir", str(tmp / "g"), "--work", str(tmp / "w2"),
                      "--frames", args.frames)
    budget = sim + 1.2 * render
    print(f"{args.scene}, frames {args.frames}")
    print(f"simulate {sim:.2f} s, render {render:.2f} s ({len(frames)} frames in one process)")
    print(f"golden check from nothing {check:.2f} s; budget simulate + 1.2 x render = {budget:.2f} s: "
          f"{'within' if check <= budget else 'OVER'} ({check / budget:.2f} x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: `fraytool batch` of 8 shots on 1 and on 2 local Dask workers; prints wall times and the
speedup (issue 12: >= 1.7x on this 2-core machine).

The shots are the Fig. 6 scene (plain weave, a thrown ball tears the cloth) wedged over 8 break-limit
seeds (`--wedge scene.seed=1..8`), its whole shot (72 frames) at 640x360, each simulated and rendered
in full (fresh folders, so nothing is reused); the contact sheet is timed apart (it runs after the
last shot, on one worker). Worker start-up (process spawn,
imports, numba cache loads: about 3.5 s) is inside the times, as a user sees it: it is the serial part that keeps
the speedup under 2.

Run: ``python benchmarks/batch_scaling.py [--scene NAME] [--frames N] [--resolution WxH]`` (about 3 minutes)
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run(scene: str, workers: int, folder: Path, frames: int, resolution: str, sheet: bool = False) -> float:
    cmd = [sys.executable, "-m", "fraytool", "batch", scene, "--wedge", "scene.seed=1..8", "-o", str(folder),
           "--workers", str(workers), "--frames", f"0:{frames}", "--resolution", resolution, "--progress", "none"] + ([] if sheet else ["--no-contact-sheet"])
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    elapsed = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"batch failed ({r.returncode}):\n{r.stderr}")
    return elapsed


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default="fig6_thrown_ball_plain")
    p.add_argument("--frames", type=int, default=72)
    p.add_argument("--resolution", default="640x360")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        # compile / cache every kernel the shot uses (tearing included) once, outside the timing
        subprocess.run([sys.executable, "-m", "fraytool", "simulate", a.scene, "-o", str(Path(tmp) / "warm"),
                        "--frames", str(a.frames), "--progress", "none"], check=True, capture_output=True)
        one = run(a.scene, 1, Path(tmp) / "one", a.frames, a.resolution)
        two = run(a.scene, 2, Path(tmp) / "two", a.frames, a.resolution)
        sheet = run(a.scene, 2, Path(tmp) / "sheet", a.frames, a.resolution, sheet=True)
    print(f"8 shots ({a.scene}, seeds 1-8, {a.frames} frames, {a.resolution}): 1 worker {one:.1f} s, "
          f"2 workers {two:.1f} s, speedup {one / two:.2f}x")
    print(f"with the wedge's contact sheet (made after the last shot, on one worker): 2 workers {sheet:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

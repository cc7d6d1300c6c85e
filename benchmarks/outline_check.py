#!/usr/bin/env python
"""How long a panel outline's checks take for a pattern exported from a CAD tool (thousands of points): the
self-crossing test (fraytool.scene.panel_shape.outline_problems) and the whole panel (crossings inside it).

    python benchmarks/outline_check.py [--points 2000,20000]

Prints the seconds of each; the goal (issue 50): 2,000 points under 1 s, 20,000 under 5 s.
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np


def wavy_outline(points: int, radius_m: float = 0.2) -> np.ndarray:
    """A closed, non-crossing outline: a circle with a fine ripple (a scalloped hem), `points` corners."""
    t = np.linspace(0.0, 2.0 * math.pi, points, endpoint=False)
    r = radius_m * (1.0 + 0.02 * np.sin(37 * t))
    return np.stack([r * np.cos(t) + radius_m, r * np.sin(t) + radius_m], axis=1)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--points", default="2000,20000")
    args = p.parse_args()
    from fraytool.scene import parse_scene
    from fraytool.scene.panel_shape import outline_problems, panel_shape

    for n in (int(v) for v in args.points.split(",")):
        outline = wavy_outline(n)
        t0 = time.perf_counter()
        problems = outline_problems(outline)
        t1 = time.perf_counter()
        text = ("[cloth]\nspacing_m = 0.002\nthickness_m = 0.0005\nmass_per_crossing_kg = 1e-5\noutline_m = "
                + "[" + ", ".join(f"[{u:.9g}, {v:.9g}]" for u, v in outline) + "]\n[cloth.springs]\n"
                "structural_n_per_m = 20.0\n[time]\nstep_s = 1e-4\nsteps_per_frame = 1\nframes = 1\n")
        t2 = time.perf_counter()
        spec = parse_scene(text, "bench.toml")
        shape = panel_shape(spec.cloth)
        t3 = time.perf_counter()
        print(f"{n:6d} points: crossing test {t1 - t0:.3f} s ({'ok' if not problems else problems[0][2]}); "
              f"scene load and panel {t3 - t2:.3f} s ({int(shape.present.sum())} crossings)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""A garment at real yarn density: scenes/shirt_snag.toml with its yarns `--spacing-mm` apart (1 mm: about ten
yarns a centimetre; the scene's own is 5 mm) for a few frames. Prints the crossings, the step, the time per frame
simulated and rendered, and the peak resident memory.

    python benchmarks/garment_scale.py [--spacing-mm 1.0] [--frames 2] [--render] [--factor K]

The cloth is the same material at a finer weave: every panel's and seam's spacing is the new one, a crossing's
mass scales with its area (spacing^2), spring stiffnesses per spring stay (a membrane's stiffness per spring of a
square lattice does not depend on its spacing), and the step shrinks with the spacing (the explicit bound
2 / omega_max, omega ~ sqrt(k / m) ~ 1 / spacing) with the frame's simulated time kept. The frames simulated are
the sewing pre-roll's first ones, where the whole garment lies against the moving figure. With --factor K the
garment starts as the coarse base model ([cloth.multires] factor = K, docs/multires.md "Shaped panels and
garments"), and each frame also prints the share of its crossings still slaved (coarse)."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fraytool.resident_memory import peak_rss_bytes  # noqa: E402
from fraytool.scene import load_scene  # noqa: E402
from fraytool.sim import Simulation  # noqa: E402

SCENE_SPACING_M = 0.005
PANELS = 4
SEAMS = 10


def overrides(spacing_m: float, spec) -> list[tuple[str, object]]:
    ratio = spacing_m / SCENE_SPACING_M
    steps = max(1, round(spec.time.steps_per_frame / ratio))
    out = [("time.steps_per_frame", steps), ("time.step_s", spec.time.step_s * spec.time.steps_per_frame / steps)]
    for k, panel in enumerate(spec.all_panels):
        out += [(f"cloth.{k}.spacing_m", spacing_m), (f"cloth.{k}.mass_per_crossing_kg",
                                                     panel.mass_per_crossing_kg * ratio * ratio)]
    for k, seam in enumerate(spec.seams):
        out += [(f"seams.{k}.stitch_spacing_m", seam.stitch_spacing_m * ratio),
                (f"seams.{k}.stitch_length_m", seam.stitch_length_m * ratio)]
    return out


def _coarse(sim) -> str:
    """'; N % of the crossings slaved' for a coarse model, else ''."""
    if sim.model.coarse_factor == 1:
        return ""
    from fraytool.sim import multires

    free = multires.free_crossings(multires.coarse_layout(sim.model), sim.state.coarse_cell_refined)
    return f"; {1.0 - free.mean():.0%} of the crossings slaved"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spacing-mm", type=float, default=1.0)
    ap.add_argument("--frames", type=int, default=2, help="frames simulated after frame 0")
    ap.add_argument("--render", action="store_true", help="also render the frames at 1280x720 (headless GL)")
    ap.add_argument("--factor", type=int, default=1, help="[cloth.multires] factor (1, 2, 4 or 8; default 1)")
    args = ap.parse_args()
    base = load_scene(str(ROOT / "scenes" / "shirt_snag.toml"))
    spec = load_scene(str(ROOT / "scenes" / "shirt_snag.toml"), overrides(1e-3 * args.spacing_mm, base)
                      + [("cloth.0.multires.factor", args.factor)])
    t0 = time.perf_counter()
    sim = Simulation(spec)
    build_s = time.perf_counter() - t0
    m = sim.model
    print(f"shirt_snag at {args.spacing_mm:g} mm, factor {args.factor}: {m.crossing_count:,} crossings, "
          f"{m.spring_count:,} springs, step {spec.time.step_s:.3g} s x {spec.time.steps_per_frame} a frame; built in "
          f"{build_s:.1f} s" + _coarse(sim), flush=True)
    times = []
    for f in range(args.frames):
        t0 = time.perf_counter()
        sim.advance_frame()
        times.append(time.perf_counter() - t0)
        stages = sim.solver.stage_s
        top = sorted(stages.items(), key=lambda kv: -kv[1])[:3]
        print(f"  frame {f + 1}: {times[-1]:.1f} s simulated (so far: " +
              ", ".join(f"{k} {v:.1f} s" for k, v in top) + f"); peak RSS {peak_rss_bytes() / 2 ** 30:.2f} GiB"
              + _coarse(sim), flush=True)
    render_s = None
    if args.render:  # frame 0 (the garment whole) at 1280x720, through `fraytool bench --render`'s timing
        from fraytool.commands.render_bench import render_stage_timings

        ms = render_stage_timings(spec, frames=1, resolution=(1280, 720))
        render_s = 1e-3 * sum(v for k, v in ms.items() if k in ("geometry", "draw", "readback"))
        print("  render ms a frame: " + ", ".join(f"{k} {v:.0f}" for k, v in ms.items()), flush=True)
    mean = sum(times) / max(len(times), 1)
    print(f"RESULT: {m.crossing_count:,} crossings, {mean:.1f} s a frame simulated"
          + (f", {render_s:.2f} s a frame rendered" if render_s is not None else "")
          + f", peak RSS {peak_rss_bytes() / 2 ** 30:.2f} GiB (goal: under 2 s and 2 GB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

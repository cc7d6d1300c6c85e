#!/usr/bin/env python
"""Write docs/benchmarks.md: speed and memory of the shipped scenes, each figure with its command.

    python benchmarks/benchmarks_doc.py [--out docs/benchmarks.md] [--quick]

Runs `fraytool bench ... --json` once per row of ROWS (one at a time: the figures are wall times on
this machine) and writes a table of ms per frame, the stages that cost most, the peak resident size
and bytes per crossing, with the date, the machine and the exact command of every row, so anyone can
re-measure one row. `--quick` runs fewer frames (for a look, not for the document). The README
carries no figures; this file is where they live.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

ROWS = [
    # (label, bench arguments, frames, quick frames)
    ("drape", ["scenes/drape.toml"], 36, 4),
    ("fig5_corner_grab", ["scenes/fig5_corner_grab.toml"], 48, 4),
    ("fig6_thrown_ball_plain", ["scenes/fig6_thrown_ball_plain.toml"], 48, 4),
    ("fig7_square_grab", ["scenes/fig7_square_grab.toml"], 48, 4),
    ("fig7_square_grab, render 1280x720", ["scenes/fig7_square_grab.toml", "--render"], 6, 2),
    ("fold_pile", ["scenes/fold_pile.toml"], 48, 4),
    ("mannequin_snag (a 3750-triangle mesh body)", ["scenes/mannequin_snag.toml"], 96, 4),
    ("shirt_snag (4 sewn panels on a 2,352-triangle moving figure)", ["scenes/shirt_snag.toml"], 72, 4),
    ("shirt_snag, coarse base model at factor 2", ["scenes/shirt_snag.toml", "--set",
                                                   "cloth.0.multires.factor=2"], 72, 4),
    ("shirt_snag, render 1280x720", ["scenes/shirt_snag.toml", "--render"], 12, 2),
    ("round_tablecloth (a round panel torn by a ball)", ["scenes/round_tablecloth.toml"], 72, 4),
    ("round_tablecloth, coarse base model at factor 4", ["scenes/round_tablecloth.toml", "--set",
                                                         "cloth.multires.factor=4"], 72, 4),
    ("flag_tear (gusting wind, air drag, an orbiting camera)", ["scenes/flag_tear.toml"], 144, 4),
    ("flag_tear, render 1280x720", ["scenes/flag_tear.toml", "--render"], 12, 2),
    ("tablecloth_tear (first frames)", ["scenes/tablecloth_tear.toml"], 12, 2),
    ("tablecloth_tear (whole shot)", ["scenes/tablecloth_tear.toml"], 108, 2),
    ("drape 256 x 256, 1 thread", ["scenes/drape.toml", "--set", "cloth.warp_yarns=256", "--set",
                                   "cloth.weft_yarns=256", "--threads", "1"], 4, 2),
    ("drape 256 x 256, 2 threads", ["scenes/drape.toml", "--set", "cloth.warp_yarns=256", "--set",
                                    "cloth.weft_yarns=256", "--threads", "2"], 4, 2),
]


def run_row(args: list, frames: int) -> tuple[list, dict]:
    cmd = ["fraytool", "bench", *args, "--frames", str(frames), "--json"]
    r = subprocess.run([sys.executable, "-m", "fraytool", *cmd[1:]], cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"benchmarks_doc: {' '.join(cmd)} failed (exit {r.returncode}):\n{r.stderr[-2000:]}")
    return cmd, json.loads(r.stdout.strip().splitlines()[-1])


def top_stages(figures: dict, count: int = 3) -> str:
    stages = figures.get("stages_ms_per_frame", {})
    best = sorted(stages.items(), key=lambda kv: -kv[1])[:count]
    return ", ".join(f"{k} {v:.1f}" for k, v in best)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "benchmarks.md")
    p.add_argument("--quick", action="store_true", help="fewer frames per row (a look, not the document)")
    args = p.parse_args()
    lines = ["# Benchmarks", "",
             "Made by `python benchmarks/benchmarks_doc.py` (do not edit by hand): one `fraytool bench` run per "
             "row, one at a time.", "",
             f"Measured {datetime.date.today().isoformat()} on {platform.machine()}, {os.cpu_count()} cores, "
             f"Python {platform.python_version()}{' (--quick)' if args.quick else ''}.", "",
             "| run | ms per frame | costliest stages (ms per frame) | render ms per frame | peak RSS (MB) "
             "| bytes per crossing |",
             "|---|---|---|---|---|---|"]
    commands = []
    for label, row_args, frames, quick in ROWS:
        cmd, fig = run_row(row_args, quick if args.quick else frames)
        render = fig.get("render_ms_per_frame")
        lines.append(f"| {label} | {fig['ms_per_frame']:.1f} | {top_stages(fig)} | "
                     f"{'' if render is None else f'{render:.1f}'} | {fig['peak_rss_bytes'] / 1e6:.0f} | "
                     f"{fig['bytes_per_crossing']:.0f} |")
        commands.append(f"- {label}: `{' '.join(cmd)}`")
        print(lines[-1], flush=True)
    lines += ["", "The commands:", "", *commands, "",
              "ms per frame is the median over the frames; the stages are means. Other figures with their own "
              "scripts: `benchmarks/ccd_bench.py` (edge-edge CCD), `benchmarks/mesh_contact.py` (a 20k and a 200k "
              "triangle mesh under fig7's cloth), `benchmarks/mesh_share.py` (mesh contact's share of a frame, "
              "one and two threads, mannequin_snag and a cloth draped over the mannequin), "
              "`benchmarks/garment_scale.py` (shirt_snag at 1 mm yarn spacing), `benchmarks/multires_panels.py` (the "
              "coarse base model on a round panel, a garment and a cloth at rest on a mesh: speed-up, what stays "
              "coarse, tear figures), `benchmarks/memory_profile.py` (memory by "
              "phase), `benchmarks/batch_scaling.py` (the farm), `benchmarks/frames_identical.py` (a refactor "
              "leaves the frames bit-identical).", ""]
    args.out.write_text("\n".join(lines))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

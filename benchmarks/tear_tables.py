"""The measured tables of docs/tearing.md, regenerated: every figure scene over seeds, with the tear
figures of `fraytool simulate --json` at the last frame and over the shot.

    python benchmarks/tear_tables.py                     # print the tables (markdown)
    python benchmarks/tear_tables.py --write             # also replace them in docs/tearing.md
    python benchmarks/tear_tables.py --seeds 1-8 --scenes fig5_corner_grab,fig7_square_grab --jobs 2

Speed is not in these tables (`fraytool bench` measures it). Each (scene, seed) runs in its own process (numba's cache is shared); `--jobs` runs that many at once.
The tables go between the markers <!-- tear-tables:begin --> and <!-- tear-tables:end -->.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "tearing.md"
BEGIN, END = "<!-- tear-tables:begin -->", "<!-- tear-tables:end -->"
SCENES = ("fig5_corner_grab", "fig6_thrown_ball_plain", "fig6_thrown_ball_twill", "fig7_square_grab")

RUN = """
import json, sys, time
from dataclasses import replace
from fraytool.scene import load_scene
from fraytool.sim import Simulation
spec = load_scene(sys.argv[1])
spec = replace(spec, scene=replace(spec.scene, seed=int(sys.argv[2])))
sim = Simulation(spec)
t = time.perf_counter()
for _ in range(spec.time.frames - 1):
    sim.advance_frame()
out = sim.summary()
out["ms_per_frame"] = 1e3 * (time.perf_counter() - t) / max(1, spec.time.frames - 1)
print(json.dumps(out))
"""


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def run_one(scene: str, seed: int) -> dict:
    r = subprocess.run([sys.executable, "-c", RUN, scene, str(seed)], capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        return {"scene": scene, "seed": seed, "error": r.stderr.strip().splitlines()[-1] if r.stderr else "failed"}
    out = json.loads(r.stdout.strip().splitlines()[-1])
    out["seed"] = seed
    return out


def table(rows: list[dict]) -> str:
    head = ("| scene | seed | broken | pieces | two largest (mass fraction) | small pieces, most at a frame | "
            "max woven strain | strain cap hits | mean free end [mm] |\n"
            "|---|---|---|---|---|---|---|---|---|\n")
    lines = []
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['scene']} | {r['seed']} | error: {r['error']} | | | | | | |")
            continue
        f = r.get("largest_piece_fractions", [0, 0])
        lines.append(f"| {r['scene']} | {r['seed']} | {r['broken_springs']} | {r.get('pieces', '')} | "
                     f"{f[0]:.2f}, {f[1]:.2f} | {r.get('small_pieces_max', '')} | {r['max_woven_strain']:.3f} | "
                     f"{r['strain_cap_hits']} | {1e3 * r.get('fray_mean_free_end_m', 0.0):.1f} |")
    return head + "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--seeds", default="1-8")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--write", action="store_true", help=f"replace the tables in {DOC.relative_to(ROOT)}")
    args = ap.parse_args()
    jobs = [(s, k) for s in args.scenes.split(",") for k in _seeds(args.seeds)]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(lambda j: run_one(*j), jobs))
    text = table(rows)
    summary = []
    for s in args.scenes.split(","):
        rs = [r for r in rows if r["scene"] == s and "error" not in r]
        if rs:
            summary.append(f"- {s}: small pieces at any frame: {max(r['small_pieces_max'] for r in rs)} "
                           f"(seeds {args.seeds}); second-largest piece {min(r['largest_piece_fractions'][1] for r in rs):.2f}"
                           f"-{max(r['largest_piece_fractions'][1] for r in rs):.2f} of the mass")
    text += "\n" + "\n".join(summary) + "\n"
    text += f"\n(`python benchmarks/tear_tables.py --seeds {args.seeds}`, {time.perf_counter() - t0:.0f} s on this machine)\n"
    print(text)
    if args.write:
        doc = DOC.read_text()
        if BEGIN not in doc or END not in doc:
            print(f"{DOC}: markers {BEGIN} / {END} not found", file=sys.stderr)
            return 1
        a, b = doc.index(BEGIN) + len(BEGIN), doc.index(END)
        DOC.write_text(doc[:a] + "\n" + text + doc[b:])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

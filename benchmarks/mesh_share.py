"""How much of a frame mesh contact takes (issue 53: at most 30 %), on one thread and on two.

Two shots: scenes/mannequin_snag.toml as shipped, and `mannequin_drape`, written here: a 72 x 72 cloth
(4 mm spacing, no tearing, self-collision on) dropped 1 cm over the static mannequin of
scenes/assets/mannequin.obj (3,750 triangles, a spike with sharp edges on top): it falls onto the spike
and the shoulders and drapes down the torso, so most of the cloth is on or near the mesh from the
second half second on. Each shot runs through `fraytool bench --json` (median ms a frame; the stages'
means); mesh contact is the stages `collisions` and `contact_before_limit` (neither shot has another
colliding body).

    python benchmarks/mesh_share.py [--frames 72] [--shots mannequin_snag,mannequin_drape]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

DRAPE = """[scene]
name = "mannequin_drape"
description = "72 x 72 plain weave dropped over a static mannequin (benchmarks/mesh_share.py)"
seed = 1

[time]
step_s = 0.00020833333333333335
steps_per_frame = 20
frames = 72
fps = 24

[cloth]
warp_yarns = 72
weft_yarns = 72
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5.0e-6
origin_m = [-0.142, 0.12, -0.142]
plane = "xz"
weave = "plain"

[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.02

[cloth.strain]
limit = 0.10

[self_collision]
enabled = true

[[bodies]]
name = "mannequin"
shape = "mesh"
file = "{asset}"
position_m = [0.0, -0.05, 0.0]
friction = 0.6
"""


def bench(scene: Path, frames: int, threads: int) -> dict:
    r = subprocess.run([sys.executable, "-m", "fraytool", "bench", str(scene), "--frames", str(frames), "--threads",
                        str(threads), "--json"], cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"mesh_share: bench {scene.name} failed (exit {r.returncode}):\n{r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=72)
    p.add_argument("--shots", default="mannequin_snag,mannequin_drape")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        drape = Path(tmp) / "mannequin_drape.toml"
        drape.write_text(DRAPE.format(asset=(ROOT / "scenes" / "assets" / "mannequin.obj").as_posix()))
        scenes = {"mannequin_snag": ROOT / "scenes" / "mannequin_snag.toml", "mannequin_drape": drape}
        print(f"{'shot':<16} {'threads':>7} {'ms/frame':>9} {'contact ms':>10} {'share':>6}  costliest stages")
        for name in args.shots.split(","):
            for threads in (1, 2):
                f = bench(scenes[name], args.frames, threads)
                stages = f["stages_ms_per_frame"]
                contact = stages.get("collisions", 0.0) + stages.get("contact_before_limit", 0.0)
                # the stages are means over the frames: the share is of their sum (the median frame
                # need not be a typical one)
                share = contact / max(sum(stages.values()), 1e-12)
                top = ", ".join(f"{k} {v:.1f}" for k, v in sorted(stages.items(), key=lambda kv: -kv[1])[:4])
                print(f"{name:<16} {threads:>7} {f['ms_per_frame']:>9.1f} {contact:>10.1f} {100 * share:>5.0f}%  {top}",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

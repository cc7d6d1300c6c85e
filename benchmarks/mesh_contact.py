"""Cost of a mesh body under fig7's cloth (issue 32): fig7 as shipped, then with a 20,000 and a 200,000
triangle mesh (an icosphere, static, its top 2 cm under the cloth, which sags onto it). Per frame: the
whole simulation, and the mesh contact passes alone (the stage timers "collisions" and
"contact_before_limit": fig7 has no other colliding body). The issue bounds what the mesh adds,
(fig7 + contact) / fig7 <= 1.5 at 20k triangles, and the contact at 200k <= 3 x at 20k. The mesh
changes the shot (the cloth lies on it), so the whole-frame times are printed but not compared.
Each configuration runs once untimed first (the kernels compile as the tear starts).

    python benchmarks/mesh_contact.py [--frames 24]
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def _per_frame(spec, frames, mesh=None):
    """(seconds per frame, of them in the mesh contact passes) over `frames` frames of `spec` after the
    first, with `mesh` = (vertices, triangles) added as a static body at (0, 0.03, 0)."""
    from fraytool.sim.builder import scene_builder
    from fraytool.sim.simulation import Simulation

    builder = scene_builder(spec)
    if mesh is not None:
        builder.add_mesh("mesh", vertices_m=mesh[0], triangles=mesh[1], position_m=(0.0, 0.03, 0.0))
    sim = Simulation(spec, model=builder.finalize())
    sim.advance_frame()
    stage_s = sim.solver.context.counters.stage_s
    contact0 = stage_s["collisions"] + stage_s["contact_before_limit"]
    t = time.perf_counter()
    for _ in range(frames):
        sim.advance_frame()
    total = (time.perf_counter() - t) / frames
    return total, (stage_s["collisions"] + stage_s["contact_before_limit"] - contact0) / frames


def _measure(spec, frames, mesh=None):
    _per_frame(spec, frames, mesh)  # compile (the tearing kernels compile when the tear starts)
    return _per_frame(spec, frames, mesh)


def main() -> None:
    import trimesh
    from fraytool.scene import load_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=24)
    args = p.parse_args()
    spec = load_scene("scenes/fig7_square_grab.toml")
    base, _ = _measure(spec, args.frames)
    out = {}
    for subdiv, label in ((5, "20k"), (7, "200k")):  # 20,480 and 327,680 triangles
        m = trimesh.creation.icosphere(subdivisions=subdiv, radius=0.1)
        faces = np.asarray(m.faces)[:200_000] if label == "200k" else np.asarray(m.faces)  # (200k: open)
        out[label] = _measure(spec, args.frames, (np.asarray(m.vertices), faces))
        print(f"{label}: {len(faces)} triangles", flush=True)
    t20, c20 = out["20k"]
    t200, c200 = out["200k"]
    print(f"fig7 alone:           {1000 * base:7.1f} ms/frame")
    print(f"with 20k triangles:   {1000 * t20:7.1f} ms/frame, mesh contact {1000 * c20:6.1f} ms/frame: "
          f"(fig7 + contact) / fig7 = {(base + c20) / base:.2f} (<= 1.5)")
    print(f"with 200k triangles:  {1000 * t200:7.1f} ms/frame, mesh contact {1000 * c200:6.1f} ms/frame: "
          f"contact 200k / 20k = {c200 / c20:.2f} (<= 3)")


if __name__ == "__main__":
    main()

"""Cost of a mesh body under fig7's cloth (issue 32): fig7 as shipped, then with a 20,000 and a 200,000
triangle mesh (an icosphere, static, under the cloth where it sags onto it), seconds per frame of
simulation. Prints the three figures and the two ratios the issue bounds (<= 1.5 and <= 3).

    python benchmarks/mesh_contact.py [--frames 24]
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np


def _seconds_per_frame(spec, frames, mesh=None):
    from fraytool.sim.builder import build_model, ModelBuilder
    from fraytool.sim.simulation import Simulation

    model = build_model(spec)
    if mesh is not None:
        import fraytool.sim.builder as builder_module

        original = builder_module.ModelBuilder.finalize

        def finalize(self):
            if "mesh" not in [b.name for b in self.bodies]:
                self.add_mesh("mesh", vertices_m=mesh[0], triangles=mesh[1], position_m=(0.0, 0.03, 0.0))
            return original(self)

        builder_module.ModelBuilder.finalize = finalize
        try:
            model = build_model(spec)
        finally:
            builder_module.ModelBuilder.finalize = original
    sim = Simulation(spec, model=model)
    sim.advance_frame()  # compile
    t = time.perf_counter()
    for _ in range(frames):
        sim.advance_frame()
    return (time.perf_counter() - t) / frames


def main() -> None:
    import trimesh
    from fraytool.scene import load_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=24)
    args = p.parse_args()
    spec = load_scene("scenes/fig7_square_grab.toml")
    base = _seconds_per_frame(spec, args.frames)
    out = {"fig7": base}
    for subdiv, label in ((5, "20k"), (7, "200k")):  # 20,480 and 327,680 triangles
        m = trimesh.creation.icosphere(subdivisions=subdiv, radius=0.1)
        if label == "200k":
            m = trimesh.Trimesh(m.vertices, m.faces[:200_000], process=False)  # 200,000 of them (open)
        out[label] = _seconds_per_frame(spec, args.frames, (np.asarray(m.vertices), np.asarray(m.faces)))
        print(f"{label}: {len(m.faces)} triangles", flush=True)
    print(f"fig7 alone:            {1000 * out['fig7']:.1f} ms/frame")
    print(f"with 20k triangles:    {1000 * out['20k']:.1f} ms/frame  ratio {out['20k'] / out['fig7']:.2f} (<= 1.5)")
    print(f"with 200k triangles:   {1000 * out['200k']:.1f} ms/frame  ratio to 20k {out['200k'] / out['20k']:.2f} (<= 3)")


if __name__ == "__main__":
    main()

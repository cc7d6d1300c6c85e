"""How wide a yarn is on screen: for a scene's camera and one frame record, the drawn yarn diameter
(2 x the tube radius, [render] yarn_radius_m) in pixels at the view depth of each particle,
w = 2 r H / (2 d tan(fov / 2)) for image height H and depth d (the perspective projection of
fraytool.render.camera). Prints the median, 10th percentile and minimum over the particles inside
the frame, and the share of particles inside it.

    python benchmarks/yarn_width_px.py scenes/fig7_square_grab.toml OUT_DIR FRAME
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from fraytool.io.frame_store import FrameStore
from fraytool.render.camera import Camera
from fraytool.render.geometry import YarnStyle
from fraytool.scene import load_scene


def main(scene: str, out_dir: str, frame: int) -> None:
    spec = load_scene(scene)
    store = FrameStore(Path(out_dir))
    topology = store.load_topology()
    radius = YarnStyle.from_spec(spec.render, topology).radius_m
    record = store.load_frame(frame)
    cam = Camera(spec.camera, record.time_s)  # a moving camera at the frame's time
    W, H = spec.render.resolution
    p = np.asarray(record.particle_position_m, dtype=np.float64)
    clip = np.c_[p, np.ones(len(p))] @ cam.view_proj(W / H).T
    ndc = clip[:, :2] / clip[:, 3:4]
    inside = (np.abs(ndc) <= 1).all(axis=1) & (clip[:, 3] > 0)
    depth = -cam.view_depth(p[inside])
    width = 2 * radius * H / (2 * depth * math.tan(math.radians(cam.spec.fov_deg) / 2))
    print(f"{spec.name} frame {frame}: yarn width px median {np.median(width):.1f}, "
          f"10th percentile {np.percentile(width, 10):.1f}, min {width.min():.1f}; "
          f"{100 * inside.mean():.0f} % of particles in frame")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]))

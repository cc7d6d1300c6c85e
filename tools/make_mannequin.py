"""Writes scenes/assets/mannequin.obj, the mesh of scenes/mannequin_snag.toml: a dress-form torso (a
squashed UV ellipsoid, smooth) with a sharp four-sided spike on its top (the snag), as one OBJ of two
closed parts: python tools/make_mannequin.py"""
from pathlib import Path

import numpy as np


def ellipsoid(radii, rings=40, segments=48):
    v = [(0.0, radii[1], 0.0)]
    for r in range(1, rings):
        th = np.pi * r / rings
        for s in range(segments):
            ph = 2 * np.pi * s / segments
            v.append((radii[0] * np.sin(th) * np.cos(ph), radii[1] * np.cos(th), -radii[2] * np.sin(th) * np.sin(ph)))
    v.append((0.0, -radii[1], 0.0))
    f = []
    for s in range(segments):  # top cap
        f.append((0, 1 + s, 1 + (s + 1) % segments))
    for r in range(rings - 2):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        for s in range(segments):
            s1 = (s + 1) % segments
            f += [(a + s, b + s, b + s1), (a + s, b + s1, a + s1)]
    last, base = len(v) - 1, 1 + (rings - 2) * segments
    for s in range(segments):
        f.append((last, base + (s + 1) % segments, base + s))
    return np.array(v), np.array(f)


def spike(base_y, tip_y, half, lean=0.0):
    v = np.array([(-half, base_y, -half), (half, base_y, -half), (half, base_y, half), (-half, base_y, half),
                  (lean, tip_y, 0.0)])
    f = np.array([(0, 1, 2), (0, 2, 3), (0, 4, 1), (1, 4, 2), (2, 4, 3), (3, 4, 0)])
    return v, f


def main():
    tv, tf = ellipsoid((0.10, 0.12, 0.065))
    sv, sf = spike(0.10, 0.16, 0.012)
    v = np.concatenate([tv, sv])
    f = np.concatenate([tf, sf + len(tv)])
    out = Path(__file__).resolve().parent.parent / "scenes" / "assets" / "mannequin.obj"
    with open(out, "w") as h:
        h.write("# mannequin torso with a spike on top (tools/make_mannequin.py); metres, y up\n")
        for p in v:
            h.write(f"v {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}\n")
        for t in f:
            h.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")
    print(f"wrote {out}: {len(v)} vertices, {len(f)} triangles")


if __name__ == "__main__":
    main()

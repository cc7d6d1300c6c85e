"""Writes scenes/assets/figure/figure.0001.obj ... figure.0060.obj, a doll-sized figure to dress, as a
numbered OBJ sequence (a mesh body's `file = "assets/figure/figure.####.obj"`, played at 24 frames a
second: 2.5 s): python tools/make_figure.py

Metres, y up, standing on y = 0, facing +z (its right hand at -x), 0.50 m tall. Six closed, outward
parts in one OBJ, overlapping where they join: a torso (about 0.13 m wide, 0.08 m deep, y 0.20 to
0.38; broad shoulders over a narrower chest), a neck with its head (a
sphere of 0.045 m), two arm capsules (0.018 m, 0.17 m long, their top ends buried in the shoulders)
and two leg capsules (0.025 m, from the hips to the floor). Frames 1-12 stand at rest in an A-pose (arms 45
degrees out, as garment tools dress an avatar); over 13-48 the arms rise sideways about their shoulders
(about z, eased in and out) to 80 degrees (left) and 86 degrees (right) from hanging while the upper body turns 10 degrees about y and back; 49-60
hold. Every part moves rigidly, so every frame has the same vertices and triangles; no face turns by
more than 30 degrees against its neighbour (no sharp edges for the yarns to catch on)."""
from pathlib import Path

import numpy as np

FRAMES = 60
REST_FRAMES = 12  # frames 1-12 stand still
MOVE_END = 48  # the arms reach their top at this frame and hold to FRAMES
TORSO_Y = (0.20, 0.38)
SHOULDER = np.array([0.072, 0.352, 0.0])  # the left arm's pivot; the right one at -x
ARM_RADIUS, ARM_LENGTH = 0.018, 0.17
ARM_REST_DEG = 45.0  # an A-pose at rest: panels laid round the body clear the arms
ARM_UP_DEG = {"left": 80.0, "right": 86.0}  # from hanging, at frame MOVE_END
TWIST_DEG = 10.0  # the upper body's turn about y, at the middle of the move
HIP_X, LEG_RADIUS, LEG_TOP = 0.033, 0.025, 0.235  # LEG_TOP: the leg capsule's upper centre
HEAD_CENTRE_Y, HEAD_RADIUS, NECK_RADIUS = 0.455, 0.045, 0.019


def loft(rings, bottom_y, top_y, segments):
    """A closed surface around the y axis: rings (y, half-width x, half-depth z) from bottom to top,
    each an ellipse of `segments` points, closed by a pole at bottom_y and one at top_y; normals out.
    An ellipse's points are closer at its sharper ends (halfway to even turns between its sides)."""
    phi = 2 * np.pi * np.arange(segments) / segments
    v = [(0.0, bottom_y, 0.0)]
    for y, a, c in rings:
        t = np.arctan2(np.sin(phi), np.sqrt(a / c) * np.cos(phi))
        v += [(a * np.cos(p), y, -c * np.sin(p)) for p in t]
    v.append((0.0, top_y, 0.0))
    f = []
    for s in range(segments):  # bottom fan
        f.append((0, 1 + (s + 1) % segments, 1 + s))
    for r in range(len(rings) - 1):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        for s in range(segments):
            s1 = (s + 1) % segments
            f += [(a + s, a + s1, b + s1), (a + s, b + s1, b + s)]
    top, base = len(v) - 1, 1 + (len(rings) - 1) * segments
    for s in range(segments):  # top fan
        f.append((top, base + s, base + (s + 1) % segments))
    return np.array(v), np.array(f)


def capsule(radius, length, segments, cap_rings=3, mid_rings=1):
    """A capsule along +y from its lower sphere centre at y = 0 to its upper one at y = length."""
    polar = np.radians(90.0 * np.arange(1, cap_rings + 2) / (cap_rings + 1))  # from the pole to the equator
    ys = [-radius * np.cos(t) for t in polar]
    rs = [radius * np.sin(t) for t in polar]
    ys += [length * (i + 1) / (mid_rings + 1) for i in range(mid_rings)]
    rs += [radius] * mid_rings
    ys += [length + radius * np.cos(t) for t in polar[::-1]]
    rs += [radius * np.sin(t) for t in polar[::-1]]
    return loft([(y, r, r) for y, r in zip(ys, rs)], -radius, length + radius, segments)


def resample(y, a, c, max_step, max_turn_deg):
    """Rings along a dense profile (pole to pole, y rising), as few as keep every span between two rings
    under max_step [m] of profile and max_turn_deg of turn (in width and in depth) while spreading them
    evenly in that measure: neighbouring faces turn by about max_turn_deg at most, and curved parts (a
    shoulder, the chin) get closer rings than straight ones."""
    length = np.zeros(len(y) - 1)
    turn = np.zeros(len(y) - 1)
    for w in (a, c):
        dy, dw = np.diff(y), np.diff(w)
        length = np.maximum(length, np.hypot(dy, dw))
        bend = np.abs(np.diff(np.arctan2(dw, dy)))
        turn = np.maximum(turn, np.append(bend, 0.0) / 2 + np.append(0.0, bend) / 2)
    step = np.maximum(length / max_step, turn / np.radians(max_turn_deg))
    measure = np.concatenate([[0.0], np.cumsum(step)])
    spans = int(np.ceil(measure[-1]))
    at = measure[-1] * np.arange(1, spans) / spans
    return [(np.interp(t, measure, y), np.interp(t, measure, a), np.interp(t, measure, c)) for t in at]


def bump(y, centre, width):
    return np.exp(-((y - centre) / width) ** 2)


def smooth_max(a, b, blend):
    """max(a, b) with its corner rounded over `blend` (a fillet where two profiles meet)."""
    h = np.clip(blend - np.abs(a - b), 0.0, None) / blend
    return np.maximum(a, b) + h * h * blend / 4


def torso(segments=24, max_step=0.02, max_turn_deg=22.0):
    """Rounded ends (a superellipse in height), broad shoulders, a narrower chest and waist, hips."""
    theta = np.linspace(np.pi, 0.0, 20001)  # |u|^4 + round_ends^4 = 1, u from -1 (bottom) to 1
    u = np.sign(np.cos(theta)) * np.sqrt(np.abs(np.cos(theta)))
    round_ends = np.sqrt(np.sin(theta))
    y = TORSO_Y[0] + (u + 1.0) * 0.5 * (TORSO_Y[1] - TORSO_Y[0])
    half_width = (0.0505 + 0.0175 * bump(y, 0.352, 0.022) + 0.006 * bump(y, 0.228, 0.028)
                  - 0.002 * bump(y, 0.27, 0.02))
    half_depth = 0.036 + 0.005 * bump(y, 0.305, 0.035) + 0.003 * bump(y, 0.225, 0.03)
    rings = resample(y, half_width * round_ends, half_depth * round_ends, max_step, max_turn_deg)
    return loft(rings, y[0], y[-1], segments)


def head_and_neck(segments=16, max_step=0.02, max_turn_deg=22.0):
    """The head sphere and a neck whose lower end is buried in the torso, joined by a smooth fillet."""
    bottom, top = TORSO_Y[1] - 0.035, HEAD_CENTRE_Y + HEAD_RADIUS
    y = np.linspace(bottom, top, 20001)
    head = np.sqrt(np.clip(HEAD_RADIUS ** 2 - (y - HEAD_CENTRE_Y) ** 2, 0.0, None))
    ends = np.clip(y, bottom + NECK_RADIUS, HEAD_CENTRE_Y)  # a capsule up to the head's centre
    neck = np.sqrt(np.clip(NECK_RADIUS ** 2 - (y - ends) ** 2, 0.0, None))
    r = smooth_max(head, neck, 0.012)
    return loft(resample(y, r, r, max_step, max_turn_deg), bottom, top, segments)


def rot_y(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def arm_local():
    """An arm hanging straight down from its pivot at the origin (the top sphere's centre)."""
    v, f = capsule(ARM_RADIUS, ARM_LENGTH - 2 * ARM_RADIUS, 14, cap_rings=3, mid_rings=1)
    return v - [0.0, ARM_LENGTH - 2 * ARM_RADIUS, 0.0], f


def parts():
    """(name, vertices, triangles, kind) at rest before the arms' own angle; kind says how a part moves."""
    arm_v, arm_f = arm_local()
    leg_v, leg_f = capsule(LEG_RADIUS, LEG_TOP - LEG_RADIUS, 14, cap_rings=3, mid_rings=1)
    tv, tf = torso()
    hv, hf = head_and_neck()
    return [("torso", tv, tf, "upper"), ("head and neck", hv, hf, "upper"),
            ("left arm", arm_v, arm_f, "left"), ("right arm", arm_v.copy(), arm_f, "right"),
            ("left leg", leg_v + [HIP_X, LEG_RADIUS, 0.0], leg_f, "leg"),
            ("right leg", leg_v + [-HIP_X, LEG_RADIUS, 0.0], leg_f, "leg")]


def ease(p):
    """0 to 1 with zero speed at both ends."""
    p = np.clip(p, 0.0, 1.0)
    return p * p * (3.0 - 2.0 * p)


def pose(frame):
    """(twist about y, left arm, right arm) in degrees at a frame counted from 1."""
    p = (frame - REST_FRAMES) / (MOVE_END - REST_FRAMES)
    rise = ease(p)
    twist = TWIST_DEG * np.sin(np.pi * rise) ** 2  # out and back, at rest at both ends
    left = ARM_REST_DEG + (ARM_UP_DEG["left"] - ARM_REST_DEG) * rise
    right = ARM_REST_DEG + (ARM_UP_DEG["right"] - ARM_REST_DEG) * rise
    return twist, left, right


def place(v, kind, frame):
    twist, left, right = pose(frame)
    if kind == "leg":
        return v
    if kind in ("left", "right"):  # abduction about z at the shoulder, which then turns with the torso
        side = 1.0 if kind == "left" else -1.0
        angle = left if kind == "left" else -right
        v = v @ rot_z(angle).T + SHOULDER * [side, 1.0, 1.0]
    return v @ rot_y(twist).T


def write_obj(path, vertices, triangles, header):
    rounded = np.round(vertices, 5) + 0.0  # + 0.0: no "-0.00000"
    lines = header + [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in rounded]
    lines += [f"f {a} {b} {c}" for a, b, c in triangles + 1]
    path.write_text("\n".join(lines) + "\n")


def main():
    import argparse

    ap = argparse.ArgumentParser(description="write the figure's OBJ sequence")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "scenes" / "assets" / "figure",
                    help="folder to write into (default: scenes/assets/figure)")
    out = ap.parse_args().out
    pieces = parts()
    triangles, start, header = [], 0, []
    for name, v, f, _ in pieces:
        triangles.append(f + start)
        header.append(f"# {name}: vertices {start + 1}-{start + len(v)}, {len(f)} triangles")
        start += len(v)
    triangles = np.concatenate(triangles)
    out.mkdir(parents=True, exist_ok=True)
    for frame in range(1, FRAMES + 1):
        v = np.concatenate([place(v, kind, frame) for _, v, _, kind in pieces])
        twist, left, right = pose(frame)
        top = [f"# doll figure, frame {frame} of {FRAMES} at 24 fps (tools/make_figure.py); metres, y up, "
               "facing +z",
               f"# upper body turned {twist:.2f} deg about y; left arm {left:.2f} deg, right arm "
               f"{right:.2f} deg from hanging"]
        write_obj(out / f"figure.{frame:04d}.obj", v, triangles, top + header)
    size = sum(p.stat().st_size for p in out.glob("figure.*.obj"))
    print(f"wrote {out}/figure.0001.obj ... figure.{FRAMES:04d}.obj: {start} vertices, {len(triangles)} "
          f"triangles each, {size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()

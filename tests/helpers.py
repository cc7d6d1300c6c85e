"""Shared test helpers: small scenes from text, array comparison that names what differs."""
from __future__ import annotations

import numpy as np

from fraytool.scene import parse_scene

SMALL_SCENE = """
[scene]
name = "{name}"
seed = {seed}

[time]
step_s = {step_s}
steps_per_frame = {steps_per_frame}
frames = {frames}
fps = 24

[world]
gravity_m_s2 = {gravity}

[cloth]
warp_yarns = {nx}
weft_yarns = {ny}
spacing_m = 0.005
thickness_m = 0.0008
mass_per_crossing_kg = 2.0e-5
origin_m = [-0.03, 0.1, -0.03]
plane = "xz"
weave = "plain"

[cloth.springs]
structural_n_per_m = 20.0
bend_n_per_m = {bend}
shear_n_per_m = {shear}
damping = {damping}

[cloth.strain]
limit = 0.10
max_iterations = 30
"""


def small_scene_text(**overrides) -> str:
    values = dict(name="small", seed=1, step_s=4e-4, steps_per_frame=5, frames=6, gravity="[0.0, -9.81, 0.0]",
                  nx=12, ny=12, bend=0.5, shear=2.0, damping=0.0)
    values.update(overrides)
    return SMALL_SCENE.format(**values)


BALL = """
[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.02
position_m = [0.0, 0.07, 0.0]
"""
"""A ball 7 cm above the origin, to add to small_scene_text()."""


def small_scene(extra: str = "", **overrides):
    return parse_scene(small_scene_text(**overrides) + extra, "small.toml")


def assert_arrays_equal(expected: dict, actual: dict, names=None) -> None:
    """Bit-for-bit equality of named arrays; the message names the first array that differs."""
    for name in names or expected.keys():
        a, b = np.asarray(expected[name]), np.asarray(actual[name])
        if a.shape != b.shape or a.dtype != b.dtype or a.tobytes() != b.tobytes():
            diff = np.argwhere(a != b)[:3] if a.shape == b.shape else "shape"
            raise AssertionError(f"array {name!r} differs (first differing indices: {diff})")


PULLED_STRIP = """
[scene]
name = "{name}"
seed = 1
[time]
step_s = 2e-4
steps_per_frame = 20
frames = 40
fps = 24
[world]
gravity_m_s2 = [0.0, 0.0, 0.0]
[cloth]
warp_yarns = 24
weft_yarns = 10
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xy"
weave = "plain"
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.02
[cloth.tearing]
enabled = true
yarn_level = {yarn_level}
transition_strain = 0.12
break_strain = 0.18
break_strain_spread = {spread}
{extra}[[bodies]]
name = "left"
shape = "box"
half_extents_m = [0.002, 0.03, 0.002]
position_m = [0.0, 0.018, 0.0]
collide = false
[[bodies]]
name = "right"
shape = "box"
half_extents_m = [0.002, 0.03, 0.002]
position_m = [0.092, 0.018, 0.0]
motion = "kinematic"
path = [[0.0, 0.092, 0.018, 0.0], [0.15, 0.122, 0.018, 0.0]]
collide = false
[[attachments]]
body = "left"
edge = "left"
[[attachments]]
body = "right"
edge = "right"
"""


def pulled_strip_text(name="strip", yarn_level=False, spread=0.03, extra="") -> str:
    """A 24 x 10 strip, no gravity, held by a bar at its left edge while a bar pulls its right
    edge away: it tears. `extra` is inserted after [cloth.tearing] (e.g. a [self_collision] table)."""
    return PULLED_STRIP.format(name=name, yarn_level="true" if yarn_level else "false", spread=spread, extra=extra)

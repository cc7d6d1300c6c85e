"""Rigid bodies: a thrown (dynamic) ball hits and pushes the cloth, and the cloth pushes back;
boxes and planes keep masses out."""
import numpy as np

from fraytool.sim import Simulation
from helpers import small_scene

THROWN = """
[[bodies]]
name = "left_bar"
shape = "box"
half_extents_m = [0.003, 0.003, 0.04]
position_m = [-0.03, 0.1, -0.005]
collide = false

[[bodies]]
name = "right_bar"
shape = "box"
half_extents_m = [0.003, 0.003, 0.04]
position_m = [0.025, 0.1, -0.005]
collide = false

[[bodies]]
name = "ball"
shape = "sphere"
radius_m = 0.01
motion = "dynamic"
mass_kg = 0.002
position_m = [-0.0025, 0.13, -0.0025]
velocity_m_s = [0.0, -3.0, 0.0]
gravity = false

[[attachments]]
body = "left_bar"
edge = "left"

[[attachments]]
body = "right_bar"
edge = "right"
"""


def test_thrown_ball_pushes_cloth_and_is_slowed():
    sim = Simulation(small_scene(THROWN, gravity="[0.0, 0.0, 0.0]", nx=12, ny=12, frames=40))
    n = sim.model.crossing_count
    y0 = sim.state.particle_position_m[:n, 1].copy()
    for _ in sim.frames(40):
        pass
    ball_v = sim.state.body_velocity_m_s[2]
    dy = sim.state.particle_position_m[:n, 1] - y0
    assert dy.min() < -0.005, "the cloth was not pushed down by the ball"
    assert -3.0 < ball_v[1] < -0.0 + 2.9, "the ball did not feel the cloth"
    # nothing of the cloth is inside the ball
    d = np.linalg.norm(sim.state.particle_position_m[:n] - sim.state.body_position_m[2], axis=1)
    assert d.min() >= 0.01 + 0.5 * sim.model.thickness_m - 1e-9


def test_box_and_plane_keep_masses_out():
    extra = """
[[bodies]]
name = "table"
shape = "box"
half_extents_m = [0.01, 0.02, 0.01]
position_m = [0.0, 0.05, 0.0]
rotation_deg = [0.0, 30.0, 0.0]

[[bodies]]
name = "floor"
shape = "plane"
position_m = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
"""
    sim = Simulation(small_scene(extra, frames=60, steps_per_frame=20))
    for _ in sim.frames(60):
        pass
    n = sim.model.crossing_count
    x = sim.state.particle_position_m[:n]
    half_t = 0.5 * sim.model.thickness_m
    assert x[:, 1].min() >= half_t - 1e-12
    R = sim.model.body_rotation[0]
    local = (x - np.array([0.0, 0.05, 0.0])) @ R
    half = np.array([0.01, 0.02, 0.01])
    outside = np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=1)  # distance to the box, 0 inside
    assert outside.min() >= half_t - 1e-9, "a mass is within half the thickness of the box"
    assert x[:, 1].max() > 0.05  # some of the cloth rests on the box top

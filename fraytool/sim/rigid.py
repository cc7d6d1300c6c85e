"""Rigid-body motion: static, kinematic (constant velocity or keyframed path) and dynamic bodies.

There are a handful of bodies per scene, so their motion is plain NumPy, once per step.
Dynamic bodies integrate with explicit Euler (gravity) and receive the cloth's reaction as an
impulse from the rigid-contact pass.
"""
from __future__ import annotations

import numpy as np

from fraytool.sim.model import Model
from fraytool.kinds import MOTION_DYNAMIC, MOTION_KINEMATIC
from fraytool.sim.state import State


def kinematic_position(model: Model, body: int, time_s: float) -> np.ndarray:
    """Position of a kinematic body at time_s: path keyframes (linear, held at the ends) or
    initial position + velocity x (time - start)."""
    path = model.body_path[body]
    if path.shape[0]:
        t = path[:, 0]
        return np.array([np.interp(time_s, t, path[:, 1 + d]) for d in range(3)])
    moving = max(0.0, time_s - model.body_start_s[body])
    return model.body_initial_position_m[body] + moving * model.body_initial_velocity_m_s[body]


def advance_bodies(model: Model, state: State, time_new_s: float, dt_s: float) -> None:
    """Move every non-static body to time_new_s (positions and velocities in state)."""
    for k in range(model.body_count):
        motion = model.body_motion[k]
        if motion == MOTION_KINEMATIC:
            new = kinematic_position(model, k, time_new_s)
            state.body_velocity_m_s[k] = (new - state.body_position_m[k]) / dt_s
            state.body_position_m[k] = new
        elif motion == MOTION_DYNAMIC:
            if time_new_s <= model.body_start_s[k]:
                continue  # waiting to be thrown
            if time_new_s - dt_s <= model.body_start_s[k]:
                state.body_velocity_m_s[k] = model.body_initial_velocity_m_s[k]
            if model.body_gravity[k]:
                state.body_velocity_m_s[k] += dt_s * model.gravity_m_s2
            state.body_position_m[k] += dt_s * state.body_velocity_m_s[k]


def apply_cloth_impulse(model: Model, state: State, body_impulse_ns: np.ndarray) -> None:
    """Give dynamic bodies the reaction of the impulse their contacts gave the cloth."""
    dyn = model.body_motion == MOTION_DYNAMIC
    state.body_velocity_m_s[dyn] -= body_impulse_ns[dyn] / model.body_mass_kg[dyn, None]

"""Rigid-body motion: static, kinematic (constant velocity or keyframed path) and dynamic bodies.

There are a handful of bodies per scene, so their motion is plain NumPy, once per step.
Dynamic bodies integrate with explicit Euler (gravity) and receive the cloth's reaction as an
impulse from the rigid-contact pass. A kinematic body with orientation keys turns along them
(fraytool.sim.paths); every other body keeps its fixed orientation.
"""
from __future__ import annotations

import numpy as np

from fraytool.sim.model import Model
from fraytool.kinds import MOTION_DYNAMIC, MOTION_KINEMATIC
from fraytool.geometry.rotations import quat_to_matrix
from fraytool.sim.paths import LINEAR, angular_velocity_rad_s, path_orientation, path_position_m
from fraytool.sim.state import State


def kinematic_position(model: Model, body: int, time_s: float) -> np.ndarray:
    """Position of a kinematic body at time_s: path keyframes (held at the ends; linear or Catmull-Rom,
    fraytool.sim.paths) or initial position + velocity x (time - start)."""
    path = model.body_path[body]
    if path.shape[0]:
        return path_position_m(path, interpolation(model, body), time_s)
    moving = max(0.0, time_s - model.body_start_s[body])
    return model.body_initial_position_m[body] + moving * model.body_initial_velocity_m_s[body]


def kinematic_orientation(model: Model, body: int, time_s: float) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a body with orientation keys at time_s (fraytool.sim.paths)."""
    return path_orientation(model.body_orientation_path[body], interpolation(model, body), time_s)


def interpolation(model: Model, body: int) -> str:
    """The body's interpolation between keys ("linear" for a Model made without one)."""
    return model.body_interpolation[body] if model.body_interpolation else LINEAR


def turns(model: Model, body: int) -> bool:
    """The body follows orientation keys."""
    return bool(model.body_orientation_path) and model.body_orientation_path[body].shape[0] > 0


def _turn_kinematic(model: Model, state: State, body: int, time_new_s: float, dt_s: float) -> None:
    """Orientation at time_new_s and the angular velocity of the turn over the step."""
    q_start = kinematic_orientation(model, body, time_new_s - dt_s)
    q_end = kinematic_orientation(model, body, time_new_s)
    state.body_rotation[body] = quat_to_matrix(q_end)
    state.body_angular_velocity_rad_s[body] = angular_velocity_rad_s(q_start, q_end, dt_s)


def advance_bodies(model: Model, state: State, time_new_s: float, dt_s: float) -> None:
    """Move every non-static body to time_new_s (positions, orientations and velocities in state)."""
    for k in range(model.body_count):
        motion = model.body_motion[k]
        if motion == MOTION_KINEMATIC:
            new = kinematic_position(model, k, time_new_s)
            state.body_velocity_m_s[k] = (new - state.body_position_m[k]) / dt_s
            state.body_position_m[k] = new
            if turns(model, k):
                _turn_kinematic(model, state, k, time_new_s, dt_s)
        elif motion == MOTION_DYNAMIC:
            if time_new_s <= model.body_start_s[k]:
                continue  # waiting to be thrown
            if time_new_s - dt_s <= model.body_start_s[k]:
                state.body_velocity_m_s[k] = model.body_initial_velocity_m_s[k]
            if model.body_gravity[k]:
                state.body_velocity_m_s[k] += dt_s * model.gravity_at_m_s2(time_new_s - dt_s)
            state.body_position_m[k] += dt_s * state.body_velocity_m_s[k]


def apply_cloth_impulse(model: Model, state: State, body_impulse_ns: np.ndarray) -> None:
    """Give dynamic bodies the reaction of the impulse their contacts gave the cloth."""
    dyn = model.body_motion == MOTION_DYNAMIC
    state.body_velocity_m_s[dyn] -= body_impulse_ns[dyn] / model.body_mass_kg[dyn, None]

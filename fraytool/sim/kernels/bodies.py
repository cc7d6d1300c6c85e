"""The bodies' argument group of the contact kernels: every body by its kind and parameter vector.

A body is a kind (`Model.body_shape`, SHAPE_* of fraytool.kinds) and a parameter vector of three
numbers whose meaning the kind gives (`Model.body_params`, as Newton's shape_type / shape_scale):

    sphere  (radius [m], 0, 0)
    box     half extents [m] along the body's axes
    plane   unit normal in the body frame (the free side)

so a new kind is a branch in the kernels below (surface_contact, bounding_radius) plus its parsing
(fraytool.sim.builder) and its drawing (fraytool.render.bodies); see docs/architecture.md.

`BodiesIn` holds references to the Model's and the State's arrays (no copies), built at each call
(`bodies_in`): numba types the namedtuple as a struct, as the tearing groups (fraytool.sim.tearing.groups).
"""
from __future__ import annotations

from collections import namedtuple
from typing import Optional

import numpy as np

BodiesIn = namedtuple("BodiesIn", [
    "shape",          # (B,) int8, SHAPE_*
    "params",         # (B, 3) float64, by kind (module docstring)
    "rotation",       # (B, 3, 3) body to world, State
    "friction",       # (B,) Coulomb coefficient against the cloth
    "collide",        # (B,) bool: the cloth collides with the body
    "dynamic",        # (B,) bool: the body takes the cloth's impulse
    "position_m",     # (B, 3) State
    "velocity_m_s",   # (B, 3) State
    "angular_velocity_rad_s",  # (B, 3) State: world frame, over the step
])
BodiesIn.__doc__ = "Read-only body arrays of the contact kernels (Model and State references)."


def bodies_in(model, state, collide: Optional[np.ndarray] = None) -> BodiesIn:
    """The `bodies_in` group of `model` and `state` (`collide` replaces the model's mask when given)."""
    from fraytool.kinds import MOTION_DYNAMIC

    return BodiesIn(model.body_shape, model.body_params, state.body_rotation, model.body_friction,
                    model.body_collide if collide is None else collide, model.body_motion == MOTION_DYNAMIC,
                    state.body_position_m, state.body_velocity_m_s, state.body_angular_velocity_rad_s)


def legacy_body_arrays(shape: np.ndarray, params: np.ndarray) -> dict[str, np.ndarray]:
    """The per-shape arrays frame folders have held since the first version (topology.npz):
    body_radius_m, body_half_extents_m, body_normal, from the kinds and parameter vectors."""
    from fraytool.kinds import SHAPE_BOX, SHAPE_PLANE, SHAPE_SPHERE

    params = np.asarray(params, float).reshape(-1, 3)
    radius = np.where(shape == SHAPE_SPHERE, params[:, 0], 0.0)
    half = np.where((shape == SHAPE_BOX)[:, None], params, 0.0)
    normal = np.where((shape == SHAPE_PLANE)[:, None], params, np.array([0.0, 1.0, 0.0]))
    return {"body_radius_m": radius, "body_half_extents_m": half, "body_normal": normal}


def params_from_legacy(shape: np.ndarray, arrays) -> np.ndarray:
    """body_params from the per-shape arrays of a frame folder written before body_params existed."""
    from fraytool.kinds import SHAPE_BOX, SHAPE_PLANE

    radius = np.asarray(arrays["body_radius_m"], float)
    params = np.stack([radius, np.zeros_like(radius), np.zeros_like(radius)], axis=1).reshape(-1, 3)
    box, plane = shape == SHAPE_BOX, shape == SHAPE_PLANE
    params[box] = np.asarray(arrays["body_half_extents_m"], float).reshape(-1, 3)[box]
    params[plane] = np.asarray(arrays["body_normal"], float).reshape(-1, 3)[plane]
    return params

"""After strain limiting every structural spring is within the limit, or the cap was reported."""
import numpy as np

from fraytool.sim import build_model
from fraytool.sim.kernels.strain_limit import limit_strain
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from helpers import small_scene


def _structural_strain(model, state, x):
    sel = (model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)
    d = x[state.spring_particle_b[sel]] - x[state.spring_particle_a[sel]]
    return np.linalg.norm(d, axis=1) / model.spring_rest_length_m[sel] - 1.0


def _run(model, state, x, max_iterations, inv_mass=None):
    limited = np.nonzero(model.spring_kind <= STRUCT_WARP)[0].astype(np.int32)
    return limit_strain(limited, model.spring_rest_length_m, 0.10, 1e-6, max_iterations,
                        state.particle_inv_mass if inv_mass is None else inv_mass,
                        state.spring_particle_a, state.spring_particle_b, state.spring_alive, x)


def test_within_limit_when_converged():
    model = build_model(small_scene(nx=10, ny=10))
    state = model.state()
    rng = np.random.default_rng(5)
    x = state.particle_position_m.copy()
    x[: model.crossing_count] *= rng.uniform(1.0, 1.6, size=(model.crossing_count, 1))  # stretch the cloth
    x[: model.crossing_count] += rng.normal(scale=0.002, size=(model.crossing_count, 3))
    assert _structural_strain(model, state, x).max() > 0.3
    iterations, converged = _run(model, state, x, 500)
    assert converged and 1 < iterations < 500
    assert _structural_strain(model, state, x).max() <= 0.10 + 2e-6


def test_cap_is_reported_when_limit_cannot_be_met():
    model = build_model(small_scene(nx=6, ny=2))
    state = model.state()
    x = state.particle_position_m.copy()
    inv = state.particle_inv_mass.copy()
    # hold both ends of the cloth far apart: the limit is infeasible
    left = np.arange(0, 12, 6)
    right = left + 5
    x[right, 0] += 0.02
    inv[left] = 0.0
    inv[right] = 0.0
    iterations, converged = _run(model, state, x, 25, inv)
    assert iterations == 25 and not converged
    assert _structural_strain(model, state, x).max() > 0.10
